"""Pressure advance baked into the G-code [001 Eqs. 11, 13].

The melt flow lags the commanded flow like ``H(s) = 1/(1 + K·s)`` [001 Eq. 15]. Commanding
``v_in = v⁰ + K_LA·dv⁰/dt`` [001 Eq. 11] with ``K_LA = K`` makes the output equal the
intended ``v⁰`` [001]. Integrated over time this says: the extruder should be at the
*advanced position* ``E*(t) = E⁰(t) + K·v⁰_E(t)`` instead of ``E⁰(t)``.

A G-code move turns its E in proportion to its path, so the firmware can only follow
``E*`` at the ends of the pieces a move is cut into (:mod:`flowtwin.compensation.pieces`):
every move is cut at the planner's accel/cruise/decel boundaries and each piece gets
``E*(end) − E*(start)``. Two laws give ``E*`` at a piece's end:

* ``discrete`` — Tronvoll's discrete law [001 Eq. 13],
  ``ΔD_n = K_LA·(ΔD⁰_n/Δt_n − ΔD⁰_(n−1)/Δt_(n−1)) + ΔD⁰_n``, summed:
  ``E*_n = E⁰_n + K_LA·ΔD⁰_n/Δt_n`` (the average rate of the piece just finished);
* ``smoothed`` — Eq. 11 integrated exactly, ``E* = E⁰ + K·v⁰_E``, with the advance term
  ``K·v⁰_E`` averaged over a symmetric triangular window of ``smooth_time_s`` (as
  Klipper smooths its pressure advance), which turns the velocity steps at junctions into
  ramps the firmware can execute; acceleration phases are cut into several pieces.

A *run* is a stretch of consecutive printing moves (XY motion, positive E). At both ends
of a run the advanced position equals the intended one, so each run keeps its exact
commanded E (and the file its total volume); the advance only moves filament in time.
Within a run the pieces follow ``E*`` as closely as the firmware allows
(:mod:`flowtwin.compensation.limits`, :mod:`flowtwin.compensation._track_kernel`):
no piece extrudes less than ``min_flow_fraction`` of its intended ratio (no negative
extrusion — the ideal command during a deceleration is often negative, which the
firmware's own advance can do but a G-code cannot [001 Fig. 8]), none more than the
firmware accepts, and no ratio step exceeds the firmware's jump limit at the planned
junction speed. Whatever had to be clipped is counted in :class:`AdvanceResult`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
import numpy.typing as npt

from flowtwin.compensation._law_kernel import (
    accumulate_runs,
    f2_values,
    last_at_or_before,
    run_segments,
    segment_at,
    segment_integrals,
)
from flowtwin.compensation._track_kernel import FLAG_NAMES, piece_bounds, run_pieces, track_runs
from flowtwin.compensation.limits import ExtruderLimits
from flowtwin.compensation.pieces import Pieces
from flowtwin.compensation.refine import RefineOptions
from flowtwin.errors import ProfileError
from flowtwin.gcode.moves import MoveKind, MoveTable
from flowtwin.planner.timeline import Timeline

__all__ = ["KLIPPER_PIECE_FRACTION", "KLIPPER_RELIEF_LAGS", "PIECE_FRACTION", "RELIEF_LAGS",
           "AdvanceLaw", "AdvanceOptions",
           "LawResult", "advance_targets", "eligible_rows", "follow_law",
           "smoothed_advance_term"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


class AdvanceLaw(StrEnum):
    """Which form of the advance law sets the pieces' E."""

    DISCRETE = "discrete"   #: [001 Eq. 13] on the phase pieces
    SMOOTHED = "smoothed"   #: [001 Eq. 11] integrated, advance term smoothed


#: Longest smoothed-law piece near speed changes, as a fraction of ``smooth_time_s``.
PIECE_FRACTION = 0.25
#: The same on Klipper (see ``AdvanceOptions.piece_time_fraction``).
KLIPPER_PIECE_FRACTION = 0.05
#: Shortest travel relieved, in lag factors (see ``AdvanceOptions.relief_min_lags``).
RELIEF_LAGS = 0.25
#: The same on Klipper, where a relief costs ten times the time.
KLIPPER_RELIEF_LAGS = 0.5


