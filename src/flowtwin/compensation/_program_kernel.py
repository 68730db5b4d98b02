"""Compiled kernels that assemble the refinement's program as compressed sparse rows.

A matrix is three arrays: ``ptr`` (row ``i`` holds entries ``ptr[i] : ptr[i + 1]``),
``col`` and ``val``; *canonical* rows have their columns ascending and no zero entry.
The products below add their terms in the order ``scipy.sparse`` does (a row's entries
from left to right, a transposed product's rows from top to bottom), so the program is
the same to the last bit as when it was assembled from ``scipy.sparse`` products.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = ["chain_matvec", "chain_rmatvec", "compact_slots", "csr_matvec", "csr_rmatvec",
           "drop_zeros", "group_rows", "sort_rows", "take_rows"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@njit(cache=True)
def sort_rows(ptr: IntArray, col: IntArray, val: FloatArray) -> None:
    """Sort every row's entries by column, in place (rows are short: insertion sort)."""
    for i in range(ptr.shape[0] - 1):
        for p in range(ptr[i] + 1, ptr[i + 1]):
            c = col[p]
            v = val[p]
            q = p - 1
            while q >= ptr[i] and col[q] > c:
                col[q + 1] = col[q]
                val[q + 1] = val[q]
                q -= 1
            col[q + 1] = c
            val[q + 1] = v


@njit(cache=True)
def take_rows(ptr: IntArray, col: IntArray, val: FloatArray, rows: IntArray
              ) -> tuple[IntArray, IntArray, FloatArray]:
    """The given rows of a matrix, in the given order."""
    new_ptr = np.empty(rows.shape[0] + 1, dtype=np.int64)
    new_ptr[0] = 0
    for k in range(rows.shape[0]):
        new_ptr[k + 1] = new_ptr[k] + ptr[rows[k] + 1] - ptr[rows[k]]
    new_col = np.empty(new_ptr[-1], dtype=np.int64)
    new_val = np.empty(new_ptr[-1])
    for k in range(rows.shape[0]):
        at = new_ptr[k]
        for p in range(ptr[rows[k]], ptr[rows[k] + 1]):
            new_col[at] = col[p]
            new_val[at] = val[p]
            at += 1
    return new_ptr, new_col, new_val


@njit(cache=True)
def drop_zeros(ptr: IntArray, col: IntArray, val: FloatArray
               ) -> tuple[IntArray, IntArray, FloatArray]:
    """The same rows without their entries whose value is zero (order kept)."""
    m = ptr.shape[0] - 1
    new_ptr = np.empty(m + 1, dtype=np.int64)
    new_ptr[0] = 0
    k = 0
    for i in range(m):
        for p in range(ptr[i], ptr[i + 1]):
            if val[p] != 0.0:
                k += 1
        new_ptr[i + 1] = k
    new_col = np.empty(k, dtype=np.int64)
    new_val = np.empty(k)
    at = 0
    for p in range(ptr[m]):
        if val[p] != 0.0:
            new_col[at] = col[p]
            new_val[at] = val[p]
            at += 1
    return new_ptr, new_col, new_val


@njit(cache=True)
def compact_slots(cols: npt.NDArray[np.int64], vals: npt.NDArray[np.float64]
                  ) -> tuple[IntArray, IntArray, FloatArray]:
    """Rows from a table of slots ``(m, w)``: every slot whose value is not zero, in
    order."""
    m, width = cols.shape
    ptr = np.empty(m + 1, dtype=np.int64)
    ptr[0] = 0
    for i in range(m):
        k = 0
        for j in range(width):
            if vals[i, j] != 0.0:
                k += 1
        ptr[i + 1] = ptr[i] + k
    col = np.empty(ptr[m], dtype=np.int64)
    val = np.empty(ptr[m])
    at = 0
    for i in range(m):
        for j in range(width):
            if vals[i, j] != 0.0:
                col[at] = cols[i, j]
                val[at] = vals[i, j]
                at += 1
    return ptr, col, val


@njit(cache=True)
def csr_matvec(ptr: IntArray, col: IntArray, val: FloatArray, x: FloatArray,
               out: FloatArray) -> None:
    """``out = A·x``, every row summed from its first entry to its last."""
    for i in range(ptr.shape[0] - 1):
        s = 0.0
        for p in range(ptr[i], ptr[i + 1]):
            s += val[p] * x[col[p]]
        out[i] = s


