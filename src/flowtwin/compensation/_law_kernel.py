"""Compiled parts of the smoothed advance law's window average (private; see
:func:`flowtwin.compensation.advance.smoothed_advance_term`).

``A(t) = K·r·v(t)`` is piecewise linear over segments (three per row: acceleration,
cruise, deceleration) of a run; ``F₁ = ∫A`` and ``F₂ = ∫F₁`` restart at every run.
:func:`accumulate_runs` gives ``F₁``, ``F₂`` at every segment's start,
:func:`last_at_or_before` and :func:`segment_at` the segment a query time falls in (within
its run) and where in it, and
:func:`f2_values` ``F₂`` there. The arithmetic is that of the array expressions they
replace, operation by operation in the same order (the same bits); the cube of the time
into the segment is taken by the caller with numpy's ``power`` (whose implementation
may differ from the C library's ``pow`` by an ulp on some CPUs).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = ["accumulate_runs", "f2_values", "last_at_or_before", "run_segments",
           "segment_at", "segment_integrals"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@njit(cache=True, nogil=True, error_model="numpy")
def run_segments(t0: FloatArray, ta: FloatArray, tc: FloatArray, td: FloatArray,
                 sv: FloatArray, cv: FloatArray, ev: FloatArray, g: FloatArray,
                 run_of_row: IntArray) -> tuple[FloatArray, FloatArray, FloatArray,
                                                FloatArray, npt.NDArray[np.bool_]]:
    """The three segments of every row (acceleration, cruise, deceleration), row by row:
    start, duration, ``A`` at the start (``g·v``) and slope (``g·Δv/duration``, 0 for a
    phase of no duration and for the cruise), and whether the segment starts a run (the
    first of the file's or of a row of another run), each ``(3m,)``."""
    m = t0.shape[0]
    starts = np.empty(3 * m)
    durs = np.empty(3 * m)
    a0 = np.empty(3 * m)
    slope = np.empty(3 * m)
    first = np.zeros(3 * m, dtype=np.bool_)
    for i in range(m):
        k = 3 * i
        starts[k] = t0[i]
        starts[k + 1] = t0[i] + ta[i]
        starts[k + 2] = t0[i] + ta[i] + tc[i]
        durs[k] = ta[i]
        durs[k + 1] = tc[i]
        durs[k + 2] = td[i]
        a0[k] = g[i] * sv[i]
        a0[k + 1] = g[i] * cv[i]
        a0[k + 2] = g[i] * cv[i]
        slope[k] = g[i] * (cv[i] - sv[i]) / ta[i] if ta[i] > 0 else 0.0
        slope[k + 1] = 0.0
        slope[k + 2] = g[i] * (ev[i] - cv[i]) / td[i] if td[i] > 0 else 0.0
        first[k] = i == 0 or run_of_row[i] != run_of_row[i - 1]
    return starts, durs, a0, slope, first


@njit(cache=True, nogil=True, error_model="numpy")
def segment_integrals(starts: FloatArray, durs: FloatArray, durs_cubed: FloatArray,
                      a0: FloatArray, slope: FloatArray) -> tuple[FloatArray, FloatArray,
                                                                  FloatArray]:
    """``∫A`` and ``∫∫A`` over every whole segment and its end: ``a0·T + ½·s·T²``,
    ``½·a0·T² + s·T³/6`` (``T³`` given: numpy's ``power``) and ``start + T``."""
    n = starts.shape[0]
    f1_len = np.empty(n)
    f2_len = np.empty(n)
    ends = np.empty(n)
    for k in range(n):
        d = durs[k]
        f1_len[k] = a0[k] * d + 0.5 * slope[k] * d * d
        f2_len[k] = 0.5 * a0[k] * (d * d) + slope[k] * durs_cubed[k] / 6.0
        ends[k] = starts[k] + d
    return f1_len, f2_len, ends


@njit(cache=True, nogil=True)
def accumulate_runs(starts: FloatArray, ends: FloatArray, f1_len: FloatArray,
                    f2_len: FloatArray, first: npt.NDArray[np.bool_], f1: FloatArray,
                    f2: FloatArray) -> None:
    """Running ``F₁``, ``F₂`` at segment starts, restarted where ``first`` (``first[0]``
    must be set); a gap between two segments of a run adds ``F₁·gap`` to ``F₂``.

    ``F₁`` is the cumulative sum of ``f1_len`` less its value at the run's first segment,
    ``F₂`` the cumulative sum of the increments ``F₁_(k−1)·(end − start)_(k−1) +
    f2_len_(k−1) + F₁_k·gap_k`` (0 at a run's first segment) less its value there:
    cumulative sums over the whole array, as ``numpy.cumsum`` adds them.
    """
    n = starts.shape[0]
    c1 = 0.0
    c2 = 0.0
    base1 = 0.0
    base2 = 0.0
    for k in range(n):
        c1 = f1_len[k] if k == 0 else c1 + f1_len[k]
        before = c1 - f1_len[k]
        if first[k]:
            base1 = before
        f1[k] = before - base1
    for k in range(n):
        if k == 0:
            inc = 0.0
        else:
            inc = f1[k - 1] * (ends[k - 1] - starts[k - 1]) + f2_len[k - 1]
        gap = 0.0 if first[k] else starts[k] - ends[k - 1]
        inc = inc + f1[k] * gap
        if first[k]:
            inc = 0.0
        c2 = inc if k == 0 else c2 + inc
        if first[k]:
            base2 = c2
        f2[k] = c2 - base2


@njit(cache=True, nogil=True)
def last_at_or_before(starts: FloatArray, t: FloatArray) -> IntArray:
    """Index of the last of ``starts`` at or before every ``t`` (−1: none), both sorted
    (``numpy.searchsorted(starts, t, side="right") − 1``, in one merged pass)."""
    out = np.empty(t.shape[0], dtype=np.int64)
    n = starts.shape[0]
    j = 0
    for i in range(t.shape[0]):
        while j < n and starts[j] <= t[i]:
            j += 1
        out[i] = j - 1
    return out


@njit(cache=True, nogil=True)
def segment_at(starts: FloatArray, durs: FloatArray, lo: IntArray, hi: IntArray,
               t: FloatArray, seg: IntArray) -> tuple[IntArray, FloatArray, FloatArray,
                                                      FloatArray]:
    """For every query time, from the last segment starting at or before it (``seg``, in
    place): that segment kept within ``lo .. hi`` (its run's segments), the time from its
    start ``u``, the part of it before the query (``u`` clipped to ``0 .. duration``) and
    the time after its end (``≥ 0``)."""
    q = t.shape[0]
    u = np.empty(q)
    inside = np.empty(q)
    after = np.empty(q)
    for i in range(q):
        k = seg[i]
        if k < lo[i]:
            k = lo[i]
        if k > hi[i]:
            k = hi[i]
        seg[i] = k
        ui = t[i] - starts[k]
        u[i] = ui
        x = ui if ui > 0.0 else 0.0
        d = durs[k]
        inside[i] = x if x < d else d
        a = ui - d
        after[i] = a if a > 0.0 else 0.0
    return seg, u, inside, after


@njit(cache=True, nogil=True)
def f2_values(seg: IntArray, u: FloatArray, inside: FloatArray, inside_cubed: FloatArray,
              after: FloatArray, f1: FloatArray, f2: FloatArray, a0: FloatArray,
              slope: FloatArray, f1_len: FloatArray) -> FloatArray:
    """``F₂`` at the query times (0 before the segment, ``u < 0``)."""
    q = seg.shape[0]
    out = np.empty(q)
    for i in range(q):
        k = seg[i]
        x = inside[i]
        val = (f2[k] + f1[k] * x + 0.5 * a0[k] * (x * x) + slope[k] * inside_cubed[i] / 6.0
               + (f1[k] + f1_len[k]) * after[i])
        out[i] = 0.0 if u[i] < 0.0 else val
    return out
