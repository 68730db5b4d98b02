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
    "MIN_RELIEF_MM",
    "RELIEF_MARGIN",
    "RELIEF_SPEED_MM_S",
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
                  end: FloatArray, limits: ExtruderLimits
                  ) -> tuple[IntArray, FloatArray, IntArray, FloatArray]:
    """Insert an E-only retraction before each relieved interim's first travel and the
    push-back after its last one."""
    speed = min(RELIEF_SPEED_MM_S, 0.9 * limits.e_only_speed_mm_s)
    feed_mm_min = 60.0 * speed
    n = piece_of.size
    if n == 0 or not reliefs:
        return piece_of, xyz, e_piece, feed
    rows_b = np.array([a for a, _b, _r, _back in reliefs], dtype=np.int64)
    amount_b = np.array([-r for _a, _b, r, _back in reliefs], dtype=np.int64)
    after = [(b, back) for _a, b, _r, back in reliefs if back > 0]
    rows_a = np.array([b for b, _back in after], dtype=np.int64)
    amount_a = np.array([back for _b, back in after], dtype=np.int64)
    first_of = np.searchsorted(piece_of, rows_b, side="left")   # before a row's first piece
    after_last = np.searchsorted(piece_of, rows_a, side="right")  # after a row's last one
    # at a shared position the push-back of the row before comes first
    pos = np.concatenate((after_last * 2, first_of * 2 + 1))
    order = np.argsort(pos, kind="stable")
    at = np.concatenate((after_last, first_of))[order]
    ins_row = np.concatenate((rows_a, rows_b))[order]
    ins_pt = np.vstack((end[rows_a], start[rows_b]))[order] if at.size else xyz[:0]
    ins_e = np.concatenate((amount_a, amount_b))[order]
    # the original pieces move up by the insertions before them
    total = n + at.size
    new_idx = np.arange(n) + np.searchsorted(at, np.arange(n), side="right")
    ins_idx = at + np.arange(at.size)
    rows = np.empty(total, dtype=np.int64)
    pts = np.empty((total, 3))
    es = np.empty(total, dtype=np.int64)
    fs = np.empty(total)
    rows[new_idx], pts[new_idx], es[new_idx], fs[new_idx] = piece_of, xyz, e_piece, feed
    rows[ins_idx], pts[ins_idx], es[ins_idx] = ins_row, ins_pt, ins_e
    fs[ins_idx] = feed_mm_min
    return rows, pts, es, fs