@dataclass(frozen=True, slots=True)
class AdvanceOptions:
    """How to bake the advance.

    Attributes
    ----------
    law
        :class:`AdvanceLaw`.
    k_scale
        ``K_LA = k_scale · K`` with ``K`` the twin's lag factor of each move (1 restores
        the command [001]).
    k_s
        A fixed ``K_LA`` (s) for every move instead of the twin's.
    smooth_time_s
        Width of the triangular smoothing window of the smoothed law, s (> 0).
    accel_pieces
        Least number of pieces per acceleration/deceleration phase (smoothed law; the
        discrete law cuts at the phase boundaries only).
    piece_time_fraction
        Smoothed law: longest piece in acceleration, deceleration and the cruise edges
        as a fraction of ``smooth_time_s`` (short pieces keep the ratio steps small);
        ``None``: :data:`KLIPPER_PIECE_FRACTION` on Klipper, whose extruder corner
        velocity limits every junction to ``icv/|Δratio|`` so that a later pass can only
        follow the law in small steps, :data:`PIECE_FRACTION` elsewhere (measured on the
        validation prints: docs/compensation.md, "Session 14").
    anchor_band
        Pieces at least ``smooth_time_s`` long keep their ratio within this fraction of
        the target's; the envelope of the shorter pieces before them is planned so they
        can (see :mod:`flowtwin.compensation._track_kernel`).
    min_piece_mm
        Shortest piece, mm; shorter ones are merged with a neighbour.
    min_flow_fraction
        Least E of a piece as a fraction of its intended E (no piece stops extruding).
    limit_margin
        Fraction of each firmware limit kept in reserve (0.1: use 90 %).
    refine
        Refine the law's pieces with the twin's lag model so every move delivers its own
        volume (:mod:`flowtwin.compensation.refine`); ``None`` keeps the law as it is.
    relief
        Relieve the pressure over travels between printing runs with a retraction of the
        predicted compression (needs ``refine``; see :mod:`flowtwin.compensation.bake`).
    relief_min_lags
        Relieve only travels lasting at least this many lag factors ``K`` (a shorter
        travel lets the column ooze ``x·(1 − e^(−T/K))`` unrelieved). ``None``:
        :data:`KLIPPER_RELIEF_LAGS` on Klipper, :data:`RELIEF_LAGS` elsewhere. A relief's
        two E-only moves cost ~5 ms on Marlin at 60–80 mm/s (~40 ms at 130–200 mm/s, the
        head stopping from full speed) but ~50 ms on Klipper, which runs them at its
        ``max_extrude_only_accel`` and slows the junctions around them to its extruder
        corner velocity; measured on the validation prints, relieving from a quarter of
        ``K`` raised the Marlin prints at 5× from 27 to 32 of 35 for +1 % print time
        (median; worst +6.6 %) and lowered the Klipper prints from 24 to 23 of 37 for up
        to +39 % (docs/compensation.md, "Session 15").
    relief_along
        On Klipper, lay each relief's retraction and push-back along its travel's first
        and last millimetres where they fit, instead of two E-only moves the head stands
        still for (:func:`flowtwin.compensation.relief.insert_relief`); ``False``: E-only
        moves everywhere (as on Marlin).
    twin_gain
        Learning gain of a later pass's twin correction: it aims the model at
        ``intent + g·(model − twin)`` (see :func:`flowtwin.compensation.bake.advance_pass`).
        A step of iterative learning control converges where the twin's response is less
        than ``2/g`` times the model's; at a run start after a relieved travel the twin's
        column is not linear (a column left short must refill before anything flows), and
        a full step (``g = 1``) overshot there (Cura 5.9.1: a 0.2 mm run −98 % → +39 %).
    retract_ratio
        While the head slows down (a piece that ends slower than it starts), the piece may
        pull the filament back at up to this many times its move's intended ratio (E per
        mm of path): the law's ``−K·v̇⁰_E`` where the flow falls [001 Eq. 11, Fig. 8],
        which E alone at ``min_flow_fraction`` cannot do. The refinement keeps the column
        from pulling away from the melt (``x ≥ 0`` after every such piece: no backflow),
        so this needs ``refine``; ``0``: never below ``min_flow_fraction``.
    retime_share
        A pass after the second is made only when the pass before it re-timed more than
        this share of the printing time: the refinement's model is linear in E on the
        timeline of the draft it starts from, and its ratio steps move the planner's
        junction speeds (Klipper's extruder corner velocity most of all), so where the
        result's plan left that timeline (rows whose planned time changed by more than
        :data:`~flowtwin.compensation.passes.RETIMED_ROW` of it) the next pass models
        the new one. ``0``: every pass.
    """

    law: AdvanceLaw = AdvanceLaw.SMOOTHED
    k_scale: float = 1.0
    k_s: float | None = None
    smooth_time_s: float = 0.02
    accel_pieces: int = 2
    piece_time_fraction: float | None = None
    anchor_band: float = 0.25
    min_piece_mm: float = 0.1
    min_flow_fraction: float = 0.05
    limit_margin: float = 0.1
    refine: RefineOptions | None = field(default_factory=RefineOptions)
    relief: bool = True
    relief_min_lags: float | None = None
    relief_along: bool = True
    twin_gain: float = 0.5
    retract_ratio: float = 4.0
    retime_share: float = 0.02

    def piece_fraction(self, firmware: str) -> float:
        """``piece_time_fraction`` for a firmware (``"klipper"`` or ``"marlin"``)."""
        if self.piece_time_fraction is not None:
            return self.piece_time_fraction
        return KLIPPER_PIECE_FRACTION if firmware == "klipper" else PIECE_FRACTION

    def relief_lags(self, firmware: str) -> float:
        """``relief_min_lags`` for a firmware (``"klipper"`` or ``"marlin"``)."""
        if self.relief_min_lags is not None:
            return self.relief_min_lags
        return KLIPPER_RELIEF_LAGS if firmware == "klipper" else RELIEF_LAGS

    @property
    def is_identity(self) -> bool:
        """The options change nothing: no advance, no refinement, no relief."""
        no_k = self.k_s == 0.0 or (self.k_s is None and self.k_scale == 0.0)
        return no_k and self.refine is None and not self.relief

    def __post_init__(self) -> None:
        checks = {
            "k_scale": (self.k_scale, 0.0 <= self.k_scale <= 10.0, "0 <= k_scale <= 10"),
            "smooth_time_s": (self.smooth_time_s, 0.0 < self.smooth_time_s <= 0.2,
                              "0 < t <= 0.2 s"),
            "accel_pieces": (self.accel_pieces, 1 <= self.accel_pieces <= 16, "1 .. 16"),
            "piece_time_fraction": (self.piece_time_fraction,
                                    self.piece_time_fraction is None
                                    or 0.05 <= self.piece_time_fraction <= 1.0,
                                    "0.05 .. 1 or None"),
            "anchor_band": (self.anchor_band, 0.0 <= self.anchor_band <= 10.0, "0 .. 10"),
            "min_piece_mm": (self.min_piece_mm, 0.0 <= self.min_piece_mm <= 10.0,
                             "0 .. 10 mm"),
            "min_flow_fraction": (self.min_flow_fraction,
                                  0.0 < self.min_flow_fraction <= 1.0, "0 < f <= 1"),
            "limit_margin": (self.limit_margin, 0.0 <= self.limit_margin < 1.0, "0 <= m < 1"),
            "twin_gain": (self.twin_gain, 0.0 < self.twin_gain <= 1.0, "0 < g <= 1"),
            "retract_ratio": (self.retract_ratio, 0.0 <= self.retract_ratio <= 20.0,
                              "0 .. 20"),
            "retime_share": (self.retime_share, 0.0 <= self.retime_share <= 1.0, "0 .. 1"),
            "relief_min_lags": (self.relief_min_lags,
                                self.relief_min_lags is None
                                or 0.0 <= self.relief_min_lags <= 100.0,
                                "0 .. 100 or None"),
        }
        if self.k_s is not None:
            checks["k_s"] = (self.k_s, 0.0 <= self.k_s <= 10.0, "0 <= K <= 10 s")
        for name, (value, ok, allowed) in checks.items():
            if not (ok and (value is None or math.isfinite(float(value)))):
                raise ProfileError("invalid advance option", field=name, value=value,
                                   allowed=allowed)


