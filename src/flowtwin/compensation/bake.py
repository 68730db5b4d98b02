"""One pass of the advance transformation over a draft.

The draft's rendered file has been read and planned: its rows are the draft's pieces.
A pass

1. cuts the printing rows at their phase boundaries (first pass only;
   :mod:`flowtwin.compensation.pieces`),
2. gives every piece its E by the advance law within the firmware's limits
   (:func:`flowtwin.compensation.advance.follow_law`),
3. optionally refines the E with the twin's lag model so that every *original* move
   delivers its own volume (:mod:`flowtwin.compensation.refine`),
4. optionally relieves the pressure over travels between printing runs (first pass only):
   the advance law [001 Eq. 11] commands ``−K·v⁰_E`` where the flow stops, which a G-code
   can only do as a retraction. The travel after a run retracts the compression the twin
   predicts at the run's end, the travel's end pushes the same length back (net E zero),
   so the melt does not ooze away during the travel [001 Fig. 8].

Every run of printing pieces keeps its exact E, so the file keeps its total.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from flowtwin.compensation.advance import (
    AdvanceLaw,
    AdvanceOptions,
    eligible_rows,
    follow_law,
    round_runs,
)
from flowtwin.compensation.draft import Draft
from flowtwin.compensation.limits import ExtruderLimits
from flowtwin.compensation.pieces import Pieces, split_rows
from flowtwin.compensation.refine import LagModel, build_lag_model, refine_qp
from flowtwin.gcode.moves import MoveKind, MoveTable
from flowtwin.planner.timeline import Timeline

__all__ = ["PassReport", "advance_pass"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Relief is added only when the compression at a run's end is at least this many mm.
_MIN_RELIEF_MM = 0.002
#: Retract this many times the predicted compression, so the melt stops early in the move.
_RELIEF_MARGIN = 2.0
#: Speed of the relief retraction and push-back, mm/s (capped by the firmware's limit).
_RELIEF_SPEED_MM_S = 35.0


@dataclass(slots=True)
class PassReport:
    """What one pass did.

    Attributes
    ----------
    pieces
        Pieces after the pass (relief retractions included).
    runs
        Printing runs.
    law_counts
        Pieces moved off the law's target by the limits (see ``follow_law``).
    refinement
        Figures of the refinement (empty without it).
    relief_travels
        Travels given a pressure-relief retraction.
    relief_mm
        Total length retracted (and pushed back) by the reliefs, mm of filament.
    relief_retractions
        Retracting travels whose push-back was shortened by the compression at the end of
        the run before (the next run starts relaxed).
    relief_retraction_mm
        Total length taken off those push-backs, mm of filament.
    """

    pieces: int = 0
    runs: int = 0
    law_counts: dict[str, int] = field(default_factory=dict)
    refinement: dict[str, float] = field(default_factory=dict)
    relief_travels: int = 0
    relief_mm: float = 0.0
    relief_retractions: int = 0
    relief_retraction_mm: float = 0.0


def _gaps(elig: npt.NDArray[np.bool_], timeline: Timeline,
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


def _interims(elig: npt.NDArray[np.bool_], kind: npt.NDArray[np.uint8], row_e: IntArray,
              timeline: Timeline, min_time_s: FloatArray) -> list[tuple[int, int]]:
    """Travel rows ``(first, last)`` that may relieve the pressure between two runs.

    An interim qualifies when it lies between two printing rows, moves no E itself, has at
    least one XY travel and lasts at least ``min_time_s`` of the row before it (a shorter
    one lets little melt ooze, and a relief would only add two stops);
    ``first``/``last`` are its first and last XY travels.
    """
    out: list[tuple[int, int]] = []
    for i, j in _gaps(elig, timeline, min_time_s):
        if np.all(row_e[i:j] == 0):
            xy = [k for k in range(i, j)
                  if (kind[k] & MoveKind.XY) and (kind[k] & MoveKind.TRAVEL)]
            if xy:
                out.append((xy[0], xy[-1]))
    return out


def _retraction_interims(elig: npt.NDArray[np.bool_], kind: npt.NDArray[np.uint8],
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
    not this column's).

    Returns
    -------
    list of tuple
        ``(first interim row, push-back row)``.
    """
    out: list[tuple[int, int]] = []
    for i, j in _gaps(elig, timeline, min_time_s):
        if np.all(tool[i - 1:j + 1] == tool[i - 1]):
            e = row_e[i:j]
            neg = np.flatnonzero(e < 0)
            pos = np.flatnonzero(e > 0)
            if neg.size and pos.size and pos[-1] > neg[0] and int(np.sum(e)) >= 0:
                r = i + int(pos[-1])
                if (kind[r] & (MoveKind.XY | MoveKind.FW_RETRACT)) == 0:
                    out.append((i, r))
    return out


