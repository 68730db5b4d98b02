"""Compiled core of :func:`flowtwin.physics.melt_history.melt_temperature_history`
(private).

For every move the slices leaving the zone at its start, middle and end entered when the
cumulative fresh volume was ``𝒱 − V``; their entry times are read off the breakpoints of
``𝒱(t)`` by linear interpolation (``searchsorted`` with ``side="left"``, then the same
arithmetic as the array formulation, element by element, so the results are the same to
the bit). The queries grow with the move index, so one pointer walks the breakpoints once
(a query below the previous one, which plug flow never makes, falls back to a binary
search): O(moves + breakpoints) instead of three binary searches per move and a dozen
move-sized temporaries.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit, prange
from flowtwin.physics._melt_kernel import theta_scalar

__all__ = ["breakpoints", "mean_temperatures", "mean_temperatures_parallel",
           "mean_temperatures_span"]


@njit(cache=True, nogil=True)
def breakpoints(prior_t: npt.NDArray[np.float64], prior_v: npt.NDArray[np.float64],
                t0: npt.NDArray[np.float64], dur: npt.NDArray[np.float64],
                v_start: npt.NDArray[np.float64], v_end: npt.NDArray[np.float64],
                vol: npt.NDArray[np.float64]
                ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Breakpoints ``(t, 𝒱)`` of the cumulative fresh volume: the prior ones, then each
    feeding move's start and end."""
    n_feed = 0
    for i in range(vol.shape[0]):
        if vol[i] > 0.0:
            n_feed += 1
    p = prior_t.shape[0]
    bt = np.empty(p + 2 * n_feed)
    bv = np.empty(p + 2 * n_feed)
    bt[:p] = prior_t
    bv[:p] = prior_v
    j = p
    for i in range(vol.shape[0]):
        if vol[i] > 0.0:
            bt[j] = t0[i]
            bt[j + 1] = t0[i] + dur[i]
            bv[j] = v_start[i]
            bv[j + 1] = v_end[i]
            j += 2
    return bt, bv


@njit(cache=True, inline="always")
def _search_left(bv: npt.NDArray[np.float64], x: float, k: int, last: float) -> int:
    """First ``k`` with ``bv[k] >= x`` (``searchsorted(side="left")``), walking on from the
    previous answer ``k`` for the previous query ``last <= x``."""
    n = bv.shape[0]
    if not x >= last:  # not monotone: binary search
        lo, hi = 0, n
        while lo < hi:
            mid = (lo + hi) // 2
            if bv[mid] < x:
                lo = mid + 1
            else:
                hi = mid
        return lo
    while k < n and bv[k] < x:
        k += 1
    return k


@njit(cache=True, inline="always")
def _entry_time(bt: npt.NDArray[np.float64], bv: npt.NDArray[np.float64], v_in: float,
                k: int, fill: float) -> float:
    """Entry time of the slice at cumulative volume ``v_in`` (``k``: its left search index)."""
    n = bv.shape[0]
    if n == 0:
        return fill
    if v_in >= bv[0] and k < n and k > 0:
        kk = min(max(k, 1), max(n - 1, 1))
        v_a = bv[kk - 1]
        v_b = bv[kk]
        if v_b > v_a:
            frac = min(max((v_in - v_a) / (v_b - v_a), 0.0), 1.0)
            return bt[kk - 1] + frac * (bt[kk] - bt[kk - 1])
        return bt[kk]
    if v_in == bv[0]:
        return bt[0]
    return fill


@njit(cache=True, inline="always")
def _temperature(t: float, entry: float, wall: float, inlet_c: float, a: float,
                 r: float) -> float:
    residence = t - entry
    fo = max(residence, 0.0) * a / (r * r) if math.isfinite(residence) else math.inf
    return wall - (wall - inlet_c) * theta_scalar(fo)


@njit(cache=True, nogil=True)
def mean_temperatures_span(t0: npt.NDArray[np.float64], dur: npt.NDArray[np.float64],
                           v_start: npt.NDArray[np.float64], v_end: npt.NDArray[np.float64],
                           wall: npt.NDArray[np.float64], bt: npt.NDArray[np.float64],
                           bv: npt.NDArray[np.float64], zone: float, fill: float,
                           inlet_c: float, a: float, r: float, out: npt.NDArray[np.float64],
                           i0: int, i1: int) -> None:
    """``out[i]`` for the moves ``i0 ≤ i < i1``: Simpson mean of the melt temperature over
    move ``i`` (start, middle, end), °C.

    Each move's value depends on its own inputs and the breakpoints only (the searches
    find the same index from any starting point), so spans give the numbers of one pass.
    """
    k_s = k_m = k_e = 0
    # the first queries of a span after the first are binary searches (from +inf)
    last_s = last_m = last_e = -math.inf if i0 == 0 else math.inf
    for i in range(i0, i1):
        w = wall[i]
        vs = v_start[i] - zone
        vm = 0.5 * (v_start[i] + v_end[i]) - zone
        ve = v_end[i] - zone
        k_s = _search_left(bv, vs, k_s, last_s)
        k_m = _search_left(bv, vm, k_m, last_m)
        k_e = _search_left(bv, ve, k_e, last_e)
        last_s, last_m, last_e = vs, vm, ve
        t_s = _temperature(t0[i], _entry_time(bt, bv, vs, k_s, fill), w, inlet_c, a, r)
        t_m = _temperature(t0[i] + 0.5 * dur[i], _entry_time(bt, bv, vm, k_m, fill), w,
                           inlet_c, a, r)
        t_e = _temperature(t0[i] + dur[i], _entry_time(bt, bv, ve, k_e, fill), w, inlet_c,
                           a, r)
        out[i] = (t_s + 4.0 * t_m + t_e) / 6.0


@njit(cache=True, nogil=True)
def mean_temperatures(t0: npt.NDArray[np.float64], dur: npt.NDArray[np.float64],
                      v_start: npt.NDArray[np.float64], v_end: npt.NDArray[np.float64],
                      wall: npt.NDArray[np.float64], bt: npt.NDArray[np.float64],
                      bv: npt.NDArray[np.float64], zone: float, fill: float, inlet_c: float,
                      a: float, r: float, out: npt.NDArray[np.float64]) -> None:
    """``out[i]``: Simpson mean of the melt temperature over move ``i`` (start, middle,
    end), °C; every move in one pass (:func:`mean_temperatures_span`)."""
    mean_temperatures_span(t0, dur, v_start, v_end, wall, bt, bv, zone, fill, inlet_c, a, r,
                           out, 0, t0.shape[0])


@njit(cache=True, parallel=True)
def mean_temperatures_parallel(t0: npt.NDArray[np.float64], dur: npt.NDArray[np.float64],
                               v_start: npt.NDArray[np.float64],
                               v_end: npt.NDArray[np.float64], wall: npt.NDArray[np.float64],
                               bt: npt.NDArray[np.float64], bv: npt.NDArray[np.float64],
                               zone: float, fill: float, inlet_c: float, a: float, r: float,
                               out: npt.NDArray[np.float64], spans: int) -> None:
    """:func:`mean_temperatures` in ``spans`` equal spans of moves, on numba's threads
    (the same numbers)."""
    n = t0.shape[0]
    for j in prange(spans):
        mean_temperatures_span(t0, dur, v_start, v_end, wall, bt, bv, zone, fill, inlet_c, a,
                               r, out, j * n // spans, (j + 1) * n // spans)
