"""The refinement's quadratic program, assembled as arrays.

:func:`flowtwin.compensation.refine.refine_qp` states the program in the states ``x`` after
the free pieces and the pre-charges ``y`` (see there): the pieces' ratios are
``c = C·[x; y] + c0`` with ``C`` lower bidiagonal (one more entry in the pre-charge's
column of the piece it feeds), the moves' outputs ``R·[x; y] + r0`` with one row per move.
This module builds ``C``, ``R``, the Hessian ``Cᵀ·V·C`` and the constraint rows directly as
compressed rows (:class:`Csr`) from the chain's coefficients, in the order the solver
reads the variables (every pre-charge just before the piece it feeds), at the cost of a
few passes over the pieces; the arithmetic is that of the ``scipy.sparse`` products it
replaces, term for term (:mod:`flowtwin.compensation._program_kernel`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.compensation._program_kernel import (
    chain_matvec,
    chain_rmatvec,
    compact_slots,
    csr_matvec,
    csr_rmatvec,
    drop_zeros,
    group_rows,
    sort_rows,
    take_rows,
)

__all__ = ["Chain", "Csr", "PartProgram", "program_parts", "slot_rows", "stack_rows"]

BoolArray = npt.NDArray[np.bool_]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class Csr:
    """A sparse matrix as compressed rows: row ``i`` is ``col/val[ptr[i] : ptr[i + 1]]``."""

    ptr: IntArray
    col: IntArray
    val: FloatArray

    @property
    def n_rows(self) -> int:
        """Number of rows."""
        return int(self.ptr.size - 1)

    def matvec(self, x: FloatArray) -> FloatArray:
        """``A·x``, shape ``(n_rows,)``."""
        out = np.empty(self.n_rows)
        csr_matvec(self.ptr, self.col, self.val, np.ascontiguousarray(x, dtype=np.float64),
                   out)
        return out

    def rmatvec(self, y: FloatArray, size: int) -> FloatArray:
        """``Aᵀ·y``, shape ``(size,)``."""
        out = np.zeros(size)
        csr_rmatvec(self.ptr, self.col, self.val,
                    np.ascontiguousarray(y, dtype=np.float64), out)
        return out

    def squared(self) -> Csr:
        """The entries squared (same pattern)."""
        return Csr(self.ptr, self.col, self.val * self.val)

    def take(self, rows: IntArray) -> Csr:
        """The given rows, in the given order."""
        return Csr(*take_rows(self.ptr, self.col, self.val,
                              np.ascontiguousarray(rows, dtype=np.int64)))

    def renumbered(self, new_col: IntArray) -> Csr:
        """Columns renumbered (``j → new_col[j]``), each row sorted again."""
        col = np.asarray(new_col, dtype=np.int64)[self.col]
        val = self.val.copy()
        sort_rows(self.ptr, col, val)
        return Csr(self.ptr, col, val)


def slot_rows(cols: IntArray, vals: FloatArray) -> Csr:
    """Rows from a table of slots (``(m, w)``, columns ascending along each row); slots
    whose value is zero are no entries."""
    ptr, col, val = compact_slots(np.ascontiguousarray(cols, dtype=np.int64),
                                  np.ascontiguousarray(vals, dtype=np.float64))
    return Csr(ptr, col, val)


@dataclass(frozen=True, slots=True)
class Chain:
    """The ratio map ``c = C·[x; y] + c0`` of the free pieces.

    Attributes
    ----------
    diag, sub, pre
        ``C[p, p]``, ``C[p, p − 1]`` (0 for ``p = 0``) and ``C[p, n + k]`` for the
        pre-charge ``k`` feeding piece ``p`` (0 without one), shape ``(n,)`` each.
    pre_of
        Pre-charge feeding each piece, or −1, shape ``(n,)``.
    pre_piece
        Piece each pre-charge feeds, shape ``(k,)``.
    new_index
        Position of every variable ``[x; y]`` in the solver's order (each pre-charge
        just before the piece it feeds), shape ``(n + k,)``.
    """

    diag: FloatArray
    sub: FloatArray
    pre: FloatArray
    pre_of: IntArray
    pre_piece: IntArray
    new_index: IntArray

    @property
    def n(self) -> int:
        """Free pieces."""
        return int(self.diag.size)

    @property
    def size(self) -> int:
        """Variables (states and pre-charges)."""
        return int(self.diag.size + self.pre_piece.size)

    @classmethod
    def of(cls, alpha: FloatArray, e_p: FloatArray, b_p: FloatArray,
           pre_piece: IntArray) -> Chain:
        """From the chain's coefficients (:func:`free_piece_chain`, ``B_p`` floored)."""
        n = b_p.size
        k_y = pre_piece.size
        sub = np.zeros(n)
        sub[1:] = -(e_p[1:] * alpha[1:]) / b_p[1:]
        pre = np.zeros(n)
        pre[pre_piece] = -e_p[pre_piece] / b_p[pre_piece]
        pre_of = np.full(n, -1, dtype=np.int64)
        pre_of[pre_piece] = np.arange(k_y)
        new_index = np.arange(n + k_y, dtype=np.int64)
        if k_y:
            order = np.argsort(np.concatenate((np.arange(n), pre_piece - 0.5)), kind="stable")
            new_index[order] = np.arange(n + k_y)
        return cls(1.0 / b_p, sub, pre, pre_of, np.asarray(pre_piece, dtype=np.int64),
                   new_index)

    @property
    def order(self) -> IntArray:
        """Variable at every position of the solver's order (inverse of ``new_index``)."""
        out = np.empty_like(self.new_index)
        out[self.new_index] = np.arange(self.new_index.size)
        return out

    def matrix(self) -> Csr:
        """``C`` in the variables' own order."""
        n = self.n
        p = np.arange(n)
        cols = np.column_stack((np.maximum(p - 1, 0), p, n + np.maximum(self.pre_of, 0)))
        return slot_rows(cols, np.column_stack((self.sub, self.diag, self.pre)))

    def matvec(self, x: FloatArray) -> FloatArray:
        """``C·x`` (as :meth:`matrix`'s, to the bit), shape ``(n,)``."""
        out = np.empty(self.n)
        chain_matvec(self.diag, self.sub, self.pre, self.pre_of,
                     np.ascontiguousarray(x, dtype=np.float64), out)
        return out

    def rmatvec(self, y: FloatArray) -> FloatArray:
        """``Cᵀ·y`` (as :meth:`matrix`'s, to the bit), shape ``(size,)``."""
        out = np.zeros(self.size)
        chain_rmatvec(self.diag, self.sub, self.pre, self.pre_of,
                      np.ascontiguousarray(y, dtype=np.float64), out)
        return out

    def _pre_column(self, piece: IntArray) -> IntArray:
        """Solver's column of the pre-charge feeding each piece (0 for none)."""
        k = self.pre_of[piece]
        return np.where(k >= 0, self.new_index[np.minimum(self.n + k, self.size - 1)], 0)

    def box_rows(self) -> Csr:
        """``C`` with the solver's column order."""
        n = self.n
        p = np.arange(n)
        ni = self.new_index
        cols = np.column_stack((ni[np.maximum(p - 1, 0)], self._pre_column(p), ni[p]))
        return slot_rows(cols, np.column_stack((self.sub, self.pre, self.diag)))

    def step_rows(self, step: IntArray) -> Csr:
        """``C[p] − C[p − 1]`` for every ``p`` of ``step`` (all ≥ 1), solver's columns."""
        ni = self.new_index
        p = np.asarray(step, dtype=np.int64)
        q = p - 1
        cols = np.column_stack((ni[np.maximum(p - 2, 0)], self._pre_column(q), ni[q],
                                self._pre_column(p), ni[p]))
        sub_q = np.where(q >= 1, self.sub[q], 0.0)
        vals = np.column_stack((-sub_q, -self.pre[q], -self.diag[q] + self.sub[p],
                                self.pre[p], self.diag[p]))
        return slot_rows(cols, vals)

    def unit_rows(self, var: IntArray) -> Csr:
        """One row ``e_var`` per given variable (own numbering), solver's columns."""
        var = np.asarray(var, dtype=np.int64)
        return slot_rows(self.new_index[var][:, None], np.ones((var.size, 1)))

    def hessian_diagonal(self, v: FloatArray, v_y: FloatArray) -> FloatArray:
        """Diagonal of ``Cᵀ·diag(v)·C + diag(0, v_y)`` in the variables' own order."""
        hd, h_yy = self._diagonals(v, v_y)
        return np.concatenate((hd, h_yy))

    def _diagonals(self, v: FloatArray, v_y: FloatArray) -> tuple[FloatArray, FloatArray]:
        d, s, y = self.diag, self.sub, self.pre
        hd = (d * v) * d
        hd[:-1] = hd[:-1] + (s[1:] * v[1:]) * s[1:]
        a = self.pre_piece
        return hd, (y[a] * v[a]) * y[a] + v_y

    def hessian(self, v: FloatArray, v_y: FloatArray) -> tuple[Csr, FloatArray]:
        """Upper triangle of ``Cᵀ·diag(v)·C + diag(0, v_y)`` in the solver's order (rows by
        position, canonical), and its diagonal in the variables' own order."""
        n = self.n
        k_y = self.pre_piece.size
        d, s, y = self.diag, self.sub, self.pre
        hd, h_yy = self._diagonals(v, v_y)
        h_next = np.zeros(n)  # H[p, p + 1]
        h_next[:-1] = (s[1:] * v[1:]) * d[1:]
        a = self.pre_piece
        h_before = np.where(a >= 1, (s[a] * v[a]) * y[a], 0.0)  # H[p − 1, y]
        h_after = (y[a] * v[a]) * d[a]  # H[y, p]
        ni = self.new_index
        size = n + k_y
        cols = np.zeros((size, 3), dtype=np.int64)
        vals = np.zeros((size, 3))
        p = np.arange(n)
        rows_x = ni[p]
        cols[rows_x, 0] = rows_x
        vals[rows_x, 0] = hd
        nxt = np.minimum(p + 1, n - 1)
        y_next = np.where(p + 1 < n, self.pre_of[nxt], -1)
        has = y_next >= 0
        cols[rows_x[has], 1] = ni[n + y_next[has]]
        vals[rows_x[has], 1] = h_before[y_next[has]]
        cols[rows_x, 2] = ni[nxt]
        vals[rows_x, 2] = h_next
        rows_y = ni[n + np.arange(k_y)]
        cols[rows_y, 0] = rows_y
        vals[rows_y, 0] = h_yy
        cols[rows_y, 1] = ni[a]
        vals[rows_y, 1] = h_after
        return slot_rows(cols, vals), np.concatenate((hd, h_yy))

    def outputs(self, grp: IntArray, n_groups: int, l_p: FloatArray,
                alpha: FloatArray) -> Csr:
        """``R``: every move's output in ``[x; y]`` (own numbering, canonical)."""
        ptr, col, val = group_rows(np.ascontiguousarray(grp, dtype=np.int64), int(n_groups),
                                   l_p, self.diag, self.sub, self.pre, self.pre_of, alpha,
                                   self.n)
        return Csr(*drop_zeros(ptr, col, val))

    def cuts(self, alpha: FloatArray, l_p: FloatArray, v: FloatArray, grp: IntArray,
             stepped: npt.NDArray[np.bool_]) -> IntArray:
        """Pieces ``p`` (≥ 1) before which the program falls apart: no entry of ``C``,
        ``Cᵀ·V·C``, ``R`` or a ratio-step row joins ``p`` (or its pre-charge) to
        ``p − 1`` or anything before it (their value is exactly zero, as the assembly drops
        them). ``stepped``: pieces with a ratio-step row to the previous one. Every such
        cut is a cut of the solver's blocks (:func:`flowtwin.compensation._qp.qp_blocks`),
        so the program may be assembled and solved part by part, to the same bits.
        """
        n = self.n
        if n < 2:
            return np.zeros(0, dtype=np.int64)
        p = np.arange(1, n)
        s, d = self.sub[1:], self.diag[1:]
        sv = s * v[1:]
        ok = (s == 0.0) & ((sv * d) == 0.0) & ((sv * s) == 0.0)  # C, H[p − 1, p]
        ok &= (l_p[1:] * s + alpha[1:]) == 0.0  # R: the state before the move
        ok &= grp[1:] != grp[:-1]  # R: a move's pieces
        ok &= ~stepped[1:]
        has_y = self.pre_of[1:] >= 0
        ok &= ~has_y | ((sv * self.pre[1:]) == 0.0)  # H[p − 1, y]
        return p[ok].astype(np.int64)

    def part(self, p0: int, p1: int) -> tuple[Chain, IntArray, int]:
        """The chain of pieces ``p0 … p1 − 1`` (cut at :meth:`cuts`), its pre-charges
        (indices into this chain's, ascending) and its first position in the solver's
        order (its variables are the positions from there on, in the same order)."""
        pre_of = self.pre_of[p0:p1]
        ys = np.sort(pre_of[pre_of >= 0])
        local = np.full(self.pre_piece.size, -1, dtype=np.int64)
        local[ys] = np.arange(ys.size)
        n = p1 - p0
        pre_piece = self.pre_piece[ys] - p0
        new_index = np.arange(n + ys.size, dtype=np.int64)
        pre_local = np.full(n, -1, dtype=np.int64)
        if ys.size:
            order = np.argsort(np.concatenate((np.arange(n), pre_piece - 0.5)), kind="stable")
            new_index[order] = np.arange(n + ys.size)
            pre_local[pre_of >= 0] = local[pre_of[pre_of >= 0]]
        first = int(self.new_index[p0]) - (1 if self.pre_of[p0] >= 0 else 0)
        return (Chain(self.diag[p0:p1], self.sub[p0:p1], self.pre[p0:p1], pre_local,
                      pre_piece, new_index), ys, first)