def eligible_rows(table: MoveTable, row_de_grid: IntArray) -> npt.NDArray[np.bool_]:
    """Printing moves the advance acts on: XY motion, positive E, written in the G-code."""
    kind = table.moves["kind"]
    return (((kind & MoveKind.XY) != 0) & ((kind & MoveKind.FW_RETRACT) == 0)
            & (row_de_grid > 0))


def smoothed_advance_term(timeline: Timeline, rows: IntArray, rate: FloatArray,
                          k_la: FloatArray, run_of_row: IntArray, times: FloatArray,
                          query_run: IntArray, *, smooth_time_s: float) -> FloatArray:
    """Triangular-window average of ``A(t) = K·r·v(t)`` within each run.

    ``A`` is piecewise linear in time (the planner's phases), zero outside the run's
    moves. With ``F₁ = ∫A`` and ``F₂ = ∫F₁`` the triangular average of half-width ``h``
    is exactly ``(F₂(t + h) − 2F₂(t) + F₂(t − h))/h²``.

    Parameters
    ----------
    timeline
        The phases.
    rows
        Rows that carry advance, in order, shape ``(m,)``.
    rate
        E per path length of each of those rows, shape ``(m,)``.
    k_la
        ``K_LA`` of each of those rows, s, shape ``(m,)``.
    run_of_row
        Run index of each of those rows (non-decreasing), shape ``(m,)``.
    times
        Query times, s, shape ``(q,)``.
    query_run
        Run of each query, shape ``(q,)``.
    smooth_time_s
        Window width, s.

    Returns
    -------
    ndarray
        Smoothed advance term at the query times (E units of ``rate`` times mm), ``(q,)``.
    """
    # (every row's, then these rows': the same values, without copying the rows' records)
    t0, ta, tc, td, sv, cv, ev = (a[rows] for a in timeline.trapezoids())
    g = k_la * rate
    # three segments per row: (start, duration, A at start, slope), F1 and F2 over each
    # (the cube of the durations: numpy's power, as before), restarted at every run
    f64 = [np.ascontiguousarray(a, dtype=np.float64) for a in (t0, ta, tc, td, sv, cv, ev, g)]
    starts, durs, a0, slope, first = run_segments(
        f64[0], f64[1], f64[2], f64[3], f64[4], f64[5], f64[6], f64[7],
        np.ascontiguousarray(run_of_row, dtype=np.int64))
    f1_len, f2_len, ends = segment_integrals(starts, durs, durs ** 3, a0, slope)
    n = starts.size
    f1 = np.zeros(n)
    f2 = np.zeros(n)
    # sequential accumulation (gaps between rows add F1·gap to F2)
    accumulate_runs(starts, ends, f1_len, f2_len, first, f1, f2)
    h = 0.5 * smooth_time_s
    run_first = np.flatnonzero(first)
    run_last = np.append(run_first[1:], n) - 1
    lo = np.ascontiguousarray(run_first[query_run], dtype=np.int64)
    hi = np.ascontiguousarray(run_last[query_run], dtype=np.int64)

    in_order = bool(np.all(starts[1:] >= starts[:-1]))

    def f2_at(t: FloatArray) -> FloatArray:
        """``F₂`` at ``t`` within each query's run (0 before the run)."""
        if in_order and np.all(t[1:] >= t[:-1]):
            k = last_at_or_before(starts, t)
        else:  # (a rounding can put a start an ulp late)
            k = (np.searchsorted(starts, t, side="right") - 1).astype(np.int64)
        k, u, inside, after = segment_at(starts, durs, lo, hi, t, k)
        return f2_values(k, u, inside, inside ** 3, after, f1, f2, a0, slope, f1_len)

    t = np.ascontiguousarray(times, dtype=np.float64)
    return (f2_at(t + h) - 2.0 * f2_at(t) + f2_at(t - h)) / (h * h)


