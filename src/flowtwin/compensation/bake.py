"""One pass of the advance transformation over a draft.

The draft's rendered file has been read and planned: its rows are the draft's pieces.
A pass

1. cuts the printing rows at their phase boundaries (first pass only;
   :mod:`flowtwin.compensation.pieces`),
2. gives every piece its E by the advance law within the firmware's limits
   (:func:`flowtwin.compensation.advance.follow_law`),
3. optionally refines the E with the twin's lag model so that every *original* move
   delivers its own volume (:mod:`flowtwin.compensation.refine`),
4. optionally relieves the pressure over travels between printing runs
   (:mod:`flowtwin.compensation.relief`; the first pass adds the reliefs, later passes
   re-size their push-backs): the advance law [001 Eq. 11] commands ``−K·v⁰_E`` where the
   flow stops, which a G-code can only do as a retraction. The travel after a run
   retracts twice the compression the lag model predicts at the run's end and pushes
   back all but that compression, less the pre-charge the refinement leaves for the next
   run's first moves; a slicer's own push-back is shortened the same way.

Without the refinement every run of printing pieces keeps its exact E; with it the file
keeps its total (the printing pieces carry what the reliefs take).
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from flowtwin.compensation.advance import (
    AdvanceLaw,
    AdvanceOptions,
    LawResult,
    eligible_rows,
    follow_law,
    round_runs,
)
from flowtwin.compensation.draft import Draft
from flowtwin.compensation.limits import ExtruderLimits
from flowtwin.compensation.pieces import piece_points, split_rows
from flowtwin.compensation.refine import LagModel, build_lag_model, refine_qp
from flowtwin.compensation.relief import (
    first_free_pieces,
    insert_relief,
    relief_amounts,
    relieved_gaps,
    retraction_interims,
    row_start_states,
    travel_interims,
)
from flowtwin.errors import DataError
from flowtwin.gcode.moves import MoveKind, MoveTable
from flowtwin.planner.timeline import Timeline

__all__ = ["PassReport", "advance_pass"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: A pre-charge is left only where the next run starts within this time after the
#: push-back, s.
_PRECHARGE_MAX_GAP_S = 1e-3


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
    relief_along
        Reliefs laid along their travels (Klipper: the head moves while the filament
        retracts and pushes back, :func:`flowtwin.compensation.relief.insert_relief`).
    relief_retractions
        Retracting travels whose push-back was shortened by the compression at the end of
        the run before, less the pre-charge (a later pass: slicer push-backs it changed).
    relief_retraction_mm
        Total length taken off those push-backs, mm of filament (a later pass: the net
        change it took off them; negative when it gave some back).
    relief_precharge_mm
        Pre-charge the relieved travels' push-backs leave for the next runs' first moves
        (see :func:`flowtwin.compensation.refine.refine_qp`), mm of filament.
    pull_pieces
        Printing pieces that pull the filament back while the head slows down (negative
        E; ``AdvanceOptions.retract_ratio``).
    pull_mm
        Total length those pieces pull back, mm of filament.
    """

    pieces: int = 0
    runs: int = 0
    law_counts: dict[str, int] = field(default_factory=dict)
    refinement: dict[str, float] = field(default_factory=dict)
    relief_travels: int = 0
    relief_mm: float = 0.0
    relief_along: int = 0
    relief_retractions: int = 0
    relief_retraction_mm: float = 0.0
    relief_precharge_mm: float = 0.0
    pull_pieces: int = 0
    pull_mm: float = 0.0


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
        ``intent + g·(model(draft) − delivered)`` — one step of iterative learning control
        with the model as the plant's Jacobian and the gain ``g`` of
        ``options.twin_gain``, so the twin's own figure converges where the model alone
        stops.

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
    # pieces of printing moves with XY motion; a later pass keeps in their runs the ones
    # an earlier pass made pull back (negative E while slowing down)
    elig = orig_elig[group] & ((kind & MoveKind.XY) != 0) & ((cur_e > 0) if split
                                                              else (cur_e != 0))
    smoothed = options.law is AdvanceLaw.SMOOTHED
    w = options.smooth_time_s
    pieces = split_rows(timeline, elig if split else np.zeros(n, dtype=bool),
                        accel_pieces=options.accel_pieces if smoothed else 1,
                        max_piece_s=(options.piece_fraction(limits.firmware) * w
                                     if smoothed else 0.0),
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
                     e_unit_mm=e_unit_mm, xy_rows=_junction_rows(kind, cur_e, draft, group),
                     pull_rows=None if split else cur_e < 0)
    report = PassReport(runs=int(law.run_total.size), law_counts=dict(law.counts))
    e_run = law.e
    lags = options.relief_lags(limits.firmware) * np.asarray(lag_k_s, dtype=np.float64)
    travels = travel_interims(elig, kind, cur_e, timeline, lags) if relief else []
    retracting = (retraction_interims(elig, kind, cur_e, table.moves["tool"], timeline, lags)
                  if relief else [])
    # a later pass: the reliefs the first one made start the next runs relaxed (or
    # pre-charged) too
    relieved = [] if relief else relieved_gaps(elig, cur_e, group, draft.row_e, timeline)
    holds = np.zeros(n, dtype=bool)
    spans = ([(a, b) for a, b in travels] + [(a, r) for a, r in retracting]
             + [(h, j - 1) for h, _back, j, _short in relieved])
    for a, _b in spans:
        holds[a] = True
    elig_rows = np.flatnonzero(elig)
    next_rows = elig_rows[np.minimum(np.searchsorted(elig_rows, [b for _a, b in spans],
                                                     side="right"), elig_rows.size - 1)
                          ] if spans else np.zeros(0, dtype=np.int64)
    elig_orig_rows = np.flatnonzero(orig_elig)
    group_index = np.full(draft.n_rows, -1, dtype=np.int64)
    group_index[elig_orig_rows] = np.arange(elig_orig_rows.size)
    row_group = np.where(elig, group_index[group], -1)
    model = None
    precharge = np.zeros(len(spans))
    start_state: FloatArray | None = None
    if options.refine is not None and law.sel.size:
        free = np.zeros(len(pieces), dtype=bool)
        free[law.sel] = True
        row_phys = cur_e.astype(np.float64)
        plen = pieces.row_length_mm[pieces.row]
        ratio = np.where(plen > 0, row_phys[pieces.row] / np.where(plen > 0, plen, 1.0), 0.0)
        model = build_lag_model(pieces, timeline, np.asarray(lag_k_s, dtype=np.float64), free,
                                ratio, row_phys, row_group, int(elig_orig_rows.size),
                                travel_holds=holds)
        pc_first = first_free_pieces(next_rows, pieces, model.free_pieces)
        hold_first = np.array([a for a, _b in spans], dtype=np.int64)
        intent = draft.row_e[elig_orig_rows].astype(np.float64)
        # a first pass starts from the law; later passes from the draft's own E (already
        # refined, now re-planned), so they only correct what the new timing changed
        start_e = law.e if split else cur_e[pieces.row[law.sel]].astype(np.float64)
        cap = None if state_max is None else np.asarray(state_max)[pieces.row[law.sel]]
        target = None
        ratios = start_e / np.maximum(pieces.length_mm[law.sel], 1e-12)
        now = _held_precharge(model, ratios, pc_first, spans, relieved, n)
        # a pre-charge up to the compression the run before ends with at the start (the
        # hold would keep it): fixed, so over-feeding a run's end buys none
        y_max = np.maximum(np.nan_to_num(row_start_states(
            model, model.states(ratios, (pc_first, now)), n)[hold_first]), 0.0)
        # only where the next run starts right after the push-back (no dwell, no heat-up
        # wait between: the pre-charge would ooze away there)
        push = np.array([b for _a, b in spans[:len(spans) - len(relieved)]]
                        + [back for _h, back, _j, _s in relieved], dtype=np.int64)
        t_next = np.asarray(timeline.phases["t_start"], dtype=np.float64)[next_rows]
        y_max[(push != next_rows - 1)
              | (t_next - timeline.end_time_s[np.maximum(push, 0)] > _PRECHARGE_MAX_GAP_S)] = 0.0
        if delivered is not None and not split:
            predicted, _grad = model.evaluate(ratios, intent, (pc_first, now))
            seen = np.asarray(delivered, dtype=np.float64)[elig_orig_rows]
            # never aim below a twentieth of the intent (a model that far off is no guide)
            target = np.maximum(intent + options.twin_gain * (predicted - seen),
                                0.05 * intent)
        # the firmware's ratio steps bind a later pass only: the first pass's pieces are
        # planned afresh before the second refines them, and the second must not make the
        # planner re-time its own result (a 0.08 mm piece at a fifth of its neighbours'
        # ratio slowed CrealityPrint's 200 mm/s arc to 92 mm/s); bound in the first pass
        # too, the law could not be followed as closely (PrusaSlicer 2.7.4 vase 5.4x -> 3.8x)
        e_run, report.refinement, precharge = refine_qp(
            model, pieces, start_e, intent, row_group[pieces.row[law.sel]], law.c_min,
            law.c_max, options.refine, state_max=cap, target=target,
            jump=_jumps(law, split, options), precharge=(pc_first, y_max))
        _check_finite(e_run, precharge, table, pieces.row[law.sel])
        states = model.states(e_run / np.maximum(pieces.length_mm[law.sel], 1e-12),
                              (pc_first, precharge))
        start_state = row_start_states(model, states, n)
    e_piece = cur_e[pieces.row].astype(np.int64)
    k_t, k_r = len(travels), len(travels) + len(retracting)
    reliefs = relief_amounts(travels, start_state, precharge[:k_t], e_unit_mm=e_unit_mm)
    pushed: dict[int, int] = {}  # E added to existing push-back rows (negative: taken)
    ends = relief_amounts([(f, f) for f, _r in retracting], start_state, precharge[k_t:k_r],
                          e_unit_mm=e_unit_mm, keep_zero=True)
    for (_first, r), (_a, _b, ret, back) in zip(retracting, ends, strict=True):
        take = min(ret - back, int(cur_e[r]) - 1)  # compression less pre-charge; keep one
        if take > 0:
            pushed[r] = -take
    report.relief_retractions = len(pushed)
    report.relief_retraction_mm = -sum(pushed.values()) * e_unit_mm
    if start_state is not None:
        for (h, back, _j, short), y in zip(relieved, precharge[k_r:], strict=True):
            x = float(start_state[h])
            if back < 0 or not np.isfinite(x):
                continue
            # the push-back now leaves y: it was short by `short`, now by x − y
            delta = min(max(short - int(round(max(x, 0.0))) + int(round(y)),
                            1 - int(cur_e[back])), short)
            if delta:
                for r, de in _push_shares(back, h, delta, cur_e, kind):
                    pushed[r] = pushed.get(r, 0) + de
                if draft.row_e[group[back]] > 0:  # the slicer's own push-back
                    report.relief_retractions += 1
                    report.relief_retraction_mm -= delta * e_unit_mm
    report.relief_precharge_mm = float(np.sum(np.rint(precharge))) * e_unit_mm
    if law.sel.size:
        if model is None:  # the law keeps every run's E exactly
            e_piece[law.sel] = round_runs(e_run, law.run_first, law.run_last, law.run_total)
        else:  # the refinement moves E between runs; the file keeps its total
            net = sum(back - ret for _a, _b, ret, back in reliefs) + sum(pushed.values())
            total = int(np.sum(cur_e[elig])) - net
            e_piece[law.sel] = round_total(e_run, total, law.c_min > 0)
        pulled = e_piece[law.sel][e_piece[law.sel] < 0]
        report.pull_pieces = int(pulled.size)
        report.pull_mm = -float(np.sum(pulled)) * e_unit_mm
    for r, de in pushed.items():
        e_piece[int(pieces.offsets[r])] += de
    # geometry of the pieces
    mv = table.moves
    end = np.column_stack([mv["x"], mv["y"], mv["z"]]).astype(np.float64)
    start = np.empty((n, 3))
    if n:
        start[0] = table.start_xyze[:3]
        start[1:] = end[:-1]
    xyz = piece_points(np.ascontiguousarray(pieces.row, dtype=np.int64),
                       np.ascontiguousarray(pieces.s1_mm, dtype=np.float64),
                       np.ascontiguousarray(pieces.row_length_mm, dtype=np.float64),
                       np.ascontiguousarray(pieces.offsets, dtype=np.int64), start,
                       np.ascontiguousarray(end))
    piece_of = pieces.row.copy()
    feed = draft.piece_feed_mm_min[piece_of].copy()
    if reliefs:
        piece_of, xyz, e_piece, feed, along = insert_relief(
            reliefs, piece_of, xyz, e_piece, feed, start, end, limits,
            along=(np.asarray(table.moves["feed_mm_s"], dtype=np.float64),
                   np.asarray(timeline.phases["accel"], dtype=np.float64),
                   ((kind & MoveKind.XY) != 0) & ((kind & MoveKind.TRAVEL) != 0)
                   ) if options.relief_along else None,
            e_unit_mm=e_unit_mm)
        report.relief_travels += len(reliefs)
        report.relief_along += along
        report.relief_mm += sum(r for _a, _b, r, _back in reliefs) * e_unit_mm
    report.pieces = int(piece_of.size)
    return draft.split(piece_of, xyz, e_piece, feed), report