def stack_rows(parts: list[Csr]) -> Csr:
    """Rows of several matrices, one below the other."""
    ptr = [np.zeros(1, dtype=np.int64)]
    at = 0
    for part in parts:
        ptr.append(part.ptr[1:] + at)
        at += int(part.ptr[-1])
    return Csr(np.concatenate(ptr), np.concatenate([p.col for p in parts]),
               np.concatenate([p.val for p in parts]))


#: Pieces the refinement's program is assembled and solved for at a time (at least; it is
#: cut only between runs the program does not join, see :meth:`Chain.cuts`).
_PART_PIECES = 1 << 15


def program_parts(cuts: IntArray, n: int, size: int | None = None) -> list[tuple[int, int]]:
    """Ranges ``[p0, p1)`` of at least ``size`` pieces (default ``_PART_PIECES``; but the
    last), cut at ``cuts``."""
    size = _PART_PIECES if size is None else size
    out = []
    at = 0
    while at < n:
        k = int(np.searchsorted(cuts, at + size))
        end = int(cuts[k]) if k < cuts.size else n
        out.append((at, end))
        at = end
    return out


@dataclass(frozen=True, slots=True)
class PartProgram:
    """The refinement's program, assembled and solved part by part
    (:func:`flowtwin.compensation.refine.refine_qp`): the chain, the weights (``w``
    already divided by the scale), the linear term and the start in the solver's order,
    the ratio box, the pre-charges' bounds and the ratio steps."""

    chain: Chain
    alpha: FloatArray
    l_p: FloatArray
    grp: IntArray
    w: FloatArray
    v: FloatArray
    v_y: FloatArray
    g: FloatArray
    x0: FloatArray
    c0: FloatArray
    c_min: FloatArray
    hi: FloatArray
    y_max: FloatArray
    stepped: BoolArray
    jump: FloatArray | None
    scale: float

    def solve(self, p0: int, p1: int, capped: BoolArray | None,
              state_max: FloatArray | None, *, max_iterations: int,
              tolerance: float) -> tuple[int, FloatArray, int]:
        """Solve the part of pieces ``p0 … p1 − 1`` (with the state cap where ``capped``):
        its first position in the solver's order, its variables there, the iterations."""
        from flowtwin.compensation._part_kernel import part_hessian, part_rows
        from flowtwin.compensation._qp import solve_program

        ch, ys, q0 = self.chain.part(p0, p1)
        size = ch.size
        # constraint rows, in the solver's order of the variables: the ratio box,
        # 0 ≤ y_k ≤ y_max, no backflow [001 Fig. 8] (a piece that may pull back, c_min < 0,
        # ends with x ≥ 0; the state falls monotonically while it pulls, so it stays ≥ 0
        # throughout and the linear model stays the twin's), the ratio steps
        # c_p − c_(p−1) = (C[p] − C[p−1])·x + c0_p − c0_(p−1) within ±jump_p, the state cap
        # (the rows box_rows, unit_rows and step_rows give, stacked)
        cap_part, cap_max = np.zeros(0, dtype=np.bool_), self.c0[:0]
        if capped is not None and state_max is not None:
            cap_part = capped[p0:p1]
            cap_max = np.asarray(state_max, dtype=np.float64)[p0:p1]
        rows_ptr, rows_col, rows_val, d_con, lo_con, hi_con = part_rows(
            ch.diag, ch.sub, ch.pre, ch.pre_of, ch.new_index, self.c0[p0:p1],
            self.c_min[p0:p1], self.hi[p0:p1], self.y_max[ys], self.jump is not None,
            self.stepped[p0:p1], self.c0[p0:p1] if self.jump is None else self.jump[p0:p1],
            cap_part, cap_max)
        # the Hessian's upper triangle (as hessian() gives it, divided as scipy.sparse
        # divides, zeros dropped)
        h = part_hessian(ch.diag, ch.sub, ch.pre, ch.pre_of, ch.pre_piece, ch.new_index,
                         self.v[p0:p1], self.v_y[ys], 1.0 / self.scale)
        g0, g1 = int(self.grp[p0]), int(self.grp[p1 - 1]) + 1
        r = ch.outputs(self.grp[p0:p1] - g0, g1 - g0, self.l_p[p0:p1], self.alpha[p0:p1])
        if ys.size:
            r = r.renumbered(ch.new_index)
        z, its, _mu = solve_program(
            size, h, self.g[q0:q0 + size], (rows_ptr, rows_col, rows_val),
            d_con, lo_con, hi_con,
            self.x0[q0:q0 + size], squares=(r.ptr, r.col, r.val, self.w[g0:g1]),
            max_iterations=max_iterations, tolerance=tolerance)
        return q0, z, its
