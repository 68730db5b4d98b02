"""Integrate the extrusion state equation over a commanded feed (docs/spec.md §3.4).

State ``Δl`` (mm of column compression) [001 Eq. 5]::

    dΔl/dt = v_in − v*_out,        v*_out = max(Δl, 0) / K,       F_f = max(Δl, 0) / k
    v_in   = v_nom · (1 − s)       for v_nom > 0 and not grinding,  s = k_p + s'(v_nom) · F_f
    v_in   = v_nom                 for v_nom ≤ 0 (retraction feeds without slip)
    v_in   = 0                     while grinding (v_nom > 0)

``v_nom`` is the commanded filament speed (pressure advance and M221 included,
:mod:`flowtwin.dynamics.feed`), ``K`` the lag factor [001 Eq. 15], ``k`` the column
compliance [001 Eq. 2], ``s'(v) = a + b·exp(−c·v)`` the slip gradient [000 Eq. 8]
(Eq. 6 with ``b = 0``), evaluated at the nominal speed — [000] fits it against the
measured feed speed, which differs by the factor ``1 − s``; using ``v_nom`` keeps the
equation linear in ``Δl``.

* **No backflow** [001 Fig. 8]: ``Q_out = A_fil · v*_out ≥ 0`` always.
* **Retraction** pulls the column back; ``Δl < 0`` means the filament end has been pulled
  away from the melt (a gap of ``−Δl`` mm in the feed direction): no force, no output,
  and the next forward feed first closes the gap, then builds pressure.
* **Grinding**: when ``F_f`` reaches ``max_feed_force_n`` the roller eats into the filament
  [000 §4, 003] and feeding stops; it resumes when ``F_f`` has fallen below
  ``(1 − grind_release_fraction) · max_feed_force_n`` (hysteresis, default 20 %: the seeds
  give no release level; a ground filament needs the load well below the failure force to
  be gripped again). Commanded filament while grinding is lost.

Without slip the solution is the exact exponential integrator (no internal step); with
slip, the exact exponential at constant speed and Gauss collocation (2–6 stages, chosen
per substep from its error bound) on substeps with ``β·h ≤ stiffness`` (``_expint``).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from flowtwin.dynamics._acc_kernel import (
    A_CMD,
    A_FED,
    A_FMAX,
    A_GRIND,
    A_GTIME,
    A_OUT,
    A_SLIP,
    A_TIME,
    BAD_ORDER,
    BUF_ROWS,
    BUF_WIDTH,
    N_ACC,
    N_SER,
    S_Q,
    T_SUM,
)
from flowtwin.dynamics._expint import MAX_STAGES, WS_ROWS
from flowtwin.dynamics._lag_kernel import integrate_kernel
from flowtwin.dynamics.extrusion_result import (
    MOVE_RESULT_DTYPE,
    SERIES_DTYPE,
    DynamicsResult,
    DynamicsSummary,
)
from flowtwin.dynamics.feed import CommandedFeed
from flowtwin.dynamics.params import ExtrusionParams
from flowtwin.errors import DataError, ProfileError

__all__ = ["MAX_SERIES_SAMPLES", "integrate"]

#: Largest time series :func:`integrate` will allocate (8 columns of float64 each).
MAX_SERIES_SAMPLES = 20_000_000

#: Fewest collocation stages a substep may use (``MAX_STAGES``: the fixed 6-stage method).
_MIN_STAGES = 2

#: Float columns of ``MOVE_RESULT_DTYPE`` in the order ``_acc_kernel.finish_move`` writes.
_FLOAT_COLUMNS = ("cmd_mm3", "fed_cmd_mm3", "fed_mm3", "out_mm3", "stop_out_mm3", "ooze_mm3",
                  "q_mean_mm3_s", "q_min_mm3_s", "q_max_mm3_s", "peak_force_n", "slip",
                  "slip_loss_mm3", "grind_loss_mm3", "duration_s")


def _series_times(feed: CommandedFeed, t_end: float, dt_s: float,
                  window_s: tuple[float, float] | None) -> npt.NDArray[np.float64]:
    if not (dt_s > 0.0 and math.isfinite(dt_s)):
        raise DataError("series sample interval must be > 0", field="series_dt_s",
                        value=dt_s, allowed="> 0 s")
    t_a, t_b = (feed.t_begin_s, t_end) if window_s is None else window_s
    if not (t_b >= t_a):
        raise DataError("series window must have start <= end", field="series_window_s",
                        value=window_s, allowed="(t_start, t_end) with t_start <= t_end")
    n = int(math.floor((t_b - t_a) / dt_s)) + 1
    if n > MAX_SERIES_SAMPLES:
        raise DataError("time series too long", field="series_dt_s", value=dt_s,
                        allowed=f"at most {MAX_SERIES_SAMPLES} samples: use a larger interval "
                                f"or a window (this feed spans {t_b - t_a:.1f} s)")
    return t_a + dt_s * np.arange(n, dtype=np.float64)


def integrate(feed: CommandedFeed, params: ExtrusionParams, *,
              initial_compression_mm: float = 0.0, initially_grinding: bool = False,
              tail_s: float = 0.0, series_dt_s: float | None = None,
              series_window_s: tuple[float, float] | None = None,
              stiffness: float = 1.0) -> DynamicsResult:
    """Predict the delivered melt of a commanded feed.

    Parameters
    ----------
    feed
        Commanded extruder motion (:func:`~flowtwin.dynamics.feed.nominal_feed`, optionally
        shaped by :func:`~flowtwin.dynamics.advance.apply_advance`).
    params
        Per-move parameters, ``params.n_moves == feed.n_moves``.
    initial_compression_mm
        ``Δl`` before the first segment, mm (0: relaxed column touching the melt).
    initially_grinding
        Whether the drive is grinding at the start.
    tail_s
        Rest time appended after the feed, s (lets the column relax: the final ooze).
    series_dt_s
        Sample interval of the optional time series, s (``None``: no series).
    series_window_s
        ``(t_start, t_end)`` of the series, s; default the whole feed (with tail).
    stiffness
        Largest ``β·h`` of a collocation substep in the slip regime (``β = 1/K + v s'/k``);
        halving it halves the substeps (convergence check). Unused without slip.

    Returns
    -------
    DynamicsResult
        Per-move figures, summary, optional series.

    Raises
    ------
    ProfileError
        Parameters for a different number of moves, or a bad ``stiffness``.
    DataError
        Empty feed, bad tail or series settings.
    """
    return _integrate(feed, params, initial_compression_mm=initial_compression_mm,
                      initially_grinding=initially_grinding, tail_s=tail_s,
                      series_dt_s=series_dt_s, series_window_s=series_window_s,
                      stiffness=stiffness, min_stages=_MIN_STAGES)


def _per_move(values: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """A parameter for the kernel: the ``(n_moves,)`` array, or its one value as an array
    of length 1 when it has stride 0 (a constant broadcast by
    :func:`~flowtwin.dynamics.params.resolve_per_move`: nothing per move is read or
    written; the kernel indexes a length-1 array at 0)."""
    if values.shape[0] > 1 and values.strides[0] == 0:
        return np.array([values[0]], dtype=np.float64)
    return np.ascontiguousarray(values, dtype=np.float64)


def _integrate(feed: CommandedFeed, params: ExtrusionParams, *,
               initial_compression_mm: float, initially_grinding: bool, tail_s: float,
               series_dt_s: float | None, series_window_s: tuple[float, float] | None,
               stiffness: float, min_stages: int) -> DynamicsResult:
    """:func:`integrate` with the fewest collocation stages a substep may use
    (``MAX_STAGES`` = 6 reproduces the fixed 6-stage method: the reference of the tests)."""
    n = feed.n_moves
    if params.n_moves != n:
        raise ProfileError("parameters are for a different number of moves",
                           field="params.n_moves", value=params.n_moves, allowed=f"{n}")
    if feed.n_segments == 0:
        raise DataError("the commanded feed is empty (no moves with duration)", field="feed",
                        value=0, allowed="at least one segment")
    if not (0.0 < stiffness <= 4.0):
        raise ProfileError("collocation step bound out of range", field="stiffness",
                           value=stiffness, allowed="0 < stiffness <= 4")
    if not (tail_s >= 0.0 and math.isfinite(tail_s)):
        raise DataError("tail must be >= 0 s", field="tail_s", value=tail_s, allowed=">= 0")
    if not math.isfinite(initial_compression_mm):
        raise DataError("initial compression must be finite", field="initial_compression_mm",
                        value=initial_compression_mm, allowed="finite mm")
    t0, dt, coef, e0 = feed.t0_s, feed.dt_s, feed.coef, feed.e0_mm
    move, gap = feed.move, feed.gap
    if tail_s > 0.0:
        t0 = np.append(t0, feed.t_end_s)
        dt = np.append(dt, tail_s)
        coef = np.vstack([coef, np.zeros((1, 4))])
        e0 = np.append(e0, feed.e_end_mm())
        move = np.append(move, n - 1)
        gap = np.append(gap, True)
    move = np.ascontiguousarray(move, dtype=np.int64)
    gap = np.ascontiguousarray(gap, dtype=np.bool_)
    dt = np.ascontiguousarray(dt, dtype=np.float64)
    coef = np.ascontiguousarray(coef, dtype=np.float64)
    t_end = float(t0[-1] + dt[-1])
    sample_t = (np.zeros(0) if series_dt_s is None
                else _series_times(feed, t_end, series_dt_s, series_window_s))
    samples = np.zeros((sample_t.shape[0], N_SER))
    p = params
    area = p.filament_area_mm2
    # every field of every row is written by the kernel
    moves = np.empty(n, dtype=MOVE_RESULT_DTYPE)
    cols = tuple(moves[name] for name in _FLOAT_COLUMNS)
    tot = np.empty((2, N_ACC))
    pre = np.empty(N_ACC)
    x_end, grind_end, n_events, status = integrate_kernel(
        np.ascontiguousarray(t0, dtype=np.float64), dt, coef,
        np.ascontiguousarray(e0, dtype=np.float64), move, gap, _per_move(p.lag_k_s),
        _per_move(p.compliance_mm_per_n), _per_move(p.slip_offset),
        _per_move(p.slip_gradient_per_n), _per_move(p.slip_velocity_gain_per_n),
        _per_move(p.slip_velocity_decay_s_per_mm), _per_move(p.max_feed_force_n),
        float(p.grind_release_fraction), float(initial_compression_mm),
        bool(initially_grinding), float(stiffness), int(min_stages), sample_t, samples,
        float(area), np.ascontiguousarray(feed.move_de_mm, dtype=np.float64),
        np.ascontiguousarray(feed.move_t0_s, dtype=np.float64),
        np.ascontiguousarray(feed.move_t1_s, dtype=np.float64), cols, moves["grinding"],
        tot, pre, np.empty((WS_ROWS, MAX_STAGES)), np.empty(8), np.empty((BUF_ROWS, BUF_WIDTH)))
    if status != 0:
        why = ("segments not in move order: a move's segments must be contiguous, its stop "
               "right after them, moves in index order" if status == BAD_ORDER else
               "move index out of range, segment without a move, non-positive duration or "
               "non-finite speed")
        raise DataError(f"commanded feed is inconsistent ({why})", field="feed",
                        value=feed.n_segments,
                        allowed=f"move indices in [-1, {n}) in order, dt > 0, finite "
                                "coefficients")
    before = np.zeros(1, dtype=MOVE_RESULT_DTYPE)
    before["cmd_mm3"] = 0.0
    before["fed_cmd_mm3"] = area * pre[A_CMD]
    before["fed_mm3"] = area * pre[A_FED]
    before["stop_out_mm3"] = area * pre[A_OUT]
    before["ooze_mm3"] = area * pre[A_OUT]
    before["peak_force_n"] = pre[A_FMAX]
    before["duration_s"] = pre[A_TIME]
    before["grinding"] = pre[A_GTIME] > 0.0
    tot_ = tot[T_SUM]
    fed = area * float(tot_[A_FED])
    out = area * float(tot_[A_OUT])
    summary = DynamicsSummary(
        cmd_mm3=area * float(np.sum(feed.move_de_mm)),
        fed_cmd_mm3=area * float(tot_[A_CMD]),
        fed_mm3=fed,
        out_mm3=out,
        stored_start_mm3=area * float(initial_compression_mm),
        stored_end_mm3=area * float(x_end),
        mass_balance_error_mm3=fed - out - area * (float(x_end) - float(initial_compression_mm)),
        slip_loss_mm3=area * float(tot_[A_SLIP]),
        grind_loss_mm3=area * float(tot_[A_GRIND]),
        ooze_mm3=float(np.sum(moves["ooze_mm3"])) + area * float(pre[A_OUT]),
        peak_force_n=float(tot_[A_FMAX]),
        grinding_moves=int(np.count_nonzero(moves["grinding"])),
        duration_s=t_end - float(t0[0]),
        n_segments=int(t0.shape[0]),
        n_events=int(n_events),
        advance=feed.advance,
    )
    series = None
    if series_dt_s is not None:
        # the kernel's sample rows are the series' records: its columns S_T … S_X are
        # SERIES_DTYPE's fields in order (tests/dynamics/test_integrator.py holds the two
        # together), so the rows are viewed as records, not copied field by field; the
        # outflow becomes mm³/s in place
        samples[:, S_Q] *= area
        series = samples.view(SERIES_DTYPE).reshape(-1)
    return DynamicsResult(moves=moves, summary=summary, series=series,
                          before_first_move=before, final_compression_mm=float(x_end),
                          final_grinding=bool(grind_end), feed=feed, warnings=feed.warnings)

