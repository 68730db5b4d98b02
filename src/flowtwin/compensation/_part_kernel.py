"""Compiled kernels that assemble one part of the refinement's program
(:meth:`flowtwin.compensation.program.PartProgram.solve`) in one pass each: the
constraint rows with their offsets and bounds, and the Hessian's upper triangle as
entries. They write what the chain's slot tables (:meth:`~flowtwin.compensation.program.
Chain.box_rows`, ``unit_rows``, ``step_rows``, ``hessian``) stacked and compacted give,
to the bit: the same products in the same order, zero slots dropped.

The part's chain is in the variables' own order (states ``0 … n − 1``, then its
pre-charges); ``ni`` is every variable's position in the solver's order.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = ["part_hessian", "part_rows"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


@njit(cache=True)
def _pre_col(pre_of: IntArray, ni: IntArray, p: int, n: int, size: int) -> int:
    """Solver's column of the pre-charge feeding piece ``p`` (0 for none)."""
    k = pre_of[p]
    if k < 0:
        return 0
    return ni[min(n + k, size - 1)]


@njit(cache=True)
def _put(col: IntArray, val: FloatArray, at: int, c: int, v: float) -> int:
    """Store the slot ``(c, v)`` at ``at`` unless ``v`` is zero; the next free place."""
    if v != 0.0:
        col[at] = c
        val[at] = v
        return at + 1
    return at


@njit(cache=True)
def part_rows(diag: FloatArray, sub: FloatArray, pre: FloatArray, pre_of: IntArray,
              ni: IntArray, c0: FloatArray, c_min: FloatArray, c_hi: FloatArray,
              y_hi: FloatArray, use_jump: bool, stepped: BoolArray, jump: FloatArray,
              capped: BoolArray, state_max: FloatArray):  # type: ignore[no-untyped-def]
    """The part's constraint rows (compressed, solver's columns) and their ``d, lo, hi``.

    In order: the ratio box ``c_min ≤ C·x + c0 ≤ c_hi`` of every piece; ``0 ≤ y_k ≤
    y_hi`` of every pre-charge; ``x_p ≥ 0`` after every piece with ``c_min < 0``; with
    ``use_jump``, ``|c_p − c_(p−1)| ≤ max(jump_p, 1e-9)`` (NaN stays NaN) for every
    ``stepped`` piece (all ``p ≥ 1``); ``x_p ≤ state_max_p`` for every ``capped`` piece
    (``capped`` empty: none).
    """
    n = diag.shape[0]
    k_y = y_hi.shape[0]
    size = n + k_y
    n_pull = 0
    n_step = 0
    n_cap = 0
    for p in range(n):
        if c_min[p] < 0:
            n_pull += 1
        if use_jump and stepped[p]:
            n_step += 1
        if capped.shape[0] and capped[p]:
            n_cap += 1
    m = n + k_y + n_pull + n_step + n_cap
    ptr = np.empty(m + 1, dtype=np.int64)
    col = np.empty(3 * n + k_y + n_pull + 5 * n_step + n_cap, dtype=np.int64)
    val = np.empty(col.shape[0])
    d = np.empty(m)
    lo = np.empty(m)
    hi = np.empty(m)
    ptr[0] = 0
    at = 0
    i = 0
    for p in range(n):  # the ratio box: C[p] (slots C[p, p − 1], pre-charge, C[p, p])
        at = _put(col, val, at, ni[max(p - 1, 0)], sub[p])
        at = _put(col, val, at, _pre_col(pre_of, ni, p, n, size), pre[p])
        at = _put(col, val, at, ni[p], diag[p])
        d[i] = c0[p]
        lo[i] = c_min[p]
        hi[i] = c_hi[p]
        i += 1
        ptr[i] = at
    for k in range(k_y):  # the pre-charges' bounds
        at = _put(col, val, at, ni[n + k], 1.0)
        d[i] = 0.0
        lo[i] = 0.0
        hi[i] = y_hi[k]
        i += 1
        ptr[i] = at
    for p in range(n):  # no backflow
        if c_min[p] < 0:
            at = _put(col, val, at, ni[p], 1.0)
            d[i] = 0.0
            lo[i] = 0.0
            hi[i] = np.inf
            i += 1
            ptr[i] = at
    if use_jump:
        for p in range(n):  # the ratio steps C[p] − C[p − 1]
            if not stepped[p]:
                continue
            q = p - 1
            sub_q = sub[q] if q >= 1 else 0.0
            at = _put(col, val, at, ni[max(p - 2, 0)], -sub_q)
            at = _put(col, val, at, _pre_col(pre_of, ni, q, n, size), -pre[q])
            at = _put(col, val, at, ni[q], -diag[q] + sub[p])
            at = _put(col, val, at, _pre_col(pre_of, ni, p, n, size), pre[p])
            at = _put(col, val, at, ni[p], diag[p])
            j = jump[p]
            if not j > 1e-9 and j == j:  # (numpy's maximum: NaN wins)
                j = 1e-9
            d[i] = c0[p] - c0[q]
            lo[i] = -j
            hi[i] = j
            i += 1
            ptr[i] = at
    for p in range(capped.shape[0]):  # the state cap
        if capped[p]:
            at = _put(col, val, at, ni[p], 1.0)
            d[i] = 0.0
            lo[i] = -np.inf
            hi[i] = state_max[p]
            i += 1
            ptr[i] = at
    return ptr, col[:at].copy(), val[:at].copy(), d, lo, hi