def advance_targets(pieces: Pieces, timeline: Timeline, rate: FloatArray, k_la: FloatArray,
                    piece_run: IntArray, run_rows: IntArray, row_run: IntArray,
                    options: AdvanceOptions) -> FloatArray:
    """Advance term at the end of every piece (E units of ``rate`` · mm).

    Parameters
    ----------
    pieces
        The pieces of the runs' rows (only pieces with ``piece_run >= 0`` are used).
    timeline
        The phases.
    rate
        E per path length of every row, shape ``(n_rows,)``.
    k_la
        ``K_LA`` per row, s, shape ``(n_rows,)``.
    piece_run
        Run of every piece (−1: not in a run), shape ``(n_pieces,)``.
    run_rows
        Rows in runs, in order.
    row_run
        Run of each of ``run_rows``.
    options
        The law and its settings.

    Returns
    -------
    ndarray
        ``E* − E⁰`` at each piece's end, shape ``(n_pieces,)`` (0 outside runs).
    """
    out = np.zeros(len(pieces))
    sel = piece_run >= 0
    if not np.any(sel):
        return out
    r = pieces.row[sel]
    if options.law is AdvanceLaw.DISCRETE:
        dt = pieces.t1_s[sel] - pieces.t0_s[sel]
        de0 = rate[r] * pieces.length_mm[sel]
        with np.errstate(divide="ignore", invalid="ignore"):
            out[sel] = np.where(dt > 0, k_la[r] * de0 / dt, 0.0)
        return out
    out[sel] = smoothed_advance_term(
        timeline, run_rows, rate[run_rows], k_la[run_rows], row_run, pieces.t1_s[sel],
        piece_run[sel], smooth_time_s=options.smooth_time_s)
    return out