@njit(cache=True)
def csr_rmatvec(ptr: IntArray, col: IntArray, val: FloatArray, y: FloatArray,
                out: FloatArray) -> None:
    """``out = Aᵀ·y`` (``out`` zeroed by the caller), rows taken from the top."""
    for i in range(ptr.shape[0] - 1):
        yi = y[i]
        for p in range(ptr[i], ptr[i + 1]):
            out[col[p]] += val[p] * yi


@njit(cache=True)
def chain_matvec(diag: FloatArray, sub: FloatArray, pre: FloatArray, pre_of: IntArray,
                 x: FloatArray, out: FloatArray) -> None:
    """``out = C·x`` for the chain's ratio map ``C`` (``sub`` below the diagonal, ``diag``
    on it, ``pre`` in the column ``n + pre_of`` of a piece with a pre-charge), without
    the matrix: row ``p`` adds its non-zero entries from the left, as :func:`csr_matvec`
    does on the canonical rows of ``C``."""
    n = diag.shape[0]
    for p in range(n):
        s = 0.0
        if p >= 1 and sub[p] != 0.0:
            s += sub[p] * x[p - 1]
        if diag[p] != 0.0:
            s += diag[p] * x[p]
        if pre[p] != 0.0:
            s += pre[p] * x[n + pre_of[p]]
        out[p] = s


@njit(cache=True)
def chain_rmatvec(diag: FloatArray, sub: FloatArray, pre: FloatArray, pre_of: IntArray,
                  y: FloatArray, out: FloatArray) -> None:
    """``out = Cᵀ·y`` (``out`` zeroed by the caller) for the chain's ratio map, without
    the matrix: rows taken from the top, each row's non-zero entries from the left, as
    :func:`csr_rmatvec` does on the canonical rows of ``C``."""
    n = diag.shape[0]
    for p in range(n):
        yp = y[p]
        if p >= 1 and sub[p] != 0.0:
            out[p - 1] += sub[p] * yp
        if diag[p] != 0.0:
            out[p] += diag[p] * yp
        if pre[p] != 0.0:
            out[n + pre_of[p]] += pre[p] * yp


@njit(cache=True)
def group_rows(grp: IntArray, n_groups: int, l_p: FloatArray, cd: FloatArray,
               cs: FloatArray, cy: FloatArray, y_of: IntArray, alpha: FloatArray,
               n: int) -> tuple[IntArray, IntArray, FloatArray]:
    """Rows ``R`` of the moves' outputs in the states ``[x; y]`` (canonical, columns of
    the unpermuted variables: ``x_p`` is ``p``, pre-charge ``k`` is ``n + k``).

    Row ``g`` is ``Σ_(p∈g) L_p·C[p, :] − e_last(g) + P[first(g), :]`` with ``C`` the
    chain's ratio map (``cd`` on its diagonal, ``cs`` below it, ``cy`` in the pre-charge
    column of a piece with one, ``y_of`` its index or −1) and ``P`` the state before a
    piece (``α`` below the diagonal, 1 in its pre-charge's column). Pieces of a group
    are consecutive (``grp`` does not decrease).
    """
    m = n_groups
    counts = np.zeros(m, dtype=np.int64)
    for p in range(n):
        g = grp[p]
        counts[g] += 1
        if p == 0 or grp[p - 1] != g:
            counts[g] += 1  # the column before the group
        if y_of[p] >= 0:
            counts[g] += 1
    ptr = np.zeros(m + 1, dtype=np.int64)
    for g in range(m):
        ptr[g + 1] = ptr[g] + counts[g]
    col = np.empty(ptr[m], dtype=np.int64)
    val = np.empty(ptr[m], dtype=np.float64)
    fill = ptr[:m].copy()
    p = 0
    while p < n:
        g = grp[p]
        first = p
        last = p
        while last + 1 < n and grp[last + 1] == g:
            last += 1
        at = fill[g]
        if first >= 1:
            col[at] = first - 1
            val[at] = l_p[first] * cs[first] + alpha[first]
        else:
            col[at] = 0
            val[at] = 0.0
        at += 1
        for q in range(first, last + 1):
            r1 = l_p[q] * cd[q]
            if q < last:
                r1 = r1 + l_p[q + 1] * cs[q + 1]
                col[at] = q
                val[at] = r1
            else:
                col[at] = q
                val[at] = r1 - 1.0
            at += 1
        for q in range(first, last + 1):
            if y_of[q] >= 0:
                col[at] = n + y_of[q]
                v = l_p[q] * cy[q]
                val[at] = v + 1.0 if q == first else v
                at += 1
        fill[g] = at
        p = last + 1
    sort_rows(ptr, col, val)
    return ptr, col, val