@njit(cache=True)
def part_hessian(diag: FloatArray, sub: FloatArray, pre: FloatArray, pre_of: IntArray,
                 pre_piece: IntArray, ni: IntArray, v: FloatArray, v_y: FloatArray,
                 inv_scale: float):  # type: ignore[no-untyped-def]
    """Entries ``(rows, cols, vals)`` of the upper triangle of ``Cᵀ·diag(v)·C +
    diag(0, v_y)`` in the solver's order, rows by position and columns ascending, each
    value times ``inv_scale``, zeros dropped (those of the product too)."""
    n = diag.shape[0]
    k_y = pre_piece.shape[0]
    size = n + k_y
    cols = np.zeros((size, 3), dtype=np.int64)
    vals = np.zeros((size, 3))
    for p in range(n):
        r = ni[p]
        hd = (diag[p] * v[p]) * diag[p]
        if p + 1 < n:
            hd = hd + (sub[p + 1] * v[p + 1]) * sub[p + 1]
        cols[r, 0] = r
        vals[r, 0] = hd
        if p + 1 < n:
            k = pre_of[p + 1]
            if k >= 0:  # H[p, y] of the pre-charge feeding p + 1
                a = pre_piece[k]
                cols[r, 1] = ni[n + k]
                vals[r, 1] = (sub[a] * v[a]) * pre[a] if a >= 1 else 0.0
            cols[r, 2] = ni[p + 1]
            vals[r, 2] = (sub[p + 1] * v[p + 1]) * diag[p + 1]
        else:
            cols[r, 2] = ni[n - 1]
            vals[r, 2] = 0.0
    for k in range(k_y):
        a = pre_piece[k]
        r = ni[n + k]
        cols[r, 0] = r
        vals[r, 0] = (pre[a] * v[a]) * pre[a] + v_y[k]
        cols[r, 1] = ni[a]
        vals[r, 1] = (pre[a] * v[a]) * diag[a]
    count = 0
    for r in range(size):
        for s in range(3):
            if vals[r, s] != 0.0 and vals[r, s] * inv_scale != 0.0:
                count += 1
    h_r = np.empty(count, dtype=np.int64)
    h_c = np.empty(count, dtype=np.int64)
    h_v = np.empty(count)
    at = 0
    for r in range(size):
        for s in range(3):
            x = vals[r, s]
            if x != 0.0:
                x = x * inv_scale
                if x != 0.0:
                    h_r[at] = r
                    h_c[at] = cols[r, s]
                    h_v[at] = x
                    at += 1
    return h_r, h_c, h_v