def _junction_rows(kind: npt.NDArray[np.uint8], cur_e: IntArray, draft: Draft,
                   group: IntArray) -> npt.NDArray[np.bool_]:
    """Rows whose E ratio bounds the ratio of a run's first and last piece at the junction
    between them: XY moves, except the pieces of a relief laid along a travel (E written
    on a row the slicer wrote without; a later pass must not pin the run's ends to the
    relief's steep ratio, which it crosses anyway where the head has slowed down)."""
    xy = (kind & MoveKind.XY) != 0
    return xy & ~((cur_e != 0) & (draft.row_e[group] == 0))


def _push_shares(back: int, hold: int, delta: int, cur_e: IntArray,
                 kind: npt.NDArray[np.uint8]) -> list[tuple[int, int]]:
    """A change of a relief's push-back, as ``(row, E)``: all on an E-only push-back; on
    one laid along the travel's end (rows with XY and positive E from the hold on, the
    last being ``back``) in proportion to their E, so that its ratio stays even and
    within the limit it was laid at (:func:`flowtwin.compensation.relief.insert_relief`)."""
    if not kind[back] & MoveKind.XY:
        return [(back, delta)]
    rows = np.arange(hold + 1, back + 1)
    rows = rows[(cur_e[rows] > 0) & ((kind[rows] & MoveKind.XY) != 0)]
    have = cur_e[rows].astype(np.float64)
    delta = max(delta, int(rows.size) - int(np.sum(have)))  # every piece keeps one unit
    share = round_total(have, delta, np.zeros(rows.size, dtype=bool))
    return [(int(r), int(d)) for r, d in zip(rows, share, strict=True) if d]