def advance_pass(draft: Draft, table: MoveTable, timeline: Timeline, lag_k_s: FloatArray,
                 limits: ExtruderLimits, options: AdvanceOptions, *, e_unit_mm: float,
                 split: bool, relief: bool, state_max: FloatArray | None = None,
                 delivered: FloatArray | None = None) -> tuple[Draft, PassReport]:
    """Give the draft's printing pieces their advanced E (see the module docstring).

    Parameters
    ----------
    draft
        The draft; its rendered file's rows are ``table``.
    table, timeline
        The rendered draft read and planned (``len(table) == len(draft)``).
    lag_k_s
        The twin's lag factor of every row, s.
    limits
        The firmware's extruder limits.
    options
        Law and settings.
    e_unit_mm
        Size of one E grid unit, mm.
    split
        Cut printing rows at their phase boundaries.
    relief
        Add pressure relief on travels between runs.
    state_max
        Largest compression of the column during every row, grid units (the feed force
        at which the drive would grind, with a margin); ``None``: no cap.
    delivered
        What the twin predicts the draft *as it is* delivers, per original row, E grid
        units without the drive's slip (the slip stage corrects that), shape
        ``(n_original_rows,)``; only with ``split=False``. The lag model is linear and
        leaves out what the twin adds (the melt's nonlinear flow, temperatures, holds
        it models differently); the refinement then aims the model at
        ``intent + (model(draft) − delivered)`` — one step of iterative learning control
        with the model as the plant's Jacobian, so the twin's own figure converges where
        the model alone stops.

    Returns
    -------
    tuple
        The new draft and a :class:`PassReport`.
    """
    n = len(table)
    kind = np.asarray(table.moves["kind"], dtype=np.uint8)
    group = draft.row
    orig_elig = eligible_rows(draft.table, draft.row_e)
    cur_e = draft.e_grid
    elig = orig_elig[group] & ((kind & MoveKind.XY) != 0) & (cur_e > 0)
    smoothed = options.law is AdvanceLaw.SMOOTHED
    w = options.smooth_time_s
    pieces = split_rows(timeline, elig if split else np.zeros(n, dtype=bool),
                        accel_pieces=options.accel_pieces if smoothed else 1,
                        max_piece_s=options.piece_time_fraction * w if smoothed else 0.0,
                        cruise_edge_s=0.5 * w if smoothed else 0.0,
                        min_piece_mm=options.min_piece_mm)
    # the law's E⁰: each original move's intent spread over its rows by planned length
    row_len = pieces.row_length_mm
    group_len = np.bincount(group, weights=np.where(elig, row_len, 0.0), minlength=draft.n_rows)
    with np.errstate(divide="ignore", invalid="ignore"):
        intent_row = np.where(elig & (group_len[group] > 0),
                              draft.row_e[group] * row_len / group_len[group],
                              cur_e.astype(np.float64))
    k_la = (np.full(n, options.k_s) if options.k_s is not None
            else options.k_scale * np.asarray(lag_k_s, dtype=np.float64))
    law = follow_law(pieces, timeline, elig, intent_row, cur_e, k_la, limits, options,
                     e_unit_mm=e_unit_mm, xy_rows=(kind & MoveKind.XY) != 0)
    report = PassReport(runs=int(law.run_total.size), law_counts=dict(law.counts))
    e_run = law.e
    interims = (_interims(elig, kind, cur_e, timeline,
                          options.relief_min_lags * np.asarray(lag_k_s, dtype=np.float64))
                if relief else [])
    retracting = (_retraction_interims(elig, kind, cur_e, table.moves["tool"], timeline,
                                       options.relief_min_lags
                                       * np.asarray(lag_k_s, dtype=np.float64))
                  if relief else [])
    holds = np.zeros(n, dtype=bool)
    for a, _b in [*interims, *retracting]:
        holds[a] = True
    elig_orig_rows = np.flatnonzero(orig_elig)
    group_index = np.full(draft.n_rows, -1, dtype=np.int64)
    group_index[elig_orig_rows] = np.arange(elig_orig_rows.size)
    row_group = np.where(elig, group_index[group], -1)
    model = None
    if options.refine is not None and law.sel.size:
        free = np.zeros(len(pieces), dtype=bool)
        free[law.sel] = True
        row_phys = cur_e.astype(np.float64)
        plen = pieces.row_length_mm[pieces.row]
        ratio = np.where(plen > 0, row_phys[pieces.row] / np.where(plen > 0, plen, 1.0), 0.0)
        model = build_lag_model(pieces, timeline, np.asarray(lag_k_s, dtype=np.float64), free,
                                ratio, row_phys, row_group, int(elig_orig_rows.size),
                                travel_holds=holds)
        intent = draft.row_e[elig_orig_rows].astype(np.float64)
        # a first pass starts from the law; later passes from the draft's own E (already
        # refined, now re-planned), so they only correct what the new timing changed
        start_e = law.e if split else cur_e[pieces.row[law.sel]].astype(np.float64)
        cap = None if state_max is None else np.asarray(state_max)[pieces.row[law.sel]]
        target = None
        if delivered is not None and not split:
            ratios = start_e / np.maximum(pieces.length_mm[law.sel], 1e-12)
            predicted, _grad = model.evaluate(ratios, intent)
            seen = np.asarray(delivered, dtype=np.float64)[elig_orig_rows]
            # never aim below a twentieth of the intent (a model that far off is no guide)
            target = np.maximum(intent + (predicted - seen), 0.05 * intent)
        e_run, report.refinement = refine_qp(model, pieces, start_e, intent,
                                             row_group[pieces.row[law.sel]], law.c_min,
                                             law.c_max, options.refine, state_max=cap,
                                             target=target)
    e_piece = cur_e[pieces.row].astype(np.int64)
    reliefs = _relief_amounts(interims, model, pieces, e_run, e_unit_mm=e_unit_mm)
    shortened: list[tuple[int, int]] = []
    if retracting:
        ends = _relief_amounts([(f, f) for f, _r in retracting], model, pieces, e_run,
                               e_unit_mm=e_unit_mm, keep_zero=True)
        for (_first, r), (_a, _b, ret, back) in zip(retracting, ends, strict=True):
            take = min(ret - back, int(cur_e[r]) - 1)  # compression; keep one unit
            if take > 0:
                shortened.append((r, take))
    if law.sel.size:
        if model is None:  # the law keeps every run's E exactly
            e_piece[law.sel] = round_runs(e_run, law.run_first, law.run_last, law.run_total)
        else:  # the refinement moves E between runs; the file keeps its total
            net = sum(back - ret for _a, _b, ret, back in reliefs)
            net -= sum(take for _r, take in shortened)
            total = int(np.sum(cur_e[elig])) - net
            e_piece[law.sel] = round_total(e_run, total)
    for r, take in shortened:
        e_piece[int(pieces.offsets[r])] -= take
    report.relief_retractions = len(shortened)
    report.relief_retraction_mm = sum(t for _r, t in shortened) * e_unit_mm
    # geometry of the pieces
    mv = table.moves
    end = np.column_stack([mv["x"], mv["y"], mv["z"]]).astype(np.float64)
    start = np.empty((n, 3))
    if n:
        start[0] = table.start_xyze[:3]
        start[1:] = end[:-1]
    f = pieces.fraction_end
    xyz = start[pieces.row] + f[:, None] * (end[pieces.row] - start[pieces.row])
    last = pieces.offsets[1:] - 1
    xyz[last] = end
    piece_of = pieces.row.copy()
    feed = draft.piece_feed_mm_min[piece_of].copy()
    if reliefs:
        piece_of, xyz, e_piece, feed = _insert_relief(reliefs, piece_of, xyz, e_piece, feed,
                                                      start, end, limits, report,
                                                      e_unit_mm=e_unit_mm)
    report.pieces = int(piece_of.size)
    return draft.split(piece_of, xyz, e_piece, feed), report


