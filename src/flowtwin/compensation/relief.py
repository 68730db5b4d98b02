"""Pressure relief over travels between printing runs.

The advance law [001 Eq. 11] commands ``−K·v⁰_E`` where the flow stops, which a G-code
can only do as a retraction. A travel between two printing runs (long enough for the melt
to ooze, :func:`travel_interims`) gets an E-only retraction of twice the compression the
lag model predicts at the run's end and a push-back that leaves the column relaxed
(:func:`relief_amounts`, :func:`insert_relief`); a travel the slicer already retracts
for holds that compression through the travel, and its push-back is shortened by it
(:func:`retraction_interims`). The refinement may leave a *pre-charge* in the push-back
for the next run's first moves (:func:`first_free_pieces`,
:func:`flowtwin.compensation.refine.refine_qp`). A later pass finds the reliefs an earlier
one made (:func:`relieved_gaps`) and models them the same way.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from flowtwin.compensation._refine_kernel import row_starts
from flowtwin.compensation.limits import ExtruderLimits
from flowtwin.compensation.pieces import Pieces
from flowtwin.compensation.refine import LagModel
from flowtwin.gcode.moves import MoveKind
from flowtwin.planner.timeline import Timeline

__all__ = [
    "ALONG_LIMIT",
    "MIN_RELIEF_MM",
    "RELIEF_MARGIN",
    "RELIEF_SPEED_MM_S",
    "along_ratio",
    "first_free_pieces",
    "gaps",
    "insert_relief",
    "relief_amounts",
    "relieved_gaps",
    "retraction_interims",
    "row_start_states",
    "start_gap",
    "travel_interims",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Relief is added only when the compression at a run's end is at least this many mm.
MIN_RELIEF_MM = 0.002
#: Retract this many times the predicted compression, so the melt stops early in the move.
RELIEF_MARGIN = 2.0
#: Speed of the relief retraction and push-back, mm/s (capped by the firmware's limit).
RELIEF_SPEED_MM_S = 35.0


def gaps(elig: npt.NDArray[np.bool_], timeline: Timeline,
          min_time_s: FloatArray) -> list[tuple[int, int]]:
    """Stretches ``i .. j-1`` of non-printing rows between two runs (rows ``i-1`` and ``j``
    print) lasting at least ``min_time_s[i-1]``, as ``(i, j)``."""
    n = elig.shape[0]
    if n < 3:
        return []
    e = elig.astype(np.int8)
    first = np.flatnonzero(np.diff(e) == -1) + 1  # a printing row, then not
    last = np.flatnonzero(np.diff(e) == 1) + 1    # not, then a printing row
    if not first.size or not last.size:
        return []
    # pair each gap start with the next printing row after it
    k = np.searchsorted(last, first, side="left")
    ok = k < last.size
    i, j = first[ok], last[k[ok]]
    start = np.asarray(timeline.phases["t_start"], dtype=np.float64)
    end = timeline.end_time_s
    keep = start[j] - end[i - 1] >= min_time_s[i - 1]
    return list(zip(i[keep].tolist(), j[keep].tolist(), strict=True))


def start_gap(elig: npt.NDArray[np.bool_]) -> list[tuple[int, int]]:
    """The rows before the file's first run, ``[(0, j)]`` (``j`` its first row), or none.

    A print starts with a prime (Cura's ``G1 F200 E3``, a purge) whose compression a
    retraction holds over the travel to the first run like any run's end.
    """
    first = np.flatnonzero(elig)
    return [(0, int(first[0]))] if first.size and first[0] > 0 else []


def travel_interims(elig: npt.NDArray[np.bool_], kind: npt.NDArray[np.uint8], row_e: IntArray,
              timeline: Timeline, min_time_s: FloatArray) -> list[tuple[int, int]]:
    """Travel rows ``(first, last)`` that may relieve the pressure between two runs.

    An interim qualifies when it lies between two printing rows, moves no E itself, has at
    least one XY travel and lasts at least ``min_time_s`` of the row before it (a shorter
    one lets little melt ooze, and a relief would only add two stops);
    ``first``/``last`` are its first and last XY travels.
    """
    out: list[tuple[int, int]] = []
    for i, j in gaps(elig, timeline, min_time_s):
        if np.all(row_e[i:j] == 0):
            xy = [k for k in range(i, j)
                  if (kind[k] & MoveKind.XY) and (kind[k] & MoveKind.TRAVEL)]
            if xy:
                out.append((xy[0], xy[-1]))
    return out


def retraction_interims(elig: npt.NDArray[np.bool_], kind: npt.NDArray[np.uint8],
                         row_e: IntArray, tool: npt.NDArray[np.integer], timeline: Timeline,
                         min_time_s: FloatArray) -> list[tuple[int, int]]:
    """Retracting interims between two runs whose push-back can relieve the pressure.

    The slicer's own retraction holds the compression of the run's end through the travel
    (no backflow), and its push-back restores it: the next run starts with the pressure
    of a full-speed end, which it cannot absorb from rest (a short first move gets it
    all). Shortening the push-back by that compression starts the next run relaxed, as
    the advance law wants [001 Eq. 11] (the ``−K·v⁰_E`` where the flow stops). An interim
    qualifies when it lasts at least ``min_time_s`` of the row before it, retracts (a row
    with negative E) and pushes back at least as much in a later E-only row written in
    the G-code, all with one tool (a tool change loads another filament: its push-back is
    not this column's). The hold starts at the first retracting row: travels before it
    (a slicer that travels first, PrusaSlicer's move off its purge line) let the melt
    ooze like any gap. The rows before the file's first run count as such an interim
    (:func:`start_gap`): a prime (Cura's ``G1 F200 E3``) compresses the column, its
    retraction holds that over the travel to the first run, whose first moves got it all
    (Cura 4.13: the skirt's first 0.6 mm +157 %, +211 % once advanced).

    Returns
    -------
    list of tuple
        ``(first retracting row, push-back row)``.
    """
    i, j = _stretches([*start_gap(elig), *gaps(elig, timeline, min_time_s)])
    if not i.size:
        return []
    first_neg, last_pos, total = _signs(np.asarray(row_e, dtype=np.int64), i, j)
    # one tool from the row before the interim to the run after it
    change = np.concatenate(([0], np.cumsum(tool[1:] != tool[:-1])))
    one_tool = change[j] == change[np.maximum(i - 1, 0)]
    push = np.maximum(last_pos, 0)
    ok = (one_tool & (first_neg < j) & (last_pos >= i) & (last_pos > first_neg) & (total >= 0)
          & ((kind[push] & (MoveKind.XY | MoveKind.FW_RETRACT)) == 0))
    return list(zip(first_neg[ok].tolist(), last_pos[ok].tolist(), strict=True))


def _stretches(spans: list[tuple[int, int]]) -> tuple[IntArray, IntArray]:
    """Starts and ends of ``(i, j)`` stretches as two arrays."""
    a = np.array(spans, dtype=np.int64).reshape(-1, 2)
    return a[:, 0], a[:, 1]


def _signs(e: IntArray, i: IntArray, j: IntArray) -> tuple[IntArray, IntArray, IntArray]:
    """For every stretch ``e[i:j]`` (``i < j``): the index of its first negative entry
    (``>= j``: none), of its last positive entry (``< i``: none) and its sum."""
    n = e.shape[0]
    idx = np.arange(n, dtype=np.int64)
    next_neg = np.minimum.accumulate(np.where(e < 0, idx, n)[::-1])[::-1]
    last_pos = np.maximum.accumulate(np.where(e > 0, idx, -1))
    csum = np.concatenate(([0], np.cumsum(e)))
    return next_neg[i], last_pos[j - 1], csum[j] - csum[i]


def relieved_gaps(elig: npt.NDArray[np.bool_], row_e: IntArray, group: IntArray,
                   orig_e: IntArray, timeline: Timeline) -> list[tuple[int, int, int, int]]:
    """Holds between runs that an earlier pass sized to leave the next run relaxed (or
    pre-charged).

    The first pass relieves the pressure between runs: a relief retraction pushes back
    less than it retracts, a slicer's push-back is shortened, both by the compression its
    lag model predicts when the hold starts less the pre-charge (:func:`relief_amounts`),
    so that the next run starts as that model assumed. A later pass sees only the shortfall: a hold
    whose push-back is short by a fixed amount carries the run's end compression *minus*
    that amount into the next run, so raising a run's end (over-extruding it) would feed
    the next run's start through the travel, a lever the first pass ruled out (it cost the
    PrusaSlicer 2.8.1 minicube +13 % on the last move of a run, to lift a −97 % 0.06 mm arc
    after the travel). The gap between two runs is such a relief where its E adds up to
    less than the whole original rows it holds (the first pass took the difference off).

    Parameters
    ----------
    elig
        Printing rows, shape ``(n,)``.
    row_e
        E of every row, grid units, shape ``(n,)``.
    group
        Original row of every row (non-decreasing), shape ``(n,)``.
    orig_e
        E of every original row, grid units.
    timeline
        The rows' phases.

    Returns
    -------
    list of tuple
        ``(hold row, push-back row, next run's first row, shortfall)``: the gap's first
        retracting row, its last pushing-back row (``-1``: none), the printing row after
        the gap, and the grid units the earlier pass took off.
    """
    i, j = _stretches([*start_gap(elig), *gaps(elig, timeline, np.zeros(elig.shape[0]))])
    if not i.size:
        return []
    first_neg, last_pos, total = _signs(np.asarray(row_e, dtype=np.int64), i, j)
    group = np.asarray(group, dtype=np.int64)
    orig = np.asarray(orig_e, dtype=np.int64)
    # an original row split between a run and the gap would mix its printing E in
    # (``group`` is non-decreasing: such a row is the gap's first or last row's)
    split = (((i > 0) & (group[np.maximum(i - 1, 0)] == group[i]))
             | (group[j - 1] == group[j]))
    # E of the gap's original rows: each counted at its first row in the gap
    new = np.concatenate(([True], group[1:] != group[:-1]))
    counted = np.concatenate(([0], np.cumsum(np.where(new, orig[group], 0))))
    short = orig[group[i]] + counted[j] - counted[i + 1] - total
    ok = (first_neg < j) & ~split & (short > 0)
    back = np.where((last_pos >= i) & (last_pos > first_neg), last_pos, -1)
    return list(zip(first_neg[ok].tolist(), back[ok].tolist(), j[ok].tolist(),
                    short[ok].tolist(), strict=True))


def row_start_states(model: LagModel, states: FloatArray, n_rows: int) -> FloatArray:
    """Model state when every row's own motion starts (after the rest before it: a
    heat-up wait or a dwell lets the melt ooze), ``nan`` for rows without segments.

    Parameters
    ----------
    model
        The lag model.
    states
        State at the end of every segment (:meth:`LagModel.states`), grid units.
    n_rows
        Rows of the rendered draft.

    Returns
    -------
    ndarray
        Shape ``(n_rows,)``, grid units (``0`` before the file's first segment).
    """
    out = np.full(n_rows, np.nan)
    row_starts(model.seg_gap, model.seg_owner, np.ascontiguousarray(states, dtype=np.float64),
               out)
    return out


def relief_amounts(travels: list[tuple[int, int]], start_state: FloatArray | None,
                   precharge: FloatArray | None = None, *, e_unit_mm: float,
                   keep_zero: bool = False) -> list[tuple[int, int, int, int]]:
    """Retraction and push-back of every relieved interim, grid units.

    The lag model gives the compression ``x`` when the interim starts (the end of the run
    before, less what oozed during a rest between);
    the retraction takes twice that (so the melt stops at once), the push-back returns all
    but ``x − y``: the next run starts with the pre-charge ``y`` the refinement chose
    (``0 ≤ y ≤ x``; relaxed without one) and builds the rest of its pressure from its
    own E.

    Parameters
    ----------
    travels
        ``(first row, last row)`` of every interim.
    start_state
        Model state when every row starts (:func:`row_start_states`), grid units;
        ``None``: no model (nothing is relieved).
    precharge
        Pre-charge of every interim, grid units (default none).
    e_unit_mm
        Size of one grid unit, mm.
    keep_zero
        Every interim gets an entry (``(a, b, 0, 0)`` where nothing is known or the
        compression is below the threshold), in order.

    Returns
    -------
    list of tuple
        ``(first row, last row, retraction, push-back)`` per relieved interim.
    """
    if start_state is None or not travels:
        return [(a, b, 0, 0) for a, b in travels] if keep_zero else []
    out: list[tuple[int, int, int, int]] = []
    for k, (a, b) in enumerate(travels):
        x = float(start_state[a])
        x_end = max(x, 0.0) if math.isfinite(x) else 0.0
        retract = int(math.ceil(RELIEF_MARGIN * x_end)) + 1
        if not math.isfinite(x) or retract * e_unit_mm < MIN_RELIEF_MM:
            if keep_zero:
                out.append((a, b, 0, 0))
            continue
        y = 0.0 if precharge is None else min(max(float(precharge[k]), 0.0), x_end)
        out.append((a, b, retract, retract - int(round(x_end)) + int(round(y))))
    return out


def first_free_pieces(next_rows: IntArray, pieces: Pieces,
                      free_pieces: IntArray) -> IntArray:
    """Free variable of the first piece of every run after a relieved travel, the piece
    its pre-charge feeds (see :func:`flowtwin.compensation.refine.refine_qp`).

    Parameters
    ----------
    next_rows
        First printing row after every relieved travel, shape ``(k,)``.
    pieces
        All rows' pieces.
    free_pieces
        Piece of every free variable, ascending (``LagModel.free_pieces``).

    Returns
    -------
    ndarray
        Variable index, ``-1`` where that piece is not free, shape ``(k,)``.
    """
    first = pieces.offsets[np.asarray(next_rows, dtype=np.int64)]
    if free_pieces.size == 0:
        return np.full(first.size, -1, dtype=np.int64)
    k = np.searchsorted(free_pieces, first)
    ok = (k < free_pieces.size) & (free_pieces[np.minimum(k, free_pieces.size - 1)] == first)
    return np.where(ok, k, -1).astype(np.int64)


def insert_relief(reliefs: list[tuple[int, int, int, int]], piece_of: IntArray,
                   xyz: FloatArray, e_piece: IntArray, feed: FloatArray, start: FloatArray,
                  end: FloatArray, limits: ExtruderLimits, *,
                  along: tuple[FloatArray, FloatArray, npt.NDArray[np.bool_]] | None = None,
                  e_unit_mm: float = 0.0
                  ) -> tuple[IntArray, FloatArray, IntArray, FloatArray, int]:
    """Insert every relief's retraction where its interim starts and its push-back where
    it ends.

    On Klipper (``along`` given) both are laid along the interim's travels where they
    fit, at the steepest ratio ``|E|/path`` that leaves the travel's own speed and
    acceleration alone (:func:`along_ratio`): the retraction on the first millimetres of
    the path, the push-back on the last. Klipper runs an E-only move at
    ``max_extrude_only_accel`` (~800 mm/s² of filament by default) with the head standing
    on both sides of it; a retraction that moves the head is held to the same limits
    divided by its ratio (``kinematics/extruder.py`` ``check_move``), so it pulls the
    filament back as fast while the head travels. The head still slows down where the
    ratio steps (``v ≤ instantaneous_corner_velocity/|Δρ|``), but no longer stops twice
    and waits for two E-only moves: measured on the dev Cura ring (Klipper, 3000 mm/s²),
    the advance's print time +29.5 % → +23.9 % with the same flow error
    (docs/compensation.md). Elsewhere (Marlin, whose E-only moves cost ~6 ms, or travels
    too short) they are E-only moves at :data:`RELIEF_SPEED_MM_S`.

    Parameters
    ----------
    reliefs
        ``(first row, last row, retraction, push-back)`` per interim (grid units), in order.
    piece_of, xyz, e_piece, feed
        Row, end point (mm), E (grid units) and feed (mm/min) of every piece, shapes
        ``(m,)`` and ``(m, 3)``.
    start, end
        Start and end point of every row, mm, shape ``(n, 3)``.
    limits
        The firmware's extruder limits.
    along
        Requested speed (mm/s) and planned acceleration (mm/s²) of every row, and which
        rows are XY travels, shapes ``(n,)``; ``None``: E-only moves.
    e_unit_mm
        Size of one grid unit, mm (needed with ``along``).

    Returns
    -------
    tuple
        Row, end point, E and feed of the pieces with the reliefs, and how many reliefs
        were laid along their travels.
    """
    speed = min(RELIEF_SPEED_MM_S, 0.9 * limits.e_only_speed_mm_s)
    feed_mm_min = 60.0 * speed
    n = piece_of.size
    if n == 0 or not reliefs:
        return piece_of, xyz, e_piece, feed, 0
    arr = np.array(reliefs, dtype=np.int64).reshape(-1, 4)
    row_a, row_b, ret, back = arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3]
    first_of = np.searchsorted(piece_of, row_a, side="left")
    after_last = np.searchsorted(piece_of, row_b, side="right")
    laid = np.zeros(arr.shape[0], dtype=bool)
    # every output piece sorted by (original piece it comes before, order there,
    # index within its block); the pieces a relief laid along replaces drop out
    keep = np.ones(n, dtype=bool)
    parts: list[tuple[IntArray, IntArray, IntArray, IntArray, FloatArray, IntArray,
                      FloatArray]] = []
    if along is not None and limits.firmware == "klipper" and e_unit_mm > 0:
        row_speed, row_accel, xy_travel = along
        rho = along_ratio(row_speed, row_accel, limits)  # of every row, once
        for k in range(arr.shape[0]):
            p0, p1 = int(first_of[k]), int(after_last[k])
            lay = _lay_along(int(row_a[k]), int(row_b[k]), int(ret[k]), int(back[k]), p0,
                             p1, xyz, start, rho, xy_travel, e_unit_mm)
            if lay is None:
                continue
            pts, es, of = lay
            laid[k] = True
            keep[p0:p1] = False
            parts.append((np.full(of.size, p0), np.full(of.size, 2), np.arange(of.size),
                          piece_of[p0 + of], pts, es, feed[p0 + of]))
    e_only = ~laid
    push = e_only & (back > 0)
    m_push, m_ret = int(np.count_nonzero(push)), int(np.count_nonzero(e_only))
    # E-only: at a shared place the push-back of the row before comes first
    parts.append((after_last[push], np.zeros(m_push, dtype=np.int64),
                  np.zeros(m_push, dtype=np.int64), row_b[push], end[row_b[push]],
                  back[push], np.full(m_push, feed_mm_min)))
    parts.append((first_of[e_only], np.ones(m_ret, dtype=np.int64),
                  np.zeros(m_ret, dtype=np.int64), row_a[e_only], start[row_a[e_only]],
                  -ret[e_only], np.full(m_ret, feed_mm_min)))
    kept = np.flatnonzero(keep)
    parts.append((kept, np.full(kept.size, 3), np.zeros(kept.size, dtype=np.int64),
                  piece_of[kept], xyz[kept], e_piece[kept], feed[kept]))
    at, key, sub, rows, pts, es, fs = (np.concatenate([pt[c] for pt in parts])
                                       for c in range(7))
    order = np.lexsort((sub, key, at))
    return (rows[order].astype(np.int64), pts[order], es[order].astype(np.int64),
            fs[order].astype(np.float64), int(np.count_nonzero(laid)))


#: Share of Klipper's limits the ratio ``|E|/path`` of a relief laid along may use.
ALONG_LIMIT = 0.9


def along_ratio(speed_mm_s: FloatArray, accel_mm_s2: FloatArray,
                limits: ExtruderLimits) -> FloatArray:
    """Largest ratio ``|E|/path`` a relief laid along a travel may have on Klipper.

    Klipper holds a move whose E runs backwards to ``max_extrude_only_velocity/|ρ|`` and
    ``max_extrude_only_accel/|ρ|`` (``ρ`` = E per mm of path), and refuses a forward one
    with ``ρ`` above ``max_extrude_cross_section``/filament area unless its E is tiny
    (``kinematics/extruder.py`` ``check_move``). :data:`ALONG_LIMIT` times the smallest
    of ``e_only_accel/a``, ``e_only_speed/v`` and that ratio keeps the travel's own speed
    ``v`` and acceleration ``a`` and is accepted.

    Parameters
    ----------
    speed_mm_s, accel_mm_s2
        Requested speed and planned acceleration of the travels, any shape.
    limits
        Klipper's extruder limits.

    Returns
    -------
    ndarray
        E mm per mm of path, the shape of the inputs (0 where nothing is known).
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.minimum(np.minimum(limits.e_only_accel_mm_s2 / np.asarray(accel_mm_s2),
                                  limits.e_only_speed_mm_s / np.asarray(speed_mm_s)),
                       limits.max_ratio)
    return ALONG_LIMIT * np.where(np.isfinite(r) & (r > 0), r, 0.0)


#: Closest a relief laid along may cut a travel to one of its ends, mm.
_MIN_CUT_MM = 0.005


def _lay_along(a: int, b: int, ret: int, back: int, p0: int, p1: int, xyz: FloatArray,
               start: FloatArray, rho_row: FloatArray, xy_travel: npt.NDArray[np.bool_],
               e_unit_mm: float) -> tuple[FloatArray, IntArray, IntArray] | None:
    """Points, E and original piece (counted from ``p0``) of the pieces of one interim
    (rows ``a … b``, pieces ``p0:p1``) with its relief laid along, or ``None`` where it
    does not fit (a row in it that is not an XY travel of one piece, or a path too short
    for both parts at the rows' :func:`along_ratio` ``rho_row``)."""
    # every row has a piece: as many pieces as rows is one piece each
    if p1 - p0 != b - a + 1 or not np.all(xy_travel[a:b + 1]):
        return None
    pts = np.vstack((start[a][None, :], xyz[p0:p1]))
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    cum = np.concatenate(([0.0], np.cumsum(seg)))
    total = float(cum[-1])  # (the last row's own end, to the bit: it must keep its piece)
    if np.any(seg <= _MIN_CUT_MM):
        return None
    rho = float(np.min(rho_row[a:b + 1]))
    if rho <= 0:
        return None
    # the push-back's part is sized for the whole retraction: a later pass may push back
    # up to that much (:func:`relieved_gaps`)
    d = max(ret, back) * e_unit_mm / rho
    if not 0.0 < 2.0 * d <= total:
        return None
    # cut the path where the retraction ends and the push-back starts
    cuts = np.array([d, total - d])
    # a cut within a few µm of a row's end would leave a piece too short to write
    cuts = cuts[np.min(np.abs(cuts[:, None] - cum[None, :]), axis=1) > _MIN_CUT_MM]
    s_all = np.unique(np.concatenate((cum, cuts)))
    s_all = s_all[(s_all > 0) & (s_all <= total)]
    # E at every new end point: −ret over [0, d], then +back over [total − d, total]
    e_at = (-ret * np.minimum(s_all, d) / d
            + back * np.maximum(s_all - (total - d), 0.0) / d)
    e_cum = np.rint(e_at).astype(np.int64)
    e_cum[-1] = back - ret
    es = np.diff(np.concatenate(([0], e_cum)))
    seg_of = np.minimum(np.searchsorted(cum, s_all, side="left") - 1, seg.size - 1)
    t = (s_all - cum[seg_of]) / np.maximum(seg[seg_of], 1e-12)
    out = pts[seg_of] + (pts[seg_of + 1] - pts[seg_of]) * t[:, None]
    return out, es, seg_of.astype(np.int64)