def _held_precharge(model: LagModel, ratios: FloatArray, first_vars: IntArray,
                    spans: list[tuple[int, int]], relieved: list[tuple[int, int, int, int]],
                    n_rows: int) -> FloatArray:
    """Pre-charge the draft as it is leaves after every relieved hold, grid units.

    An earlier pass shortened the hold's push-back by ``short``; the column then starts
    the next run with what the run before ended with less that: ``max(x_end − short, 0)``.
    The state at a run's end depends on its own start, so two rounds.
    """
    k0 = len(spans) - len(relieved)
    y = np.zeros(len(spans))
    if not relieved:
        return y
    hold = np.array([h for h, _b, _j, _s in relieved], dtype=np.int64)
    short = np.array([s for _h, _b, _j, s in relieved], dtype=np.float64)
    for _ in range(2):
        ends = row_start_states(model, model.states(ratios, (first_vars, y)), n_rows)[hold]
        y[k0:] = np.maximum(np.nan_to_num(ends) - short, 0.0)
    return y


def _check_finite(e_run: FloatArray, precharge: FloatArray, table: MoveTable,
                  rows: IntArray) -> None:
    """The refinement's solution must be finite; a solver failure is refused with the first
    line it concerns, never written."""
    bad = np.flatnonzero(~np.isfinite(e_run))
    if bad.size == 0 and np.all(np.isfinite(precharge)):
        return
    line = int(table.moves["line"][int(rows[bad[0]])]) if bad.size else None
    raise DataError("the advance's refinement found no finite solution here (a solver "
                    "failure on this file: compensate without --advance, and please report "
                    "the file)", source=table.source, line=line, field="--advance",
                    value=f"{bad.size} of {e_run.size} pieces",
                    allowed="a finite solution")


