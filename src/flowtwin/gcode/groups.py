"""Sums of per-move columns grouped by a small integer key (layer, feature, tool).

``np.unique(..., return_inverse=True)`` sorts the whole column (~50 ms per million moves);
these keys span a small range, so counting sort (``np.bincount``) does the same in one
pass. Keys spread too wide for that fall back to ``np.unique``.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = ["group_sums"]

#: Widest key range counted directly (bins beyond the number of rows).
_MAX_SPAN = 1 << 16


def group_sums(key: npt.ArrayLike, *weights: npt.ArrayLike
               ) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64],
                          list[npt.NDArray[np.float64]]]:
    """The distinct values of ``key``, how often each occurs and the sum of each weight
    column per value.

    Parameters
    ----------
    key : (n,) integer array
        Group of each row (any integer dtype and stride).
    *weights : (n,) float arrays
        Columns to sum per group.

    Returns
    -------
    keys : (g,) int64
        Distinct key values, ascending.
    counts : (g,) int64
        Rows per key.
    sums : list of (g,) float64
        One array per weight column (sequential summation within a group).
    """
    k = np.asarray(key).astype(np.int64, copy=False)
    if k.size == 0:
        empty = np.zeros(0, np.int64)
        return empty, empty.copy(), [np.zeros(0) for _ in weights]
    lo = int(k.min())
    span = int(k.max()) - lo + 1
    if span <= k.size + _MAX_SPAN:
        idx = k - lo if lo else k
        counts = np.bincount(idx, minlength=span)
        present = np.flatnonzero(counts)
        if present.size == 1:  # one group (e.g. one tool): numpy's pairwise sum, more exact
            return (present.astype(np.int64) + lo, counts[present].astype(np.int64),
                    [np.array([np.sum(np.asarray(w, np.float64))]) for w in weights])
        sums = [np.bincount(idx, weights=np.asarray(w, np.float64),
                            minlength=span)[present].astype(np.float64, copy=False)
                for w in weights]
        return present.astype(np.int64) + lo, counts[present].astype(np.int64), sums
    keys, inv, cnt = np.unique(k, return_inverse=True, return_counts=True)
    return (keys.astype(np.int64), cnt.astype(np.int64),
            [np.bincount(inv, weights=np.asarray(w, np.float64),
                         minlength=keys.size).astype(np.float64, copy=False)
             for w in weights])
