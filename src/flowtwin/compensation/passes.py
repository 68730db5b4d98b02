"""Which advance passes are made and which are kept
(:func:`~flowtwin.compensation.stages.advance_stage`).

The refinement models the lag on the timeline of the draft a pass starts from; its ratio
steps move the planner's junction speeds (Klipper's extruder corner velocity limits a
junction to ``icv/|Δr|``), so the result's plan can leave that timeline. A pass after the
second is made while the last kept pass re-timed more than
``AdvanceOptions.retime_share`` of the printing time (:func:`retimed_share` of
:func:`row_times`), and kept only by :func:`pass_kept` (docs/compensation.md §1, "Later
passes, while the plan moves").
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

if TYPE_CHECKING:
    from flowtwin.compensation.draft import Draft
    from flowtwin.simulation import SimulationResult

__all__ = ["RETIMED_ROW", "pass_kept", "retimed_share", "row_times"]

#: A row is re-timed when its planned time changed by more than this share of it.
RETIMED_ROW = 0.05


def pass_kept(rms: float, kept_rms: float, score: float | None,
              kept_score: float | None) -> bool:
    """Whether an advance pass's result replaces the kept draft.

    It must not raise the twin's RMS flow error and, for a pass after the second, not
    its :func:`~flowtwin.compensation.metrics.flow_score` either (the weaker of the two
    improvements, RMS and windowed peak: a later pass must not trade one for the other).

    Parameters
    ----------
    rms, kept_rms
        RMS flow error of the pass's result and of the kept draft (fractions).
    score, kept_score
        Their flow scores, or ``None`` for the first two passes (not compared).

    Returns
    -------
    bool
        ``True`` when the pass is kept; never for a ``nan`` RMS or score.
    """
    if not rms <= kept_rms:
        return False
    return score is None or kept_score is None or bool(score <= kept_score)


def row_times(sim: SimulationResult, draft: Draft) -> npt.NDArray[np.float64]:
    """Planned time of every original row.

    Parameters
    ----------
    sim
        The simulation of ``draft``.
    draft
        A draft (its pieces' original rows: ``draft.row``).

    Returns
    -------
    numpy.ndarray
        Time the planner gives the pieces of each original row, s, shape
        ``(draft.n_rows,)``.
    """
    times = np.asarray(sim.dynamics.moves["duration_s"], dtype=np.float64)
    return np.asarray(np.bincount(draft.row, weights=times, minlength=draft.n_rows),
                      dtype=np.float64)


def retimed_share(before_s: npt.NDArray[np.float64], after_s: npt.NDArray[np.float64],
                  rows: npt.NDArray[np.bool_]) -> float:
    """Share of the time of some rows that the planner moved.

    Parameters
    ----------
    before_s, after_s
        Planned time of every row on the timeline a pass modelled and in its result's
        plan, s, shape ``(n_rows,)``.
    rows
        The rows that count (the printing ones), shape ``(n_rows,)``.

    Returns
    -------
    float
        The share of ``before_s`` over ``rows`` that lies in rows whose time changed by
        more than :data:`RETIMED_ROW` of it; 0 when the rows take no time.
    """
    b, a = before_s[rows], after_s[rows]
    total = float(np.sum(b))
    if not total > 0.0:
        return 0.0
    return float(np.sum(b[np.abs(a - b) > RETIMED_ROW * b])) / total
