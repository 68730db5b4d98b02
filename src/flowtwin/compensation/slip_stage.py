"""The slip stage of the pipeline: the slip feed-forward [000 §6]
(:mod:`flowtwin.compensation.slip`) in rounds on the twin, judged, refused or kept."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.compensation.draft import Draft
from flowtwin.compensation.emit import Layout
from flowtwin.compensation.metrics import flow_figures, flow_score
from flowtwin.compensation.slip import (
    SlipOptions,
    clipped_slip,
    slip_change,
    slip_feedforward,
)
from flowtwin.compensation.stages import Current, Setting, printing_pieces
from flowtwin.errors import DataError
from flowtwin.physics.drive import steady_slip_at_intended_feed
from flowtwin.simulation import SimulationResult

__all__ = ["SlipOutcome", "SlipStart", "slip_stage"]

BoolArray = npt.NDArray[np.bool_]
FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class SlipOutcome:
    """The slip-corrected draft (or the one before, when refused), the E it added on
    printing pieces (grid units), the warnings, the rounds simulated and the last
    round's :func:`~flowtwin.compensation.slip.slip_change`."""

    current: Current
    added_grid: int
    applied: bool
    warnings: tuple[str, ...]
    rounds: int = 0
    change: float = 0.0


@dataclass(frozen=True, slots=True)
class SlipStart:
    """What the slip stage reads of the draft it starts from (:meth:`of`), so that the
    draft's simulation can be let go while the slip's drafts are simulated: the draft,
    its printing pieces, its twin's RMS flow error and predicted slip per piece, and its
    windowed peak over-extrusion over one nozzle diameter."""

    draft: Draft
    printing: BoolArray
    rms: float
    slip: FloatArray
    window_peak: float = 0.0

    @classmethod
    def of(cls, setting: Setting, current: Current) -> SlipStart:
        """The figures of ``current``."""
        draft, sim = current.draft, current.sim
        f = flow_figures(setting.original, sim, draft.row,
                         window_mm=float(setting.twin.machine.hotend.nozzle_diameter_mm))
        return cls(draft, printing_pieces(sim, draft), f.rms_flow_error,
                   np.array(sim.dynamics.moves["slip"], dtype=np.float64),
                   f.peak_overextrusion_window)


def slip_stage(setting: Setting, start: SlipStart, options: SlipOptions, *,
               ahead: Callable[[Draft, Layout], None] | None = None) -> SlipOutcome:
    """Slip feed-forward (:mod:`flowtwin.compensation.slip`) from ``start``: the first
    round corrects for the steady slip at the intended feed, each further round (up to
    ``options.iterations``) for the slip the twin predicted for the last round's file,
    until that differs from the slip corrected for by at most ``options.tolerance``.

    The last round is kept when it meets the tolerance (or the tolerance is 0); when no
    round does (near grinding the rounds need not converge: that is warned of), the one
    with the lowest :func:`~flowtwin.compensation.metrics.flow_score`. Refused when the
    round kept raises the twin's RMS flow error above the draft's it started from, or,
    when no round met the tolerance, its windowed peak over-extrusion (a correction that
    is not at its fixed point must better both figures). A draft that is kept but was
    not the last simulated is simulated again (its simulation was let go), as is the
    starting draft when refused. ``ahead`` is told each round's draft and layout before
    they are simulated (the outcome hands the kept one on unless refused)."""
    draft = start.draft
    base = draft.e_grid.copy()
    printing = start.printing
    rms0 = start.rms
    slip = steady_slip_at_intended_feed(clipped_slip(start.slip, options),
                                        k_p=setting.twin.machine.drive.k_p)
    layout = None
    sim: SimulationResult | None = None
    rounds = 0
    change = math.inf
    window = float(setting.twin.machine.hotend.nozzle_diameter_mm)
    # (score, RMS, windowed peak, round, change, draft) of the best round that missed
    # the tolerance
    best: tuple[float, float, float, int, float, Draft] | None = None
    while rounds < options.iterations and change > options.tolerance:
        draft = slip_feedforward(draft, base, printing, slip, options)
        sim = layout = None  # the last round's simulation is not held through the next one
        layout = draft.layout(check=False)
        if ahead is not None:
            ahead(draft, layout)
        sim = setting.twin.simulate_draft(draft, layout=layout)
        rounds += 1
        # a copy: a field of the structured array would hold all of this round's dynamics
        # through the next round's simulation
        predicted = np.array(sim.dynamics.moves["slip"], dtype=np.float64)
        change = slip_change(slip, predicted, printing, base, options)
        slip = predicted
        if change > options.tolerance:  # (another round, or none converged)
            f = flow_figures(setting.original, sim, draft.row, window_mm=window)
            score = flow_score(setting.original.before, f)
            if best is None or score < best[0]:
                best = (score, f.rms_flow_error, f.peak_overextrusion_window, rounds, change,
                        draft)
    del slip
    if sim is None:  # no round (iterations is at least 1)
        raise DataError("the slip feed-forward needs at least one round",
                        field="iterations", value=options.iterations, allowed=">= 1")
    warnings: list[str] = []
    converged = change <= options.tolerance or options.tolerance == 0.0
    if converged:  # the last round is kept
        best = (0.0, flow_figures(setting.original, sim, draft.row).rms_flow_error, 0.0,
                rounds, change, draft)
    assert best is not None  # (set by every round that missed the tolerance, or above)
    _score, rms1, window1, kept_round, kept_change, kept = best
    if not converged:
        warnings.append(
            f"the slip feed-forward did not reach its fixed point in {rounds} rounds (the "
            f"slip predicted for the last one is {100 * change:.2f} % of the flow off the "
            f"slip it corrected for; the drive is near grinding, try --guard): of the "
            f"rounds, round {kept_round} has the lowest flow error")
    # (a negative windowed peak is no over-extrusion: under-extruded everywhere)
    if rms1 > rms0 or (not converged and max(window1, 0.0) > max(start.window_peak, 0.0)):
        del sim, layout
        layout = start.draft.layout(check=False)
        again = Current(start.draft, setting.twin.simulate_draft(start.draft, layout=layout),
                        layout)
        raised = (f"the twin's RMS flow error (to {100 * rms1:.2f} % from {100 * rms0:.2f} %"
                  if rms1 > rms0 else
                  f"the twin's windowed peak over-extrusion (to {100 * window1:.2f} % from "
                  f"{100 * max(start.window_peak, 0.0):.2f} %")
        return SlipOutcome(again, 0, False, (
            f"the slip feed-forward raised {raised}; the drive is near grinding, try "
            "--guard): it is not used",), rounds, kept_change)
    if kept is not draft:
        del sim, layout
        draft = kept
        layout = draft.layout(check=False)
        if ahead is not None:
            ahead(draft, layout)
        sim = setting.twin.simulate_draft(draft, layout=layout)
    added = int(np.sum(draft.e_grid[printing]) - np.sum(base[printing]))
    return SlipOutcome(Current(draft, sim, layout), added, True, tuple(warnings), rounds,
                       kept_change)