def _relief_amounts(interims: list[tuple[int, int]], model: LagModel | None, pieces: Pieces,
                    e_run: FloatArray, *, e_unit_mm: float, keep_zero: bool = False
                    ) -> list[tuple[int, int, int, int]]:
    """Retraction and push-back of every relieved interim, grid units.

    The lag model gives the compression ``x`` at the end of the run before the interim;
    the retraction takes twice that (so the melt stops at once), the push-back returns all
    but ``x`` (the next run starts relaxed, as the model assumed, and builds its pressure
    from its own E).

    With ``keep_zero`` every interim gets an entry (``(a, b, 0, 0)`` where nothing is
    known or the compression is below the threshold), in order.

    Returns
    -------
    list of tuple
        ``(first row, last row, retraction, push-back)`` per relieved interim.
    """
    if model is None or not interims:
        return [(a, b, 0, 0) for a, b in interims] if keep_zero else []
    ratios = e_run / pieces.length_mm[model.free_pieces]
    states = model.states(ratios)
    owners = model.seg_owner
    last_seg: dict[int, int] = {}
    change = np.flatnonzero(np.concatenate((owners[1:] != owners[:-1], [True])))
    for s in change.tolist():
        last_seg[int(owners[s])] = s
    out: list[tuple[int, int, int, int]] = []
    for a, b in interims:
        seg = last_seg.get(a - 1)
        x_end = 0.0 if seg is None else max(float(states[seg]), 0.0)
        retract = int(math.ceil(_RELIEF_MARGIN * x_end)) + 1
        if seg is None or retract * e_unit_mm < _MIN_RELIEF_MM:
            if keep_zero:
                out.append((a, b, 0, 0))
            continue
        out.append((a, b, retract, retract - int(round(x_end))))
    return out