@dataclass(frozen=True, slots=True)
class LawResult:
    """The advance law followed within the firmware's limits, for the pieces of the runs.

    Arrays are over the *run pieces* ``sel`` (pieces of eligible rows, in order).

    Attributes
    ----------
    sel
        Piece indices of the run pieces, shape ``(p,)``.
    run
        Run of every run piece (0, 1, …), shape ``(p,)``.
    run_first, run_last
        Index (into ``sel``) of the first and last piece of every run, shape ``(r,)``.
    run_total
        Exact E of every run, grid units, shape ``(r,)``.
    e
        E of every run piece following the law, grid units (floats), shape ``(p,)``.
    c_min, c_max
        Ratio box of every run piece (grid units per mm), shape ``(p,)``; the first and
        last piece of a run also respect the junctions with the moves around the run.
    jump
        Largest ratio step at the junction before every run piece, with the previous piece
        of the same run (``inf`` at run starts and where the speed is 0), shape ``(p,)``.
    counts
        How many pieces were moved off the law's target (see
        :data:`flowtwin.compensation._track_kernel.FLAG_NAMES`).
    """

    sel: IntArray
    run: IntArray
    run_first: IntArray
    run_last: IntArray
    run_total: FloatArray
    e: FloatArray
    c_min: FloatArray
    c_max: FloatArray
    jump: FloatArray
    counts: dict[str, int]


