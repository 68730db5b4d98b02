"""The independent blocks of :mod:`flowtwin.compensation._qp`'s program, and the order of
its entries and rows by block.

Variables ``i`` and ``i + 1`` belong to one block when an entry ``H[r, c]`` with
``r ≤ i < c``, a constraint row or a squared row reading columns on both sides of the
boundary joins them. The solver reads each block's entries of ``H``, constraint rows and
squared rows as one contiguous stretch: :func:`block_layout` finds the blocks and the
(stable) orders that put the entries and rows of every block together, in one compiled
pass; :func:`qp_blocks` is the blocks alone, from the rows' spans.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = ["block_layout", "qp_blocks"]

IntArray = npt.NDArray[np.int64]


def qp_blocks(n: int, h_r: IntArray, h_c: IntArray, row_lo: IntArray, row_hi: IntArray
              ) -> tuple[IntArray, IntArray]:
    """Independent blocks of variables: ``[starts[k], ends[k])``.

    Variables ``i`` and ``i + 1`` belong together when an entry ``H[r, c]`` with
    ``r ≤ i < c`` or a constraint row spanning columns ``row_lo … row_hi`` across them
    couples them.
    """
    cover = np.zeros(n + 1, dtype=np.int64)
    np.add.at(cover, np.minimum(h_r, h_c), 1)
    np.add.at(cover, np.maximum(h_r, h_c), -1)
    np.add.at(cover, row_lo, 1)
    np.add.at(cover, row_hi, -1)
    joined = np.cumsum(cover)[:max(n - 1, 0)] > 0  # boundary i | i + 1 is joined
    cuts = np.flatnonzero(~joined) + 1
    starts = np.concatenate(([0], cuts)).astype(np.int64)
    ends = np.concatenate((cuts, [n])).astype(np.int64)
    return starts, ends


@njit(cache=True)
def _spans(ptr: IntArray, col: IntArray) -> tuple[IntArray, IntArray]:
    """Lowest and highest column of every row (``0, 0`` for an empty row, which joins
    nothing)."""
    m = ptr.shape[0] - 1
    lo = np.zeros(m, dtype=np.int64)
    hi = np.zeros(m, dtype=np.int64)
    for i in range(m):
        if ptr[i + 1] > ptr[i]:
            a = col[ptr[i]]
            b = a
            for p in range(ptr[i] + 1, ptr[i + 1]):
                a = min(a, col[p])
                b = max(b, col[p])
            lo[i] = a
            hi[i] = b
    return lo, hi


@njit(cache=True)
def _stable_order(key: IntArray, n_keys: int) -> tuple[IntArray, IntArray]:
    """Counting sort: the stable order of ``key`` (values ``0 … n_keys − 1``; empty when
    ``key`` is already in order, nothing to move) and where every key's stretch starts
    in that order, ``(n_keys + 1,)``."""
    count = np.zeros(n_keys + 1, dtype=np.int64)
    ordered = True
    for i in range(key.shape[0]):
        count[key[i] + 1] += 1
        if i > 0 and key[i] < key[i - 1]:
            ordered = False
    for k in range(n_keys):
        count[k + 1] += count[k]
    if ordered:
        return np.zeros(0, dtype=np.int64), count
    at = count[:n_keys].copy()
    order = np.empty(key.shape[0], dtype=np.int64)
    for i in range(key.shape[0]):
        order[at[key[i]]] = i
        at[key[i]] += 1
    return order, count


@njit(cache=True)
def block_layout(n: int, h_r: IntArray, h_c: IntArray, c_ptr: IntArray, c_col: IntArray,
                 r_ptr: IntArray, r_col: IntArray):  # type: ignore[no-untyped-def]
    """Blocks of the program and its entries and rows ordered by block.

    Parameters
    ----------
    n
        Variables.
    h_r, h_c
        Rows and columns of the entries of ``H`` (upper triangle, ``h_r ≤ h_c``).
    c_ptr, c_col
        Pattern of the constraint rows (compressed rows).
    r_ptr, r_col
        Pattern of the squared rows (compressed rows, none empty).

    Returns
    -------
    tuple
        ``starts, ends`` of the blocks (as :func:`qp_blocks`; one empty block when
        ``n = 0``); ``h_order, h_ptr``: the stable order of the entries of ``H`` by the
        block of their row and the first of each block in it; ``row_order, row_ptr``:
        the same for the constraint rows, by the block of their lowest column (an empty
        row: block 0); ``sq_order, sq_ptr``: the squared rows by their highest column
        (stable), and the first of each block. An order is empty when nothing moves.
    """
    row_lo, row_hi = _spans(c_ptr, c_col)
    sq_lo, sq_hi = _spans(r_ptr, r_col)
    cover = np.zeros(n + 1, dtype=np.int64)
    for p in range(h_r.shape[0]):
        cover[min(h_r[p], h_c[p])] += 1
        cover[max(h_r[p], h_c[p])] -= 1
    for q in range(row_lo.shape[0]):
        cover[row_lo[q]] += 1
        cover[row_hi[q]] -= 1
    for q in range(sq_lo.shape[0]):
        cover[sq_lo[q]] += 1
        cover[sq_hi[q]] -= 1
    block_of = np.zeros(max(n, 1), dtype=np.int64)  # block of every variable
    n_blocks = 1
    joined = 0
    for i in range(n - 1):
        joined += cover[i]
        if joined <= 0:  # boundary i | i + 1 is a cut
            n_blocks += 1
        block_of[i + 1] = n_blocks - 1
    starts = np.empty(n_blocks, dtype=np.int64)
    ends = np.empty(n_blocks, dtype=np.int64)
    starts[0] = 0
    k = 0
    for i in range(1, n):
        if block_of[i] != block_of[i - 1]:
            ends[k] = i
            k += 1
            starts[k] = i
    ends[n_blocks - 1] = n
    key = np.empty(h_r.shape[0], dtype=np.int64)
    for p in range(h_r.shape[0]):
        key[p] = block_of[h_r[p]]
    h_order, h_ptr = _stable_order(key, n_blocks)
    key = np.empty(row_lo.shape[0], dtype=np.int64)
    for q in range(row_lo.shape[0]):
        key[q] = block_of[row_lo[q]]
    row_order, row_ptr = _stable_order(key, n_blocks)
    sq_order, _ = _stable_order(sq_hi, max(n, 1))
    key = np.empty(sq_hi.shape[0], dtype=np.int64)
    for q in range(sq_hi.shape[0]):
        key[q] = block_of[sq_hi[q] if sq_order.shape[0] == 0 else sq_hi[sq_order[q]]]
    _, sq_ptr = _stable_order(key, n_blocks)
    return starts, ends, h_order, h_ptr, row_order, row_ptr, sq_order, sq_ptr