def _jumps(law: LawResult, split: bool, options: AdvanceOptions) -> FloatArray | None:
    """The ratio steps the refinement keeps within: every one in a later pass; in the first
    only into and out of the pieces that may pull back (a step to a negative ratio at
    speed would make the planner slow the junction down, most of all Klipper's extruder
    corner velocity)."""
    if not split:
        return law.jump
    if options.retract_ratio <= 0:
        return None
    pull = law.c_min < 0
    near = pull | np.concatenate((pull[1:], [False]))
    return np.where(near | np.concatenate(([False], pull[:-1])), law.jump, np.inf)


def round_total(e: FloatArray, total: int,
                positive: npt.NDArray[np.bool_] | None = None) -> IntArray:
    """Piece E in whole grid units adding up to exactly ``total``.

    ``e`` is scaled to the total, the cumulative sums are rounded (each piece carries the
    rounding residue of the one before), and a piece that must print (``positive``,
    default all) but would get less than one unit borrows it from the largest piece.
    """
    s = float(np.sum(e))
    scaled = e * (total / s) if s > 0 else np.full(e.size, total / max(e.size, 1))
    pos = np.rint(np.cumsum(scaled)).astype(np.int64)
    if pos.size:
        pos[-1] = total
    out = np.diff(np.concatenate(([0], pos)))
    must = np.ones(out.size, dtype=bool) if positive is None else np.asarray(positive, bool)
    low = np.flatnonzero((out < 1) & must)
    if low.size == 0:
        return out
    # every low piece borrows from the currently largest one (first index on ties): a heap
    # keeps this O(n + m log n) where a scan per low piece was O(n·m); the heap holds the
    # largest few (a borrow takes a unit or two: the largest stays among them), and is
    # rebuilt from every piece should a borrow ever pull its top below the rest
    k = min(out.size, 2 * low.size + 16)
    top = np.argpartition(-out, k - 1)[:k] if k < out.size else np.arange(out.size)
    rest_max = int(np.max(np.delete(out, top), initial=-(1 << 62)))
    heap = [(-int(out[i]), int(i)) for i in top.tolist()]
    heapq.heapify(heap)
    for j in low.tolist():
        while True:  # entries whose value changed since they were pushed are stale
            neg, kk = heap[0]
            if -neg == int(out[kk]):
                break
            heapq.heapreplace(heap, (-int(out[kk]), kk))
        if -heap[0][0] <= rest_max:  # the top may no longer be the largest: all of them
            heap = [(-int(v), int(i)) for i, v in enumerate(out.tolist())]
            heapq.heapify(heap)
            rest_max = -(1 << 62)
            kk = heap[0][1]
        need = 1 - int(out[j])
        if out[kk] - need < 1:
            break
        out[j] += need
        out[kk] -= need
        heapq.heapreplace(heap, (-int(out[kk]), kk))
        heapq.heappush(heap, (-int(out[j]), j))
    return out