def follow_law(pieces: Pieces, timeline: Timeline, elig: npt.NDArray[np.bool_],
               row_e: FloatArray, row_e_exact: IntArray, k_la: FloatArray,
               limits: ExtruderLimits, options: AdvanceOptions, *, e_unit_mm: float,
               xy_rows: npt.NDArray[np.bool_],
               pull_rows: npt.NDArray[np.bool_] | None = None) -> LawResult:
    """E of every piece of the runs by the advance law, within the firmware's limits.

    Parameters
    ----------
    pieces
        Pieces of every row (:func:`~flowtwin.compensation.pieces.split_rows`).
    timeline
        The phases (``n_rows``).
    elig
        Rows the advance acts on, shape ``(n_rows,)``.
    row_e
        Intended E of every row, grid units (floats), shape ``(n_rows,)``: the law's
        ``E⁰``.
    row_e_exact
        E of every row as currently written, grid units, shape ``(n_rows,)``: every run
        keeps this total exactly.
    k_la
        ``K_LA`` of every row, s.
    limits
        The firmware's extruder limits.
    options
        Law and settings.
    e_unit_mm
        Size of one grid unit, mm of filament.
    xy_rows
        Rows with XY motion, shape ``(n_rows,)``: a junction with a move without XY
        motion (an E-only retraction) has no ratio step to limit.
    pull_rows
        Rows whose pieces may pull back (``options.retract_ratio``), shape ``(n_rows,)``;
        default: every piece that slows down. A later pass passes the pieces an earlier
        one made pull: the pieces it re-plans slow down where the earlier pass's ratio
        steps made the planner slow a junction, and pulling there chased the planner
        (Bambu Studio's flow calibration lines, 100/25 mm/s above the hot end's flow
        limit: RMS 6.3 % → 6.4 % in the second pass, the pass dropped; 4.5 % with pulls
        only where the first pass put them).

    Returns
    -------
    LawResult
    """
    n = timeline.phases.shape[0]
    ph = timeline.phases
    length_row = pieces.row_length_mm
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = np.where(length_row > 0, row_e / np.where(length_row > 0, length_row, 1.0), 0.0)
    elig = elig & (length_row > 0)
    start = elig & ~np.concatenate(([False], elig[:-1]))
    row_run_all = np.cumsum(start) - 1
    run_rows = np.flatnonzero(elig)
    row_run = row_run_all[run_rows]
    n_runs = int(np.count_nonzero(start))
    piece_run = np.where(elig[pieces.row], row_run_all[pieces.row], -1)
    adv = advance_targets(pieces, timeline, rate, k_la, piece_run, run_rows, row_run, options)
    # the run pieces, their targets (E⁰ summed within the run plus the advance term, the
    # run's exact E⁰ at its end) and every run's exact total
    sel, pr, length, first_flag, run_first, run_last, run_id, target, run_total = run_pieces(
        np.ascontiguousarray(piece_run, dtype=np.int64),
        np.ascontiguousarray(pieces.row, dtype=np.int64),
        np.ascontiguousarray(pieces.s0_mm, dtype=np.float64),
        np.ascontiguousarray(pieces.s1_mm, dtype=np.float64),
        np.ascontiguousarray(rate, dtype=np.float64),
        np.ascontiguousarray(adv, dtype=np.float64),
        np.ascontiguousarray(row_run, dtype=np.int64),
        np.asarray(row_e_exact, dtype=np.float64)[run_rows], n_runs)
    empty = np.zeros(0)
    if sel.size == 0:
        z = np.zeros(0, dtype=np.int64)
        return LawResult(z, z, z, z, empty, empty, empty, empty, empty,
                         dict.fromkeys(FLAG_NAMES, 0))
    # ratio box (grid units per mm) from the firmware limits, the jump limit at the
    # junction before each piece (a step the original had is allowed) and the starting
    # envelope: anchors (long pieces) keep a ratio near their target's
    margin = 1.0 - options.limit_margin
    grid_per_mm = 1.0 / e_unit_mm
    rate_pr = np.ascontiguousarray(rate[pr], dtype=np.float64)
    # while the head slows down the extruder may pull back (retract while moving: the
    # law's −K·dv⁰_E/dt where the flow falls [001 Eq. 11, Fig. 8]); the refinement keeps
    # the column at x ≥ 0 there (no backflow), so only with it
    pulls = options.retract_ratio > 0 and options.refine is not None
    if pulls and pull_rows is None:
        slowing = pieces.v1_mm_s[sel] < pieces.v0_mm_s[sel] - 1e-9
    elif pulls:
        slowing = np.asarray(pull_rows, dtype=bool)[pr]
    else:
        slowing = np.zeros(sel.size, dtype=bool)
    duration = pieces.t1_s[sel] - pieces.t0_s[sel]
    smoothed = options.law is AdvanceLaw.SMOOTHED
    jump_grid = margin * limits.jump_mm_s * grid_per_mm
    scalars = np.array([options.min_flow_fraction, options.retract_ratio,
                        margin * limits.max_ratio * grid_per_mm,
                        margin * limits.max_e_speed_mm_s * grid_per_mm,
                        margin * limits.max_e_accel_mm_s2 * grid_per_mm, jump_grid,
                        options.smooth_time_s, options.anchor_band], dtype=np.float64)
    switches = np.array([pulls, math.isfinite(limits.max_ratio),
                         math.isfinite(limits.max_e_speed_mm_s),
                         math.isfinite(limits.max_e_accel_mm_s2), smoothed], dtype=bool)
    bounds = np.empty((5, sel.size))
    piece_bounds(rate_pr, np.ascontiguousarray(pr, dtype=np.int64),
                 np.ascontiguousarray(pieces.v0_mm_s[sel], dtype=np.float64),
                 np.asarray(ph["cruise_v"], dtype=np.float64)[pr],
                 np.asarray(ph["accel"], dtype=np.float64)[pr],
                 np.ascontiguousarray(slowing, dtype=bool), target, length,
                 np.ascontiguousarray(duration, dtype=np.float64), first_flag, scalars,
                 switches, bounds)
    c_min, c_max, dc, env_lo, env_hi = bounds
    before = pr[run_first] - 1
    prev_xy = (before >= 0) & xy_rows[np.maximum(before, 0)]
    c_prev0 = np.zeros(sel.size)
    c_prev0[run_first] = np.where(prev_xy, rate[np.maximum(before, 0)], 0.0)
    dc[run_first] = np.where(prev_xy, dc[run_first], math.inf)
    after = pr[run_last] + 1
    v_end = pieces.v1_mm_s[sel][run_last]
    next_xy = (after < n) & xy_rows[np.minimum(after, n - 1)]
    next_rate = np.where(next_xy, rate[np.minimum(after, n - 1)], 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        allow = np.where((v_end > 1e-9) & next_xy, np.maximum(jump_grid, np.abs(rate[pr[run_last]]
                                                                    - next_rate) * v_end)
                         / v_end, math.inf)
    end_lo = next_rate - allow
    end_hi = next_rate + allow
    out = np.empty(sel.size)
    flags = np.zeros(sel.size, dtype=np.int8)
    run_start = np.append(run_first, sel.size).astype(np.int64)
    track_runs(length, target, c_min, c_max, env_lo, env_hi, c_prev0, dc, run_start, run_total,
               end_lo, end_hi, out, flags)
    counts = {name: int(np.count_nonzero(flags == code)) for code, name in enumerate(FLAG_NAMES)}
    prev = np.concatenate(([0.0], out[:-1]))
    prev[run_first] = 0.0
    e_law = out - prev
    # boxes of the run ends include the junctions around the run
    lo = c_min.copy()
    hi = c_max.copy()
    f_lo = c_prev0[run_first] - dc[run_first]
    f_hi = c_prev0[run_first] + dc[run_first]
    lo[run_first] = np.maximum(lo[run_first], np.minimum(f_lo, hi[run_first]))
    hi[run_first] = np.minimum(hi[run_first], np.maximum(f_hi, lo[run_first]))
    lo[run_last] = np.maximum(lo[run_last], np.minimum(end_lo, hi[run_last]))
    hi[run_last] = np.minimum(hi[run_last], np.maximum(end_hi, lo[run_last]))
    jump = np.where(first_flag, math.inf, dc)
    return LawResult(sel, run_id.astype(np.int64), run_first.astype(np.int64),
                     run_last.astype(np.int64), run_total, e_law, lo, hi, jump, counts)


def round_runs(e: FloatArray, run_first: IntArray, run_last: IntArray,
               run_total: FloatArray) -> IntArray:
    """Piece E in whole grid units; every run keeps its exact total.

    The cumulative E at interior piece ends is rounded to the nearest grid unit (the
    rounding residue of one piece is carried into the next); the last end of each run is
    the run's exact total. A piece that would round to less than one unit borrows it from
    its neighbour, so no printing piece stops printing.

    Parameters
    ----------
    e
        E of every run piece (floats), shape ``(p,)``.
    run_first, run_last
        First and last piece of every run, shape ``(r,)``.
    run_total
        Exact (integral) E of every run, shape ``(r,)``.

    Returns
    -------
    ndarray of int64
        Shape ``(p,)``.
    """
    first = np.zeros(e.size, dtype=bool)
    first[run_first] = True
    run_id = np.cumsum(first) - 1
    cum = np.cumsum(e)
    cum = cum - (cum - e)[run_first][run_id]
    pos = np.rint(cum).astype(np.int64)
    pos[run_last] = np.rint(run_total).astype(np.int64)
    prev = np.zeros(e.size, dtype=np.int64)
    prev[1:] = pos[:-1]
    prev[run_first] = 0
    out = pos - prev
    for j in np.flatnonzero(out < 1).tolist():  # rare
        if out[j] >= 1:
            continue
        r = int(run_id[j])
        lo, hi = int(run_first[r]), int(run_last[r])
        donors = [k for k in (j + 1, j - 1) if lo <= k <= hi and out[k] > 1]
        if not donors and hi > lo:
            k = lo + int(np.argmax(out[lo:hi + 1]))
            donors = [k] if out[k] > 1 else []
        if donors:
            need = 1 - int(out[j])
            k = donors[0]
            give = min(need, int(out[k]) - 1)
            out[j] += give
            out[k] -= give
    return out
