"""Compiled loops of the flow pacing (:func:`flowtwin.compensation.pace.pace_feeds`).

The same arithmetic, in the same order, as the pure-Python definitions they replace
(:func:`flowtwin.compensation.envelopes.staircase` for the staircases; the tests compare
the two to the bit): the envelopes' backward and forward passes over the pieces, the
largest cross-section within a window, the staircases of all the pieces to cut, and the
paced pieces laid out. Squares that the definitions take with ``**`` (the C library's
``pow``, which differs from ``x·x`` in the last bit now and then) come in precomputed.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = ["end_bounds", "lay_out_paced", "staircases", "start_bounds", "window_max"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


@njit(cache=True)
def window_max(a: FloatArray, length: FloatArray, nxt: BoolArray,
               window_mm: float) -> FloatArray:
    """Largest ``a`` of the pieces within ``window_mm`` of path before the end of each
    piece, inside its run (``nxt[i]``: piece ``i`` continues into ``i + 1``)."""
    out = a.copy()
    for i in range(a.shape[0]):
        if not nxt[i]:
            continue
        best = a[i]
        walked = length[i]
        j = i - 1
        while j >= 0 and walked < window_mm and nxt[j]:
            best = max(best, a[j])
            walked += length[j]
            j -= 1
        out[i] = best
    return out


@njit(cache=True)
def end_bounds(pr: BoolArray, nxt: BoolArray, anchor: FloatArray, allowed: BoolArray,
               g: FloatArray, length: FloatArray, a: FloatArray, k: FloatArray,
               cv: FloatArray, t_start: FloatArray, t_end: FloatArray, gap_lags: float,
               margin: float) -> tuple[FloatArray, int]:
    """The drop envelope's speed at the end of every piece (backward pass), and the
    junctions across a gap where the bound was carried in flow."""
    n = pr.shape[0]
    end_bound = np.full(n, np.inf)
    bound = np.inf
    next_start = -1  # first piece of the next run
    next_flow = np.inf  # its paced top flow, mm³/s
    gaps = 0
    for i in range(n - 1, -1, -1):
        if not pr[i]:
            bound = np.inf
            continue
        b = min(bound if nxt[i] else np.inf, anchor[i])
        if not nxt[i] and next_start >= 0 and gap_lags > 0 and allowed[i]:
            gap = t_start[next_start] - t_end[i]
            if gap < gap_lags * k[i] and math.isfinite(next_flow):
                carried = next_flow * math.exp(margin * max(gap, 0.0) / k[i]) / a[i]
                if carried < b and carried < cv[i]:
                    b = carried
                    gaps += 1
        end_bound[i] = b
        bound = b + g[i] * length[i] if math.isfinite(b) else np.inf
        if i == 0 or not pr[i - 1]:  # a run starts here
            next_start = i
            next_flow = a[i] * min(cv[i], bound)
    return end_bound, gaps


@njit(cache=True)
def start_bounds(pr: BoolArray, v0: FloatArray, acc: FloatArray, length: FloatArray,
                 cv: FloatArray) -> FloatArray:
    """The rise envelope's speed at the start of every piece (forward pass)."""
    n = pr.shape[0]
    start_bound = np.full(n, np.inf)
    carry = np.inf
    for i in range(n):
        if not pr[i]:
            carry = np.inf
            continue
        b = min(carry, v0[i])
        start_bound[i] = b
        if math.isfinite(b):
            end = math.sqrt(b * b + 2.0 * acc[i] * length[i])
            carry = end if end < cv[i] else np.inf
        else:
            carry = np.inf
    return start_bound


@njit(cache=True)
def _add_cut(cuts: FloatArray, n: int, value: float) -> int:
    """Add ``value`` to the first ``n`` cuts unless it is there; the new count."""
    for j in range(n):
        if cuts[j] == value:
            return n
    cuts[n] = value
    return n + 1


@njit(cache=True)
def _levels(v_from: float, floor: float, big: float, q: float) -> int:
    """Speed levels ``max(v_from, floor, 1e-9)·qᵏ`` below ``big``."""
    count = 0
    level = max(v_from, floor, 1e-9)
    while level < big:
        count += 1
        level *= q
    return count


