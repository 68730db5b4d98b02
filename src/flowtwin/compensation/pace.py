"""Flow pacing: slow the path where the intended flow changes faster than the melt can follow.

The melt follows the extruder through a first-order lag, ``K·Q̇ = v_in − Q`` [001 Eq. 15]
(``Q`` the outflow, ``v_in`` the volumetric feed, ``K`` the twin's lag factor of the move).
With ``v_in ≥ 0`` the outflow falls no faster than ``Q̇ ≥ −Q/K`` (``K`` 0.05–0.2 s;
faster if the advance pulls back: ``pull_ratio``). Where the intended flow ``Q = a·v``
(``a`` the cross-section) falls faster (a deceleration into a slow junction, a thin
transition between two perimeters), the stored ``K·Q`` is dumped into the slow stretch;
it rises no faster than the firmware's E speed step and E speed limit let the extruder push.

E cannot fix this, time can (OrcaSlicer's "extrusion rate smoothing",
``max_volumetric_extrusion_rate_slope``, slows the path where the flow would change too
fast). Here the limit comes from the twin:

* **Falling flow.** With ``a`` constant along a stretch, ``d ln Q/dt = (1/v)·dv/dt =
  dv/ds``: the bound ``d ln Q/dt ≥ −m/K`` (margin ``m < 1``, so the advance keeps a
  positive feed) is a speed that falls at most *linearly in path distance*, with slope
  ``m/K`` (1/s). Going back from a junction where the flow falls by at least
  ``min_drop`` (the planner's junction speed ``v_J``), the path speed may be at most
  ``v_J + (m/K)·d`` at a distance ``d`` before it (:func:`drop_envelope`).
* **Cross-section steps.** The path speed is continuous through a junction, so a step of
  the cross-section steps the flow by ``ρ`` whatever the speed; the outflow needs
  ``K·ln ρ`` to follow, ``v·K·ln ρ`` of path: the junction speed is capped at
  ``adjust_mm / (K·ln ρ)`` (:func:`step_speed_mm_s`), ``ρ`` the largest cross-section
  within ``adjust_mm`` before the junction over the one after (variable-width walls narrow
  in many small steps). Runs less than ``gap_lags·K`` apart (no relief over the travel)
  carry the envelope in flow: ``Q_end ≤ Q_next·exp(m·gap/K)``.
* **Rising flow.** The extruder can command at most ``V = A_f·J`` mm³/s above the intended
  flow without the planner slowing the junction (``J`` the firmware's E speed step,
  :mod:`flowtwin.compensation.limits`; ``A_f`` the filament area), so the outflow can rise
  at ``Q̇ ≤ V/K``: a path acceleration of at most ``A = m·V/(K·a)`` after a run start or a
  rising cross-section step, ``v(s)² ≤ v₀² + 2·A·s`` (:func:`rise_envelope`), from the
  outflow the column carries into the run (:func:`~flowtwin.compensation.column.
  run_start_flow`: the gap's E and retractions; a start that carries at least
  ``1/min_drop`` of its flow is not paced; nor is a file's first run: a prime's state).

A move whose planned speed exceeds the envelope is cut (the existing
:meth:`~flowtwin.compensation.draft.Draft.split`): the paced part becomes a staircase of
pieces whose feeds step by at most ``step_ratio`` and lie under the envelope; E is shared in
proportion to length on the file's exact E grid, so the volume is kept exactly. No speed is
ever raised; a floor (``min_speed_mm_s``, ``max_slowdown`` of the planned speed) bounds the
added print time. The pipeline re-plans the paced file before the advance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.compensation.column import carried_flows, feed_after
from flowtwin.compensation.draft import Draft
from flowtwin.compensation.envelopes import SAME as _SAME
from flowtwin.compensation.envelopes import drop_envelope, rise_envelope, staircase, step_speed_mm_s
from flowtwin.errors import ProfileError

__all__ = ["DEFAULT_TIME_BUDGET", "PaceOptions", "PaceReport", "drop_envelope", "pace_feeds",
           "rise_envelope", "staircase", "step_speed_mm_s"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

#: Share of the print time the pacing may add unless told otherwise (issue #17: ≤ 10 %).
DEFAULT_TIME_BUDGET = 0.10


@dataclass(frozen=True, slots=True)
class PaceOptions:
    """How far the flow pacing may slow the path.

    Attributes
    ----------
    margin
        Share ``m`` of the fastest decay (rise) the melt can follow that the paced flow
        uses: ``d ln Q/dt ≥ −m/K`` (0 < m < 1; the advance keeps a feed of ``(1 − m)·Q``).
    min_drop
        Pace only junctions where the flow falls (rises) by at least this factor (> 1).
    min_step
        Cap the junction speed where the cross-section falls by at least this factor within
        ``adjust_mm`` of path (> 1).
    adjust_mm
        Path over which the melt may adjust at a cross-section step, mm.
    step_ratio
        Largest ratio of the feeds of two neighbouring paced pieces (> 1).
    min_speed_mm_s
        Never pace below this speed, mm/s.
    max_slowdown
        Never pace a piece below this share of its planned speed (0 < f ≤ 1).
    min_piece_mm
        Shortest paced piece, mm.
    rise
        Also pace the rise of the flow (run starts, rising cross-section steps).
    run_ends
        Also pace the fall of the flow to the end of a run (before a travel, a retraction or
        a stop), to the planner's end speed of the run.
    gap_lags
        A run followed by the next one within ``gap_lags·K`` is treated as a cross-section
        step to the next run's first piece, the outflow decaying by ``exp(−gap/K)`` in
        between. Not tied to the advance's relief threshold (:class:`~flowtwin.compensation.
        advance.AdvanceOptions` ``relief_min_lags``, a quarter of ``K`` on Marlin): tied to
        it, the Marlin validation prints came out the same with ``--pace``
        (docs/compensation.md, "Which travels are relieved").
    pull_ratio
        ``r``: pace for an advance pulling back while slowing (off: 0): ``ẋ = −x/K − r·Q``,
        so ``d ln Q/dt ≥ −m·(1 + r)/K``, steps need ``1 + r`` less path. ``compensate``
        uses at most the advance's ``retract_ratio`` (none without an advance).
    spots
        Pace only near the spots an advance without pacing leaves wrong
        (:mod:`flowtwin.compensation.spots`); off: every junction the envelopes name.
    spot_error
        A move whose flow error after that advance exceeds this is a spot (fraction).
    spot_reach_mm
        Printed path within which a spot lets a junction or a start be paced, mm.
    spot_rounds
        Most times the spots are looked for again on the paced, advanced draft.
    time_budget
        Largest share of the print time (planned, of the draft before pacing) the pacing
        near the spots may add (≥ 0); over it only the worst spots are paced
        (:mod:`flowtwin.compensation.budget`). ``None`` or ``inf``: no cap. The pacing
        everywhere (``spots`` off) has no cap.
    """

    margin: float = 0.8
    min_drop: float = 2.0
    min_step: float = 1.25
    adjust_mm: float = 0.5
    step_ratio: float = 1.3
    min_speed_mm_s: float = 2.0
    max_slowdown: float = 0.1
    min_piece_mm: float = 0.1
    rise: bool = True
    run_ends: bool = True
    gap_lags: float = 0.5
    pull_ratio: float = 4.0
    spots: bool = True
    spot_error: float = 0.1
    spot_reach_mm: float = 5.0
    spot_rounds: int = 2
    time_budget: float | None = DEFAULT_TIME_BUDGET

    def __post_init__(self) -> None:
        checks = {
            "margin": (self.margin, 0.0 < self.margin < 1.0, "0 < m < 1"),
            "min_drop": (self.min_drop, 1.0 < self.min_drop <= 1e3, "1 < r <= 1000"),
            "min_step": (self.min_step, 1.0 < self.min_step <= 1e3, "1 < r <= 1000"),
            "adjust_mm": (self.adjust_mm, 0.01 <= self.adjust_mm <= 100.0, "0.01 .. 100 mm"),
            "step_ratio": (self.step_ratio, 1.01 <= self.step_ratio <= 10.0, "1.01 .. 10"),
            "min_speed_mm_s": (self.min_speed_mm_s, 0.1 <= self.min_speed_mm_s <= 100.0,
                               "0.1 .. 100 mm/s"),
            "max_slowdown": (self.max_slowdown, 0.0 < self.max_slowdown <= 1.0, "0 < f <= 1"),
            "min_piece_mm": (self.min_piece_mm, 0.01 <= self.min_piece_mm <= 10.0,
                             "0.01 .. 10 mm"),
            "gap_lags": (self.gap_lags, 0.0 <= self.gap_lags <= 100.0, "0 .. 100"),
            "pull_ratio": (self.pull_ratio, 0.0 <= self.pull_ratio <= 20.0, "0 .. 20"),
            "spot_error": (self.spot_error, 0.001 <= self.spot_error <= 10.0, "0.001 .. 10"),
            "spot_reach_mm": (self.spot_reach_mm, 0.0 <= self.spot_reach_mm <= 1000.0,
                              "0 .. 1000 mm"),
            "spot_rounds": (self.spot_rounds, self.spot_rounds in range(1, 11), "1 .. 10"),
        }
        for name, (value, ok, allowed) in checks.items():
            if not (ok and math.isfinite(float(value))):
                raise ProfileError("invalid flow-pacing option", field=name, value=value,
                                   allowed=allowed)
        b = self.time_budget
        if b is not None and (isinstance(b, bool) or not isinstance(b, (int, float))
                              or math.isnan(b) or b < 0.0):
            raise ProfileError("invalid flow-pacing option", field="time_budget", value=b,
                               allowed="a share of the print time >= 0 (0.1 = 10 %), "
                                       "inf or None: no cap")

    @property
    def budget_cap(self) -> float:
        """The time budget as a share of the print time (``inf``: no cap)."""
        return math.inf if self.time_budget is None else float(self.time_budget)


@dataclass(slots=True)
class PaceReport:
    """What the pacing changed.

    Attributes
    ----------
    paced_rows
        Original rows some piece of which got a lower feed, sorted.
    pieces_added
        Pieces the staircases added.
    drop_junctions, step_junctions, rise_starts
        Junctions paced for a falling flow, capped for a cross-section step, and starts
        paced for a rising flow.
    gap_junctions
        Run ends capped as a cross-section step over a short gap to the next run.
    floored_pieces
        Paced pieces held at the floor (``min_speed_mm_s`` / ``max_slowdown``) above the
        envelope.
    time_budget
        The share of the print time the pacing might add (``None``: no cap).
    time_added_s
        Print time the kept pacing adds (planned), s.
    spots
        Spots (places an advance alone leaves beyond ``spot_error``) found in the rounds
        that made the kept draft; 0 when pacing everywhere.
    spots_paced
        Of those, the spots the kept draft is paced near.
    spots_over_budget
        Spots left unpaced because pacing them too would have exceeded the time budget.
    """

    paced_rows: IntArray
    pieces_added: int = 0
    drop_junctions: int = 0
    step_junctions: int = 0
    rise_starts: int = 0
    gap_junctions: int = 0
    floored_pieces: int = 0
    time_budget: float | None = None
    time_added_s: float = 0.0
    spots: int = 0
    spots_paced: int = 0
    spots_over_budget: int = 0

    def as_dict(self) -> dict[str, object]:
        """Plain dict for reports."""
        return {"paced_moves": int(self.paced_rows.size), "pieces_added": self.pieces_added,
                "drop_junctions": self.drop_junctions, "step_junctions": self.step_junctions,
                "rise_starts": self.rise_starts, "gap_junctions": self.gap_junctions,
                "floored_pieces": self.floored_pieces,
                "time_budget": (None if self.time_budget is None
                                or not math.isfinite(self.time_budget)
                                else self.time_budget),
                "time_added_s": self.time_added_s, "spots": self.spots,
                "spots_paced": self.spots_paced, "spots_over_budget": self.spots_over_budget}


def _window_max(a: FloatArray, length: FloatArray, nxt: BoolArray, window_mm: float
                ) -> FloatArray:
    """Largest ``a`` of the pieces within ``window_mm`` of path before the end of each
    piece, inside its run (``nxt[i]``: piece ``i`` continues into ``i + 1``)."""
    from flowtwin.compensation._pace_kernel import window_max  # (loaded when pacing)

    return window_max(np.ascontiguousarray(a, dtype=np.float64),
                      np.ascontiguousarray(length, dtype=np.float64),
                      np.ascontiguousarray(nxt, dtype=np.bool_), float(window_mm))


def pace_feeds(draft: Draft, *, printing: BoolArray, cross_section_mm2: FloatArray,
               lag_k_s: FloatArray, volume_mm3: FloatArray, start_v_mm_s: FloatArray,
               cruise_v_mm_s: FloatArray, end_v_mm_s: FloatArray, t_start_s: FloatArray,
               t_end_s: FloatArray, speed_factor: FloatArray, push_mm3_s: float,
               options: PaceOptions, only: BoolArray | None = None,
               no_pull: BoolArray | None = None) -> tuple[Draft, PaceReport]:
    """Cut the pieces that run faster than the pacing envelopes into slower staircases.

    Parameters
    ----------
    draft
        The draft; every array below has one entry per piece, shape ``(n,)``.
    printing
        Pieces that print (XY motion, positive E); the others break runs.
    cross_section_mm2
        Intended cross-section ``a = V/L`` of every piece, mm².
    lag_k_s
        The twin's lag factor ``K`` of every piece, s.
    volume_mm3
        Commanded volume of every piece, mm³ (retractions negative): the E written between
        two runs charges the column the next run starts with.
    start_v_mm_s, cruise_v_mm_s, end_v_mm_s
        The planner's speeds of every piece, mm/s.
    t_start_s, t_end_s
        Start and end of every piece on the printer clock, s.
    speed_factor
        ``M220`` factor in force on every piece (G-code ``F = 60·v/factor``).
    push_mm3_s
        Volumetric feed the extruder may add above the intent at once, mm³/s (``A_f·J``;
        ``inf``: no rise pacing).
    options
        The limits.
    only
        Pieces where a junction, a run end or a start may be paced (an envelope anchored
        there still slows the pieces before or after it); ``None``: everywhere.
    no_pull
        Pieces paced as if the advance could not pull back (``pull_ratio`` 0 there: where
        it was assumed and a spot remained); ``None``: none.

    Returns
    -------
    tuple
        The paced draft (same pieces where nothing is paced; E per sub-piece in proportion
        to its length, exactly on the E grid) and the report.
    """
    from flowtwin.compensation._pace_kernel import (  # (loaded when pacing)
        end_bounds,
        lay_out_paced,
        staircases,
        start_bounds,
    )

    n = len(draft)
    start = draft.start_xyz()
    seg = draft.xyz_mm - start
    length = np.sqrt(np.sum(seg * seg, axis=1))
    pr = np.asarray(printing, dtype=bool) & (length > 0)
    a = np.where(pr, np.asarray(cross_section_mm2, dtype=np.float64), 0.0)
    k = np.ascontiguousarray(lag_k_s, dtype=np.float64)
    sv = np.ascontiguousarray(start_v_mm_s, dtype=np.float64)
    cv = np.ascontiguousarray(cruise_v_mm_s, dtype=np.float64)
    ev = np.ascontiguousarray(end_v_mm_s, dtype=np.float64)
    m = options.margin
    # junction i -> i+1 inside a run
    nxt = np.zeros(n, dtype=bool)
    if n > 1:
        nxt[:-1] = pr[:-1] & pr[1:]
    a_next = np.concatenate((a[1:], [0.0]))
    k_j = np.concatenate((np.maximum(k[:-1], k[1:]), [k[-1]])) if n else k
    # a cross-section that falls over a stretch shorter than adjust_mm (variable-width
    # walls fall in many small steps) is one step: the largest cross-section within
    # adjust_mm of path before the junction against the one after it
    a_ref = _window_max(a, length, nxt, options.adjust_mm)
    # pulling back while slowing: the melt falls faster
    fall = 1.0 + options.pull_ratio * (1.0 if no_pull is None else
                                       ~np.asarray(no_pull, dtype=bool))
    step_cap = np.where(nxt & (a_ref > options.min_step * a_next), fall * step_speed_mm_s(
        a_ref, np.where(a_next > 0, a_next, 1.0), k_j, adjust_mm=options.adjust_mm), np.inf)
    # flow falls by min_drop: from the piece's top flow to the flow after the junction
    with np.errstate(divide="ignore", invalid="ignore"):
        v_j = np.minimum(ev, step_cap)
        drop = nxt & (a * cv > options.min_drop * a_next * v_j)
    anchor = np.where(drop, v_j, np.inf)
    run_end = pr & ~np.concatenate((pr[1:], [False])) if n else pr
    if options.run_ends:
        # the flow falls to that of the row after the run: none (a stop), or the feed of
        # a row that extrudes without printing (a purge blob on a Z move, a prime)
        q_after = feed_after(volume_mm3, t_start_s, t_end_s)
        with np.errstate(divide="ignore", invalid="ignore"):
            end_v = np.maximum(ev, np.where(a > 0, q_after / np.where(a > 0, a, 1.0), 0.0))
        run_end &= (end_v < cv) & (a * cv > options.min_drop * q_after)
        anchor = np.where(run_end, end_v, anchor)
        drop = drop | run_end
    allowed = np.ones(n, dtype=bool) if only is None else np.asarray(only, dtype=bool)
    drop &= allowed
    anchor = np.where(allowed, anchor, np.inf)
    report = PaceReport(paced_rows=np.zeros(0, dtype=np.int64),
                        drop_junctions=int(np.count_nonzero(drop)),
                        step_junctions=int(np.count_nonzero(drop & np.isfinite(step_cap)
                                                            & (step_cap < ev))))
    # backward pass: the drop envelope's speed at the end of every piece. Across a gap
    # shorter than gap_lags·K (no relief over it) the bound is carried in flow: the outflow
    # may decay by exp(m·gap/K) between the end of a run and the paced top flow of the next
    g = np.where(pr, m * fall / np.where(k > 0, k, np.inf), 0.0)
    ts = np.ascontiguousarray(t_start_s, dtype=np.float64)
    te = np.ascontiguousarray(t_end_s, dtype=np.float64)
    end_bound, gaps = end_bounds(pr, nxt, np.ascontiguousarray(anchor, dtype=np.float64),
                                 np.ascontiguousarray(allowed), g, length, a, k, cv, ts, te,
                                 float(options.gap_lags), float(m))
    report.gap_junctions = gaps
    # forward pass: the rise envelope's speed at the start of every piece
    start_bound = np.full(n, np.inf)
    acc = np.full(n, np.inf)
    if options.rise and math.isfinite(push_mm3_s) and push_mm3_s > 0:
        with np.errstate(divide="ignore", invalid="ignore"):
            acc = np.where(pr & (a > 0) & (k > 0), m * push_mm3_s / (k * a), np.inf)
        prev_pr = np.concatenate(([False], pr[:-1]))
        a_prev = np.concatenate(([0.0], a[:-1]))
        run_start = pr & ~prev_pr
        rising = pr & prev_pr & (a > options.min_drop * a_prev)
        cap_rise = np.where(rising, step_speed_mm_s(a_prev, a, k, adjust_mm=options.adjust_mm),
                            np.inf)
        # a run start builds from the outflow the column carries into it (the gap's E and
        # retractions, column.carried_flows); the first run of a file (after a prime, a
        # purge) is not paced: that state is not the pacing's to know
        starts, q = carried_flows(pr, a * np.minimum(ev, end_bound), volume_mm3=volume_mm3,
                                  t_start_s=t_start_s, t_end_s=t_end_s, lag_k_s=k,
                                  relief_lags=options.gap_lags)
        q_carry = np.full(n, np.inf)  # inf: no run before (not paced)
        q_carry[starts] = q
        with np.errstate(divide="ignore", invalid="ignore"):
            v_carry = np.where(a > 0, q_carry / np.where(a > 0, a, 1.0), 0.0)
        start_ok = run_start & (a * cv > options.min_drop * q_carry) & allowed
        v0 = np.where(start_ok, np.maximum(sv, v_carry),
                      np.where(rising & allowed, np.minimum(sv, cap_rise), np.inf))
        report.rise_starts = int(np.count_nonzero(np.isfinite(v0) & (v0 < cv)))
        start_bound = start_bounds(pr, np.ascontiguousarray(v0, dtype=np.float64),
                                   np.ascontiguousarray(acc, dtype=np.float64), length, cv)
    # pieces to cut
    floor = np.maximum(options.min_speed_mm_s, options.max_slowdown * cv)
    over = pr & (cv > floor * (1.0 + _SAME)) & ((end_bound < cv * (1.0 - _SAME))
                                               | (start_bound < cv * (1.0 - _SAME)))
    pieces = np.flatnonzero(over)
    if pieces.size == 0:
        return draft, report
    # the squares the staircase's definition takes with ``**`` (the C library's pow)
    cv_sq = np.array([v ** 2 for v in cv[pieces].tolist()])
    start_sq = np.array([v ** 2 for v in start_bound[pieces].tolist()])
    kept, counts, sub_ends, sub_v, floored = staircases(
        pieces, length, cv, cv_sq, end_bound, g, start_bound, start_sq, acc,
        np.ascontiguousarray(floor, dtype=np.float64),
        np.ascontiguousarray(draft.e_grid, dtype=np.int64), float(options.step_ratio),
        float(options.min_piece_mm), _SAME)
    report.floored_pieces = int(floored)
    if kept.size == 0:
        return draft, report
    new_counts = np.ones(n, dtype=np.int64)
    new_counts[kept] = counts
    piece = np.repeat(np.arange(n, dtype=np.int64), new_counts)
    offsets = np.concatenate(([0], np.cumsum(new_counts)))
    xyz = draft.xyz_mm[piece].copy()
    e = draft.e_grid[piece].copy()
    feed = draft.piece_feed_mm_min[piece].copy()
    lay_out_paced(kept, counts, sub_ends, sub_v, offsets, length,
                  np.ascontiguousarray(start, dtype=np.float64),
                  np.ascontiguousarray(seg, dtype=np.float64),
                  np.ascontiguousarray(draft.xyz_mm, dtype=np.float64),
                  np.ascontiguousarray(draft.e_grid, dtype=np.int64),
                  np.ascontiguousarray(draft.piece_feed_mm_min, dtype=np.float64), cv,
                  np.ascontiguousarray(speed_factor, dtype=np.float64), _SAME, xyz, e, feed)
    report.pieces_added = int(offsets[-1] - n)
    report.paced_rows = np.unique(draft.row[kept])
    return draft.split(piece, xyz, e, feed), report