def round_total(e: FloatArray, total: int) -> IntArray:
    """Piece E in whole grid units adding up to exactly ``total``.

    ``e`` is scaled to the total, the cumulative sums are rounded (each piece carries the
    rounding residue of the one before), and a piece that would get less than one unit
    borrows it from the largest piece.
    """
    s = float(np.sum(e))
    scaled = e * (total / s) if s > 0 else np.full(e.size, total / max(e.size, 1))
    pos = np.rint(np.cumsum(scaled)).astype(np.int64)
    if pos.size:
        pos[-1] = total
    out = np.diff(np.concatenate(([0], pos)))
    low = np.flatnonzero(out < 1)
    if low.size == 0:
        return out
    # every low piece borrows from the currently largest one (first index on ties): a heap
    # keeps this O(n + m log n) where a scan per low piece was O(n·m)
    heap = [(-int(v), int(i)) for i, v in enumerate(out.tolist())]
    heapq.heapify(heap)
    for j in low.tolist():
        while True:  # entries whose value changed since they were pushed are stale
            neg, k = heap[0]
            if -neg == int(out[k]):
                break
            heapq.heapreplace(heap, (-int(out[k]), k))
        need = 1 - int(out[j])
        if out[k] - need < 1:
            break
        out[j] += need
        out[k] -= need
        heapq.heapreplace(heap, (-int(out[k]), k))
        heapq.heappush(heap, (-int(out[j]), j))
    return out


def _insert_relief(reliefs: list[tuple[int, int, int, int]], piece_of: IntArray,
                   xyz: FloatArray, e_piece: IntArray, feed: FloatArray, start: FloatArray,
                   end: FloatArray, limits: ExtruderLimits, report: PassReport, *,
                   e_unit_mm: float) -> tuple[IntArray, FloatArray, IntArray, FloatArray]:
    """Insert an E-only retraction before each relieved interim's first travel and the
    push-back after its last one."""
    speed = min(_RELIEF_SPEED_MM_S, 0.9 * limits.e_only_speed_mm_s)
    feed_mm_min = 60.0 * speed
    before = {a: -retract for a, _b, retract, _back in reliefs}
    after = {b: back for _a, b, _retract, back in reliefs}
    report.relief_travels += len(reliefs)
    report.relief_mm += sum(r for _a, _b, r, _back in reliefs) * e_unit_mm
    rows: list[int] = []
    pts: list[FloatArray] = []
    es: list[int] = []
    fs: list[float] = []
    for k in range(piece_of.size):
        r = int(piece_of[k])
        first_of_row = k == 0 or piece_of[k - 1] != r
        last_of_row = k == piece_of.size - 1 or piece_of[k + 1] != r
        if first_of_row and r in before:
            rows.append(r)
            pts.append(start[r])
            es.append(before[r])
            fs.append(feed_mm_min)
        rows.append(r)
        pts.append(xyz[k])
        es.append(int(e_piece[k]))
        fs.append(float(feed[k]))
        if last_of_row and after.get(r, 0) > 0:
            rows.append(r)
            pts.append(end[r])
            es.append(after[r])
            fs.append(feed_mm_min)
    return (np.asarray(rows, dtype=np.int64), np.vstack(pts) if pts else xyz,
            np.asarray(es, dtype=np.int64), np.asarray(fs, dtype=np.float64))
