"""Refining the advanced E with the twin's lag model: every move delivers its own volume.

The advance laws [001 Eqs. 11, 13] assume the firmware can follow ``E* = E⁰ + K·v⁰_E``;
a G-code cannot command negative extrusion, and the ratio steps are limited
(:mod:`flowtwin.compensation.limits`), so where the law is clipped (mostly in
decelerations, where the ideal command is negative) the melt runs late and moves near
corners and stops over-extrude. The twin scores a move by ``delivered / commanded − 1``,
so the refinement chooses the pieces' ratios ``c`` to minimise, under the linear lag model
of :mod:`flowtwin.compensation._refine_kernel` (exact for ``dx/dt = u − x/K`` on every
segment of constant acceleration)::

    J = ½·Σ_m (O_m − I_m)²/I_m                     (volume-weighted squared flow error)
      + ½·λ·Σ_j (E_j − E^law_j)²/I_(m(j))           (stay near the advance law's E)

over the ratio box ``c_min ≤ c ≤ c_max`` (no piece below ``min_flow_fraction`` of its
intent, none above the firmware's limits). With the states after the pieces as unknowns
the problem is a banded convex QP plus one squared row per move, solved by an
interior-point method (:func:`refine_qp`). Retractions hold the state (no backflow
[001 Fig. 8]); gaps and travels let it decay (ooze); a pressure-relief travel leaves it
relaxed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.compensation._refine_kernel import (
    apply_holds,
    first_segments,
    model_columns,
    model_pass,
    piece_segments,
    segment_maps,
    segment_states,
)
from flowtwin.compensation.pieces import Pieces
from flowtwin.compensation.program import Chain, PartProgram, program_parts
from flowtwin.errors import CalibrationError, ProfileError
from flowtwin.planner.timeline import Timeline

__all__ = ["LagModel", "RefineOptions", "build_lag_model", "refine_qp"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


@dataclass(frozen=True, slots=True)
class RefineOptions:
    """Weight and stopping rule of the refinement (see the module docstring).

    Attributes
    ----------
    track_weight
        ``λ``: pull of every piece's E towards the advance law's (> 0; it also makes the
        pieces within a move, which the flow error alone cannot tell apart, unique).
    peak_weight
        ``μ``: weight of the squared relative error of every move (next to the
        volume-weighted one), against large relative errors of small moves.
    max_iterations
        Interior-point iterations at most.
    tolerance
        Stopping test of the interior point (gap per constraint and scaled residuals of
        the scaled program, :func:`flowtwin.compensation._qp.solve_program`). At ``1e-6``
        the states lie within 0.1 grid units of a ``1e-9`` solve (99.9 % within 0.005)
        and the objective within 1e-13 of its value; the written E are whole grid units
        and the file's total E is kept by the rounding, not by the solver.
    """

    track_weight: float = 0.02
    peak_weight: float = 0.05
    max_iterations: int = 150
    tolerance: float = 1e-6

    def __post_init__(self) -> None:
        if not (0.0 < self.track_weight <= 100.0):
            raise ProfileError("invalid refinement weight", field="track_weight",
                               value=self.track_weight, allowed="0 < λ <= 100")
        if not (0.0 <= self.peak_weight <= 100.0):
            raise ProfileError("invalid peak weight", field="peak_weight",
                               value=self.peak_weight, allowed="0 <= μ <= 100")
        if not (5 <= self.max_iterations <= 1000):
            raise ProfileError("invalid iteration limit", field="max_iterations",
                               value=self.max_iterations, allowed="5 .. 1000")
        if not (1e-12 <= self.tolerance <= 1e-3):
            raise ProfileError("invalid solver tolerance", field="tolerance",
                               value=self.tolerance, allowed="1e-12 .. 1e-3")


@dataclass(frozen=True, slots=True)
class LagModel:
    """Segments of the linear lag model over a whole file (see ``_refine_kernel``).

    Attributes
    ----------
    seg_piece, seg_fixed, seg_len, seg_a, seg_b, seg_c, seg_row, seg_first, seg_last
        Per segment: free piece (or −1), fixed ratio, path length, affine map, objective
        row (or −1), first/last segment of its objective row.
    free_pieces
        Piece index of every free variable, shape ``(p,)``.
    objective_rows
        Group of every objective entry (``0 … m−1``), shape ``(m,)``.
    holds
        Retractions that hold the state.
    seg_owner
        Row each segment belongs to (a gap: the row after it), shape ``(s,)``.
    seg_t_s
        Duration of each segment, s.
    seg_gap
        Segment is the rest before its owner row (not part of the row's motion).
    """

    seg_piece: IntArray
    seg_fixed: FloatArray
    seg_len: FloatArray
    seg_a: FloatArray
    seg_b: FloatArray
    seg_c: FloatArray
    seg_row: IntArray
    seg_first: BoolArray
    seg_last: BoolArray
    free_pieces: IntArray
    objective_rows: IntArray
    holds: int
    seg_owner: IntArray
    seg_t_s: FloatArray
    seg_gap: BoolArray

    def states(self, ratios: FloatArray,
               precharge: tuple[IntArray, FloatArray] | None = None) -> FloatArray:
        """Model state (compression, grid units) at the end of every segment.

        Parameters
        ----------
        ratios
            Ratio of every free piece, shape ``(p,)``.
        precharge
            Free pieces that start from a pre-charge and its size (grid units), as
            returned by :func:`refine_qp` (see there): the state just before such a piece
            is the pre-charge instead of zero.
        """
        out = np.empty(self.seg_piece.shape[0])
        segment_states(np.ascontiguousarray(ratios, dtype=np.float64), self.seg_piece,
                       self.seg_fixed, self.seg_a, self.seg_b, self._seg_c(precharge), out)
        return out

    def _seg_c(self, precharge: tuple[IntArray, FloatArray] | None) -> FloatArray:
        """``seg_c`` with every pre-charge put on the reset segment before its piece."""
        if precharge is None or not np.any(np.asarray(precharge[1]) != 0.0):
            return self.seg_c
        seg_c = self.seg_c.copy()
        first_seg = first_segments(self.seg_piece, int(self.free_pieces.size))
        piece = np.asarray(precharge[0], dtype=np.int64)
        y = np.asarray(precharge[1], dtype=np.float64)
        if piece.size != y.size:
            raise ValueError("one pre-charge per piece")
        known = (piece >= 0) & (piece < first_seg.size)
        s = np.full(piece.size, -1, dtype=np.int64)
        s[known] = first_seg[piece[known]]
        put = np.flatnonzero((y != 0.0) & (s > 0))
        put = put[self.seg_a[s[put] - 1] == 0.0]  # on the reset segment before the piece
        np.add.at(seg_c, s[put] - 1, y[put])  # (in order, repeated segments add up)
        return seg_c

    def evaluate(self, ratios: FloatArray, intent: FloatArray,
                 precharge: tuple[IntArray, FloatArray] | None = None
                 ) -> tuple[FloatArray, FloatArray]:
        """Model output per objective row and the gradient of ``Σ (O − I)²`` (unit weights).

        Parameters
        ----------
        ratios
            Ratio of every free piece, shape ``(p,)``.
        intent
            Intended E of every objective row, shape ``(m,)``.
        precharge
            Pre-charges (see :meth:`states`).

        Returns
        -------
        tuple of ndarray
            ``O`` shape ``(m,)``, gradient shape ``(p,)``.
        """
        out = np.zeros(intent.shape[0])
        grad = np.zeros(ratios.shape[0])
        model_pass(np.ascontiguousarray(ratios, dtype=np.float64), self.seg_piece,
                   self.seg_fixed, self.seg_len, self.seg_a, self.seg_b,
                   self._seg_c(precharge),
                   self.seg_row, self.seg_first, self.seg_last,
                   np.ascontiguousarray(intent, dtype=np.float64), np.ones(intent.shape[0]),
                   out, grad)
        return out, grad


def build_lag_model(pieces: Pieces, timeline: Timeline, lag_k_s: FloatArray,
                    free_piece: BoolArray, piece_ratio: FloatArray, row_de: FloatArray,
                    row_group: IntArray, n_groups: int, *,
                    travel_holds: BoolArray | None = None) -> LagModel:
    """Segments of the lag model for every piece of every move, and the gaps between.

    Parameters
    ----------
    pieces
        All rows' pieces.
    timeline
        The phases (``n_rows``).
    lag_k_s
        Lag factor of every row, s.
    free_piece
        Pieces whose ratio is optimised, shape ``(n_pieces,)``.
    piece_ratio
        Ratio of every piece (fixed pieces keep it), E grid units per mm.
    row_de
        E of every row in grid units (physical E, retractions included).
    row_group
        Objective group of every row (the original move it is a piece of), or −1 for rows
        whose output does not count, shape ``(n_rows,)``; a group's rows are consecutive.
    n_groups
        Number of groups.
    travel_holds
        Rows (travels) that start a hold like a retraction, shape ``(n_rows,)``.

    Returns
    -------
    LagModel
    """
    n_rows = timeline.phases.shape[0]
    t0_row, ta, tc, td, sv, cv, ev = timeline.trapezoids()
    r = pieces.row
    # gaps: rest time before every row (after the previous row's end)
    end_row = t0_row + ta + tc + td
    gap = np.zeros(n_rows)
    gap[1:] = np.maximum(t0_row[1:] - end_row[:-1], 0.0)
    n_p = len(pieces)
    first_of_row = np.zeros(n_p, dtype=bool)
    first_of_row[pieces.offsets[:-1][pieces.offsets[1:] > pieces.offsets[:-1]]] = True
    seg_piece_of, seg_t, seg_len, seg_va, seg_vb, owner_row = piece_segments(
        r, pieces.t0_s, pieces.t1_s, first_of_row, t0_row, ta, tc, td, sv, cv, ev, gap)
    is_gap = seg_piece_of < 0
    seg_k = np.asarray(lag_k_s, dtype=np.float64)[owner_row]
    if np.any(~(seg_k > 0)):
        raise CalibrationError("lag factor must be positive for every move",
                               field="lag_k_s", value=float(np.min(seg_k)), allowed="> 0 s")
    n_s = seg_t.shape[0]
    e = np.empty(n_s)
    g = np.empty(n_s)
    segment_maps(seg_t, seg_k, seg_va, seg_vb, e, g)
    free_idx = np.flatnonzero(free_piece)
    var_of_piece = np.full(n_p, -1, dtype=np.int64)
    var_of_piece[free_idx] = np.arange(free_idx.size)
    row_free = np.zeros(n_rows, dtype=bool)
    row_free[r[free_idx]] = True
    hold_rows = np.zeros(n_rows, dtype=bool) if travel_holds is None else travel_holds
    # the segments' columns, the objective's stretches, and the units (gaps and rows in
    # time order) the holds through retractions are made of
    (seg_var, ratio, seg_b, seg_c, seg_row, first, last, unit_start, unit_end, unit_free,
     unit_de, unit_hold) = model_columns(
        np.ascontiguousarray(seg_piece_of, dtype=np.int64),
        np.ascontiguousarray(owner_row, dtype=np.int64), var_of_piece,
        np.ascontiguousarray(piece_ratio, dtype=np.float64), g, row_free,
        np.ascontiguousarray(row_de, dtype=np.float64),
        np.ascontiguousarray(hold_rows, dtype=bool),
        np.ascontiguousarray(row_group, dtype=np.int64))
    seg_a = e
    holds = apply_holds(unit_start, unit_end, unit_free, unit_de, unit_hold, seg_a, seg_b,
                        seg_c)
    obj_rows = np.arange(n_groups, dtype=np.int64)
    return LagModel(seg_var.astype(np.int64), ratio, seg_len, seg_a, seg_b, seg_c,
                    seg_row.astype(np.int64), first, last, free_idx.astype(np.int64),
                    obj_rows.astype(np.int64), int(holds), owner_row.astype(np.int64), seg_t,
                    is_gap)


def refine_qp(model: LagModel, pieces: Pieces, initial_e: FloatArray, intent: FloatArray,
              piece_group: IntArray, c_min: FloatArray, c_max: FloatArray,
              options: RefineOptions, *, state_max: FloatArray | None = None,
              target: FloatArray | None = None,
              jump: FloatArray | None = None,
              precharge: tuple[IntArray, FloatArray] | None = None
              ) -> tuple[FloatArray, dict[str, float], FloatArray]:
    """Optimise the free pieces' E as a sparse quadratic program in the states.

    With the state ``x_p`` after every free piece as the unknowns, each piece's ratio is
    ``c_p = (x_p − E_p·(α_p·x_(p−1) + κ_p) − K_p)/B_p`` (:func:`free_piece_chain`) and each
    move's output ``O_g = Σ_(p∈g) L_p·c_p − x_last(g) + x_before(g)``: both are linear with
    a band structure, so ``½ Σ_g w_g (O_g − I_g)² + ½ λ Σ_p (L_p (c_p − ĉ_p))²/I_g`` with
    ``w_g = 1/I_g + μ·Ī/I_g²`` (the volume-weighted squared flow error, plus ``μ`` times the
    squared *relative* error, which keeps small moves from carrying large relative errors)
    over the ratio box, under the state cap ``x_p ≤ x_max`` (the compression at which the
    feed force reaches the grinding limit) and within the firmware's ratio steps
    ``|c_p − c_(p−1)| ≤ j_p`` between neighbouring pieces of a run (a larger step makes the
    planner slow the junction down: Marlin's E jerk, Klipper's extruder corner velocity,
    :mod:`flowtwin.compensation.limits`) is a banded convex QP
    (:func:`flowtwin.compensation._qp.solve_program`, assembled by
    :mod:`flowtwin.compensation.program`).

    A relieved travel (a retraction whose push-back leaves the column relaxed, see
    :func:`flowtwin.compensation.bake.advance_pass`) starts the next run from ``x = 0``;
    its push-back may instead leave a *pre-charge* ``y``, a variable of the program with
    ``0 ≤ y ≤ y_max`` (at most the compression the run before ended with at the starting
    point, which the hold would have kept; a constant, so that over-feeding a run's end
    cannot buy a larger pre-charge): the next run's first piece then starts from
    ``x_pre = y``. A short
    first move after a travel (a 0.06 mm arc) cannot build its pressure from rest within
    the firmware's ratio limits; the push-back can, E-only and before the head moves.
    ``y`` carries the track weight ``λ·y²/I`` of that run's first move (the law's
    pre-charge is zero). The ``y`` are ordered just before the piece they feed, so the
    band stays narrow.

    A piece whose ``c_min`` is negative may pull the filament back while the head slows
    down (:attr:`flowtwin.compensation.advance.AdvanceOptions.retract_ratio`); the
    program then keeps the state after it at ``x ≥ 0``: the model has no gap between the
    filament and the melt, so it may only pull back what is compressed.

    Parameters
    ----------
    model
        The lag model.
    pieces
        All pieces.
    initial_e
        E of every free piece of the law (grid units): the starting and reference point.
    intent
        Intended E of every group, grid units.
    piece_group
        Group of every free piece.
    c_min, c_max
        Ratio box of every free piece.
    options
        Weights and iterations.
    state_max
        Largest compression after every free piece, grid units (``inf``: none).
    target
        Model output to aim at per group, grid units (default ``intent``; the weights are
        always the intent's). A later pass aims the model at ``intent`` corrected by what
        the twin delivered against what the model predicted (see
        :func:`flowtwin.compensation.bake.advance_pass`).
    jump
        Largest ratio step ``|c_p − c_(p−1)|`` from the previous free piece, per free
        piece (grid units per mm; ``inf``: none, e.g. at a run's first piece), shape
        ``(p,)`` (:attr:`flowtwin.compensation.advance.LawResult.jump`). Default: none.
    precharge
        Relieved travels that may pre-charge the next run: the free piece (index into
        ``model.free_pieces``) each one's run starts with, and the largest pre-charge
        (grid units), shape ``(k,)`` each. Entries whose first piece does not start
        relaxed in the model (``x_pre`` not zero) or whose bound is not positive get no
        pre-charge.

    Returns
    -------
    tuple
        E of every free piece (grid units, floats), figures, and the pre-charge of every
        ``precharge`` entry (grid units, ``0`` for entries without one), shape ``(k,)``.
    """
    from flowtwin.compensation._refine_kernel import free_piece_chain

    n = model.free_pieces.size
    alpha = np.zeros(n)
    kappa = np.zeros(n)
    e_p = np.ones(n)
    b_p = np.zeros(n)
    k_p = np.zeros(n)
    l_p = np.zeros(n)
    free_piece_chain(model.seg_piece, model.seg_a, model.seg_b, model.seg_c, model.seg_len,
                     alpha, kappa, e_p, b_p, k_p, l_p)
    b_p = np.maximum(b_p, 1e-12)
    grp = np.asarray(piece_group, dtype=np.int64)
    if np.any(grp[1:] < grp[:-1]):
        raise ProfileError("the pieces of a move must be consecutive", field="piece_group",
                           value=int(np.flatnonzero(grp[1:] < grp[:-1])[0]) + 1,
                           allowed="a group index that does not decrease")
    m = intent.size
    first = np.concatenate(([True], grp[1:] != grp[:-1]))
    # pre-charges y: x_pre(p_k) += y_k, so c_p gains −E_p/B_p·y_k (variables [x; y])
    after_v, y_max, use = _precharge_entries(precharge, alpha, kappa, n)
    k_y = int(after_v.size)
    chain = Chain.of(alpha, e_p, b_p, after_v)
    # c = C·[x; y] + c0 (products from the chain's arrays: chain.matvec, chain.rmatvec)
    c0 = -(e_p * kappa + k_p) / b_p
    # outputs R·[x; y] + r0: Σ L_p·c_p over the move's pieces, minus the state after its
    # last piece, plus the state before its first (x_pre = α·x_(p−1) + κ, or y)
    r_mat = chain.outputs(grp, m, l_p, alpha)
    r_first = np.zeros(m)
    r_first[grp[first]] += kappa[first]
    r0 = (np.bincount(grp, weights=l_p * c0, minlength=m) + r_first
          - (intent if target is None else target))
    inv = 1.0 / np.maximum(intent, 1e-9)
    w = inv + options.peak_weight * float(np.mean(intent)) * inv * inv
    v = options.track_weight * l_p ** 2 * inv[grp]
    v_y = options.track_weight * inv[grp[after_v]]
    c_hat = np.asarray(initial_e, dtype=np.float64) / np.maximum(l_p, 1e-12)
    # the Hessian is Cᵀ·V·C + Rᵀ·diag(w)·R; the solver takes R's rows as they are (a
    # move cut into many pieces would make its block of Rᵀ·W·R dense)
    size = chain.size
    g = r_mat.rmatvec(w * r0, size) + chain.rmatvec(v * (c0 - c_hat))
    r_diag = r_mat.squared().rmatvec(w, size)
    scale = float(np.mean(np.abs(chain.hessian_diagonal(v, v_y) + r_diag))) or 1.0
    del r_diag
    hi = np.where(np.isfinite(c_max), np.maximum(c_max, c_min * (1 + 1e-6) + 1e-9), np.inf)

    def objective(x: FloatArray) -> float:  # x: [states; pre-charges]
        r = r_mat.matvec(x) + r0
        c = chain.matvec(x) + c0
        return float(0.5 * np.sum(w * r * r) + 0.5 * np.sum(v * (c - c_hat) ** 2)
                     + 0.5 * np.sum(v_y * x[n:] ** 2))

    # states of the law's E (clipped into the box), no pre-charge: the objective before,
    # and the start
    c_start = np.clip(c_hat, c_min, hi)
    x_start = np.concatenate((_chain_states(alpha, kappa, e_p, b_p, k_p, c_start),
                              np.zeros(k_y)))
    before = objective(x_start)
    del c_start, kappa, k_p, e_p, b_p
    jmp = None
    if jump is not None:
        jmp = np.asarray(jump, dtype=np.float64)
        if jmp.shape != (n,):
            raise ProfileError("ratio step limits do not match the free pieces", field="jump",
                               value=jmp.shape, allowed=f"shape ({n},)")
    stepped = np.zeros(n, dtype=bool) if jmp is None else np.isfinite(jmp)
    stepped[:1] = False
    # the program falls apart between runs: it is assembled and solved part by part (the
    # solver's blocks and their arithmetic are those of the whole program)
    cuts = chain.cuts(alpha, l_p, v, grp, stepped)
    bounds = program_parts(cuts, n)
    order = chain.order
    # the state cap: rows only where it binds (solved without it first; most runs stay
    # far below the compression at which the drive would grind)
    cap = (None if state_max is None or not np.any(np.isfinite(state_max))
           else np.isfinite(state_max))
    x = np.empty(n + k_y)
    iterations = 0
    problem = PartProgram(chain, alpha, l_p, grp, w / scale, v, v_y, g[order] / scale,
                       x_start[order], c0, c_min, hi, y_max, stepped, jmp, scale)
    del g
    for with_cap in (False, True):
        capped: npt.NDArray[np.bool_] | None = None
        if with_cap:
            if cap is None:
                break
            limit = np.asarray(state_max, dtype=np.float64)[cap]
            over = x[:n][cap] > limit + 1e-6 * np.maximum(np.abs(limit), 1)
            if not np.any(over):
                break
            capped = cap
        for p0, p1 in bounds:
            q0, z, its = problem.solve(p0, p1, capped,
                                       None if capped is None else state_max,
                                       max_iterations=options.max_iterations,
                                       tolerance=options.tolerance)
            iterations = max(iterations, its)
            x[order[q0:q0 + z.size]] = z
    del problem
    c = np.clip(chain.matvec(x) + c0, c_min, hi)
    e_new = c * l_p
    after = objective(x)
    total = float(np.sum(intent))
    y_out = np.zeros(use.size)
    y_out[use] = np.maximum(x[n:], 0.0)
    return e_new, {"flow_before": 2.0 * before / total, "flow_after": 2.0 * after / total,
                   "iterations": float(iterations),
                   "precharges": float(np.count_nonzero(y_out > 0.5))}, y_out


def _precharge_entries(precharge: tuple[IntArray, FloatArray] | None, alpha: FloatArray,
                       kappa: FloatArray, n: int) -> tuple[IntArray, FloatArray,
                                                          npt.NDArray[np.bool_]]:
    """The usable pre-charge entries of :func:`refine_qp`: a run's first free piece that
    starts relaxed in the model, with a positive bound; the mask of the usable ones among
    all given."""
    if precharge is None:
        return np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0, dtype=bool)
    after_v = np.asarray(precharge[0], dtype=np.int64)
    y_max = np.asarray(precharge[1], dtype=np.float64)
    if after_v.shape != y_max.shape:
        raise ProfileError("pre-charge entries do not pair up", field="precharge",
                           value=(after_v.shape, y_max.shape), allowed="equal shapes")
    use = (after_v >= 0) & (after_v < n) & (y_max > 0.5)
    ok = np.flatnonzero(use)
    use[ok] = (alpha[after_v[ok]] == 0.0) & (kappa[after_v[ok]] == 0.0)
    # one pre-charge per piece (the first entry)
    _, first = np.unique(after_v[use], return_index=True)
    keep = np.zeros(after_v.size, dtype=bool)
    keep[np.flatnonzero(use)[first]] = True
    return after_v[keep], y_max[keep], keep


def _chain_states(alpha: FloatArray, kappa: FloatArray, e_p: FloatArray, b_p: FloatArray,
                  k_p: FloatArray, c: FloatArray) -> FloatArray:
    """States after every free piece for the ratios ``c`` (see :func:`refine_qp`)."""
    from flowtwin.compensation._refine_kernel import chain_states

    out = np.empty(c.size)
    chain_states(alpha, kappa, e_p, b_p, k_p, np.ascontiguousarray(c, dtype=np.float64), out)
    return out
