"""Compiled kernel of the original file's E grid: a line's E split over its rows.

A line the reader cuts into several rows (an arc's chords) keeps its E exactly on the
grid: the cumulative E at each row's end is the line's grid E times the row's share of the
reader's E, rounded (``numpy.rint``), the last one the line's own. :func:`split_lines`
does this for every such line in one pass with numpy's arithmetic, operation by operation:
the share's denominator is summed as ``numpy.sum`` sums a contiguous float64 array
(pairwise: eight running sums per block of at most 128, blocks halved on multiples of
8; ``_numpy_sum``), the numerators as ``numpy.cumsum`` (in order).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = ["split_lines"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Rows of a line beyond which the caller splits it (numpy's own sum then, which may cut a
#: long array into buffers).
MAX_ROWS = 4096
_BLOCK = 128


@njit(cache=True)
def _block_sum(a: FloatArray, lo: int, n: int) -> float:
    """numpy's sum of at most ``_BLOCK`` values: in order below 8, else eight running sums
    (every eighth value), joined pairwise, then the rest in order."""
    if n < 8:
        res = 0.0
        for i in range(lo, lo + n):
            res += a[i]
        return res
    r0 = a[lo]
    r1 = a[lo + 1]
    r2 = a[lo + 2]
    r3 = a[lo + 3]
    r4 = a[lo + 4]
    r5 = a[lo + 5]
    r6 = a[lo + 6]
    r7 = a[lo + 7]
    i = 8
    while i < n - (n % 8):
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True)
def _numpy_sum(a: FloatArray, lo: int, n: int) -> float:
    """``numpy.sum(a[lo : lo + n])`` (float64, contiguous): numpy's pairwise summation, a
    stretch longer than ``_BLOCK`` the sum of its two halves (the first cut to a multiple
    of 8). Without recursion (a recursive kernel loads slowly from numba's cache): the
    halves on an explicit stack, each sum made when both of its halves are."""
    if n <= _BLOCK:
        return _block_sum(a, lo, n)
    depth = 64
    st_lo = np.empty(depth, dtype=np.int64)
    st_n = np.empty(depth, dtype=np.int64)
    st_stage = np.empty(depth, dtype=np.int64)
    vals = np.empty(depth)
    sp = 0
    vp = 0
    st_lo[0] = lo
    st_n[0] = n
    st_stage[0] = 0
    sp = 1
    while sp > 0:
        f_lo = st_lo[sp - 1]
        f_n = st_n[sp - 1]
        if f_n <= _BLOCK:
            vals[vp] = _block_sum(a, f_lo, f_n)
            vp += 1
            sp -= 1
            continue
        half = f_n // 2
        half -= half % 8
        stage = st_stage[sp - 1]
        st_stage[sp - 1] = stage + 1
        if stage == 0:  # the first half
            st_lo[sp] = f_lo
            st_n[sp] = half
            st_stage[sp] = 0
            sp += 1
        elif stage == 1:  # the second
            st_lo[sp] = f_lo + half
            st_n[sp] = f_n - half
            st_stage[sp] = 0
            sp += 1
        else:  # both made: first + second
            vals[vp - 2] = vals[vp - 2] + vals[vp - 1]
            vp -= 1
            sp -= 1
    return float(vals[0])


@njit(cache=True, error_model="numpy")
def split_lines(de: FloatArray, first: IntArray, counts: IntArray, line_grid: IntArray,
                out: IntArray) -> IntArray:
    """Split the grid E of every line of more than one row over its rows, in ``out``.

    Parameters
    ----------
    de
        The reader's E of every row, shape ``(n,)``.
    first, counts
        First row and rows of every line, shape ``(k,)``.
    line_grid
        Every line's E on the grid, shape ``(k,)``.
    out
        Every row's E on the grid, shape ``(n,)``: written for the lines split here.

    Returns
    -------
    ndarray
        The lines of more than one row left to the caller: their rows' E sums to zero
        (spread evenly instead) or they have more than :data:`MAX_ROWS` rows.
    """
    left = np.zeros(first.shape[0], dtype=np.bool_)
    n_left = 0
    for k in range(first.shape[0]):
        m = counts[k]
        if m < 2:
            continue
        a = first[k]
        s = _numpy_sum(de, a, m) if m <= MAX_ROWS else 0.0
        if m > MAX_ROWS or s == 0.0:
            left[k] = True
            n_left += 1
            continue
        g = float(line_grid[k])
        cum = 0.0
        prev = 0
        for i in range(m - 1):
            cum = de[a] if i == 0 else cum + de[a + i]
            pos = int(np.rint(cum / s * g))
            out[a + i] = pos - prev
            prev = pos
        out[a + m - 1] = line_grid[k] - prev
    out_left = np.empty(n_left, dtype=np.int64)  # (no np.flatnonzero: its implementation
    j = 0                                         # makes numba's cache load import scipy)
    for k in range(first.shape[0]):
        if left[k]:
            out_left[j] = k
            j += 1
    return out_left