@njit(cache=True)
def staircases(pieces: IntArray, length: FloatArray, cv: FloatArray, cv_sq: FloatArray,
               end_bound: FloatArray, g: FloatArray, start_bound: FloatArray,
               start_sq: FloatArray, acc: FloatArray, floor: FloatArray, e_grid: IntArray,
               step_ratio: float, min_piece_mm: float, same: float
               ) -> tuple[IntArray, IntArray, FloatArray, FloatArray, int]:
    """The staircase of every piece in ``pieces`` (``staircase``'s definition, with
    ``cv_sq``/``start_sq`` the pieces' ``cv**2`` and ``start_bound**2``), kept where a
    sub-piece is paced and every sub-piece gets E on the grid.

    Returns the kept pieces (ascending), their sub-piece counts, the sub-pieces' end
    distances and speeds (concatenated in that order) and the sub-pieces at the floor.
    """
    m = pieces.shape[0]
    # room for the cuts: the two ends, each envelope's levels and its top (per piece, and
    # for all of them)
    room = 0
    total_room = 0
    for p in range(m):
        i = pieces[p]
        big = cv[i] * (1.0 - same)
        r = (2 + _levels(end_bound[i], floor[i], big, step_ratio) + 1
             + _levels(start_bound[i], floor[i], big, step_ratio) + 1)
        room = max(room, r)
        total_room += r
    cuts = np.empty(room)
    ends = np.empty(room)
    speeds = np.empty(room)
    kept = np.empty(m, dtype=np.int64)
    counts = np.empty(m, dtype=np.int64)
    all_ends = np.empty(total_room)
    all_v = np.empty(total_room)
    n_kept = 0
    n_out = 0
    floored = 0
    for p in range(m):
        i = pieces[p]
        length_mm = length[i]
        v_plan = cv[i]
        end_v = end_bound[i]
        slope = g[i] if g[i] > 0 else np.inf
        start_v = start_bound[i]
        accel = acc[i]
        fl = floor[i]
        big = v_plan * (1.0 - same)
        nc = 0
        nc = _add_cut(cuts, nc, 0.0)
        nc = _add_cut(cuts, nc, length_mm)
        if math.isfinite(end_v) and end_v < big:
            level = max(end_v, fl, 1e-9)
            while level < big:
                d = (level - end_v) / slope
                if 0.0 < d < length_mm:
                    nc = _add_cut(cuts, nc, length_mm - d)
                level *= step_ratio
            d = (v_plan - end_v) / slope
            if 0.0 < d < length_mm:
                nc = _add_cut(cuts, nc, length_mm - d)
        if math.isfinite(start_v) and start_v < big:
            level = max(start_v, fl, 1e-9)
            while level < big:
                s = (level * level - start_sq[p]) / (2.0 * accel)
                if 0.0 < s < length_mm:
                    nc = _add_cut(cuts, nc, s)
                level *= step_ratio
            s = (cv_sq[p] - start_sq[p]) / (2.0 * accel)
            if 0.0 < s < length_mm:
                nc = _add_cut(cuts, nc, s)
        pts = np.sort(cuts[:nc])
        cnt = nc - 1
        for j in range(cnt):
            s0 = pts[j]
            s1 = pts[j + 1]
            v = v_plan
            if math.isfinite(end_v):
                v = min(v, end_v + slope * (length_mm - s1))
            if math.isfinite(start_v):
                v = min(v, math.sqrt(start_sq[p] + 2.0 * accel * s0))
            v = max(v, min(fl, v_plan))
            ends[j] = s1
            speeds[j] = v
        # merge short sub-pieces into the slower neighbour
        k = 0
        while cnt > 1 and k < cnt:
            start = ends[k - 1] if k > 0 else 0.0
            if ends[k] - start >= min_piece_mm:
                k += 1
                continue
            if k == 0:
                j = 1
            elif k == cnt - 1:
                j = k - 1
            else:
                j = k - 1 if speeds[k - 1] <= speeds[k + 1] else k + 1
            lo = min(j, k)
            hi = max(j, k)
            speeds[lo] = min(speeds[lo], speeds[hi])
            ends[lo] = ends[hi]
            for t in range(hi, cnt - 1):
                ends[t] = ends[t + 1]
                speeds[t] = speeds[t + 1]
            cnt -= 1
            k = max(lo - 1, 0) if lo == k else lo
        # neighbours at the same speed become one
        out = 0
        for j in range(cnt):
            e = ends[j]
            v = speeds[j]
            if out > 0 and abs(speeds[out - 1] - v) <= same * max(v, 1e-9):
                ends[out - 1] = e
            else:
                ends[out] = e
                speeds[out] = v
                out += 1
        cnt = out
        paced = False
        for j in range(cnt):
            if not speeds[j] >= v_plan * (1.0 - same):
                paced = True
                break
        if not paced:
            continue
        # every sub-piece must print (a share of 0 grid units would make it a travel)
        total = float(e_grid[i])
        prev = 0.0
        empty = False
        for j in range(cnt):
            share = np.rint(total * ends[j] / length_mm)
            if share - prev <= 0:
                empty = True
                break
            prev = share
        if empty:
            continue
        for j in range(cnt):
            if speeds[j] <= fl * (1.0 + same):
                floored += 1
            all_ends[n_out + j] = ends[j]
            all_v[n_out + j] = speeds[j]
        n_out += cnt
        kept[n_kept] = i
        counts[n_kept] = cnt
        n_kept += 1
    return (kept[:n_kept].copy(), counts[:n_kept].copy(), all_ends[:n_out].copy(),
            all_v[:n_out].copy(), floored)


@njit(cache=True)
def lay_out_paced(kept: IntArray, counts: IntArray, ends: FloatArray, speeds: FloatArray,
                  offsets: IntArray, length: FloatArray, start: FloatArray, seg: FloatArray,
                  xyz_old: FloatArray, e_old: IntArray, feed_old: FloatArray,
                  cv: FloatArray, speed_factor: FloatArray, same: float,
                  xyz: FloatArray, e: IntArray, feed: FloatArray) -> None:
    """Write the kept pieces' sub-pieces into ``xyz``, ``e`` and ``feed`` (rows from
    ``offsets``): positions along the piece, E shared in proportion to length on the grid
    (the piece's total kept exactly), and the paced sub-pieces' feeds (never above the
    speed; never above the piece's own feed)."""
    at = 0
    for p in range(kept.shape[0]):
        i = kept[p]
        cnt = counts[p]
        o = offsets[i]
        total = e_old[i]
        prev = 0
        for j in range(cnt):
            frac = ends[at + j] / length[i]
            if j == cnt - 1:
                frac = 1.0
            for c in range(3):
                xyz[o + j, c] = start[i, c] + frac * seg[i, c]
            cum = int(np.rint(total * frac)) if j < cnt - 1 else total
            e[o + j] = cum - prev
            prev = cum
            v = speeds[at + j]
            if v >= cv[i] * (1.0 - same):
                continue  # not paced: the line's (or the piece's own) feed
            f = math.floor(60e3 * v / speed_factor[i]) / 1e3  # never above v
            old = feed_old[i]
            feed[o + j] = min(f, old) if math.isfinite(old) else f
        for c in range(3):
            xyz[o + cnt - 1, c] = xyz_old[i, c]
        at += cnt
