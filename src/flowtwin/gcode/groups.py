"""Sums of per-move columns grouped by a small integer key (layer, feature, tool).

``np.unique(..., return_inverse=True)`` sorts the whole column (~50 ms per million moves)
and record fields are strided, so every numpy step copies them first. The keys span a
small range, so one compiled pass counts and sums straight from the strided columns
(compensated sums, so a one-group total agrees with ``math.fsum`` to rounding). Keys spread
too wide for bins fall back to ``np.unique``.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = ["compensated_add", "group_sums"]

#: Widest key range counted directly (bins beyond the number of rows).
_MAX_SPAN = 1 << 16


@njit(cache=True, nogil=True)
def _key_range(key: npt.NDArray[np.integer]) -> tuple[int, int]:
    lo = key[0]
    hi = key[0]
    for i in range(1, key.shape[0]):
        k = key[i]
        if k < lo:
            lo = k
        elif k > hi:
            hi = k
    return int(lo), int(hi)


@njit(cache=True, nogil=True)
def _count(key: npt.NDArray[np.integer], lo: int, counts: npt.NDArray[np.int64]) -> None:
    for i in range(key.shape[0]):
        counts[key[i] - lo] += 1


@njit(cache=True, inline="always")
def compensated_add(s: npt.NDArray[np.float64], c: npt.NDArray[np.float64], b: int,
                    v: float) -> None:
    """``s[b] += v`` with Neumaier's compensation accumulated in ``c[b]``; the sum is
    ``s[b] + c[b]`` (fold ``c`` in once, at the end)."""
    t = s[b] + v
    if abs(s[b]) >= abs(v):
        c[b] += (s[b] - t) + v
    else:
        c[b] += (v - t) + s[b]
    s[b] = t


@njit(cache=True, nogil=True)
def _sum(key: npt.NDArray[np.integer], lo: int, w: npt.NDArray[np.float64],
         out: npt.NDArray[np.float64]) -> None:
    """``out[k - lo] = Σ w[key == k]``, Neumaier-compensated."""
    comp = np.zeros(out.shape[0])
    for i in range(key.shape[0]):
        compensated_add(out, comp, key[i] - lo, w[i])
    for b in range(out.shape[0]):
        out[b] += comp[b]


def group_sums(key: npt.ArrayLike, *weights: npt.ArrayLike
               ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64],
                          list[npt.NDArray[np.float64]]]:
    """The distinct values of ``key``, how often each occurs and the sum of each weight
    column per value.

    Parameters
    ----------
    key : (n,) integer array
        Group of each row (any integer dtype and stride, e.g. a record field).
    *weights : (n,) float arrays
        Columns to sum per group (any stride).

    Returns
    -------
    keys : (g,) int64
        Distinct key values, ascending.
    counts : (g,) int64
        Rows per key.
    sums : list of (g,) float64
        One array per weight column.
    """
    k = np.asarray(key)
    if k.dtype.kind not in "iu":
        k = k.astype(np.int64)
    cols = [np.asarray(w, dtype=np.float64) for w in weights]
    if k.size == 0:
        empty = np.zeros(0, np.int64)
        return empty, empty.copy(), [np.zeros(0) for _ in cols]
    lo, hi = _key_range(k)
    span = hi - lo + 1
    if span <= k.size + _MAX_SPAN:
        counts = np.zeros(span, np.int64)
        _count(k, lo, counts)
        present = np.flatnonzero(counts)
        sums = []
        for w in cols:
            s = np.zeros(span)
            _sum(k, lo, w, s)
            sums.append(s[present])
        return present.astype(np.int64) + lo, counts[present], sums
    keys, inv, cnt = np.unique(k, return_inverse=True, return_counts=True)
    return (keys.astype(np.int64), cnt.astype(np.int64),
            [np.bincount(inv, weights=w, minlength=keys.size).astype(np.float64, copy=False)
             for w in cols])
