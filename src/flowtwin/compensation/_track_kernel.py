"""Compiled kernel: follow an E target piece by piece within the extruder's limits.

For one run of printing pieces ``j = 0 … m−1`` (path lengths ``L_j``) the cumulative E at
the end of every piece should reach the target ``T_j``, and must end exactly at the run's
total ``E_end``. Each piece's ratio ``c_j = ΔE_j / L_j`` must lie in
``[c_min,j, c_max,j]`` (the *box*), and a ratio step at the junction before piece ``j``
should not exceed ``Δc_j`` (``|c_j − c_(j−1)| ≤ Δc_j``, the firmware's jump limit at the
junction speed).

Two passes. **Backward**, an envelope of ratios from which every later piece can still be
reached within the jump limits: ``env_j = box_j ∩ (env_(j+1) ± Δc_(j+1))``, where *anchor*
pieces (long pieces whose ratio matters most) start from a narrow band around their target
ratio instead of their box. **Forward**, each piece takes the ratio closest to its target
inside, in order of priority:

1. the box, intersected with what keeps the rest of the run able to end at ``E_end``::

       lo_j = max(E_(j−1) + c_min,j·L_j, E_end − Σ_(k>j) c_max,k·L_k)
       hi_j = min(E_(j−1) + c_max,j·L_j, E_end − Σ_(k>j) c_min,k·L_k)

2. the jump limit from the previous piece,
3. the envelope.

A lower priority is dropped when it conflicts with a higher one (and counted). The last
piece ends exactly at ``E_end``.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = ["FLAG_NAMES", "piece_bounds", "run_pieces", "track_runs"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Meaning of the per-piece flags.
FLAG_NAMES = ("on_target", "ratio_bounds", "jump_bounds", "jump_exceeded", "forced_end")


@njit(cache=True)
def _clip(x: float, lo: float, hi: float) -> float:
    return min(max(x, lo), hi)


@njit(cache=True)
def track_runs(length: npt.NDArray[np.float64], target: npt.NDArray[np.float64],
               c_min: npt.NDArray[np.float64], c_max: npt.NDArray[np.float64],
               env_lo0: npt.NDArray[np.float64], env_hi0: npt.NDArray[np.float64],
               c_prev0: npt.NDArray[np.float64], dc_max: npt.NDArray[np.float64],
               run_start: npt.NDArray[np.int64], run_total: npt.NDArray[np.float64],
               end_lo: npt.NDArray[np.float64], end_hi: npt.NDArray[np.float64],
               out: npt.NDArray[np.float64], flags: npt.NDArray[np.int8]) -> None:
    """Fill ``out`` with the cumulative E (from the run start) at every piece's end.

    Parameters
    ----------
    length
        Piece path lengths, mm, ``(n,)`` (> 0).
    target
        Wanted cumulative E at each piece's end, from its run's start, ``(n,)``.
    c_min, c_max
        Ratio box per piece, ``(n,)``.
    env_lo0, env_hi0
        Starting envelope per piece (the box, or a band around the target ratio for
        anchors), ``(n,)``.
    c_prev0
        Ratio of the move before each run's first piece, ``(n,)`` (read at run starts).
    dc_max
        Largest ratio step at the junction before each piece, ``(n,)`` (``inf``: free).
    run_start
        Index of the first piece of each run, ``(r + 1,)`` with ``run_start[r] = n``.
    run_total
        Exact E of each run, ``(r,)``.
    end_lo, end_hi
        Bounds of the last piece's ratio from the junction after the run, ``(r,)``.
    out
        Output cumulative E, ``(n,)``.
    flags
        Output per piece, an index into :data:`FLAG_NAMES`.
    """
    n_runs = run_total.shape[0]
    for r in range(n_runs):
        j0 = run_start[r]
        j1 = run_start[r + 1]
        m = j1 - j0
        suf_min = np.zeros(m + 1)
        suf_max = np.zeros(m + 1)
        env_lo = np.empty(m)
        env_hi = np.empty(m)
        for k in range(m - 1, -1, -1):
            j = j0 + k
            lo_c = c_min[j]
            hi_c = c_max[j]
            if k == m - 1:
                lo_c = max(lo_c, end_lo[r])
                hi_c = min(hi_c, end_hi[r])
                if lo_c > hi_c:
                    lo_c = hi_c = 0.5 * (lo_c + hi_c)
            suf_min[k] = suf_min[k + 1] + lo_c * length[j]
            suf_max[k] = suf_max[k + 1] + hi_c * length[j]
            elo = max(env_lo0[j], lo_c)
            ehi = min(env_hi0[j], hi_c)
            if k < m - 1:
                d = dc_max[j + 1]
                elo = max(elo, env_lo[k + 1] - d)
                ehi = min(ehi, env_hi[k + 1] + d)
            if elo > ehi:  # unreachable envelope: fall back to the box
                elo = lo_c
                ehi = hi_c
            env_lo[k] = elo
            env_hi[k] = ehi
        total = run_total[r]
        pos = 0.0
        c_prev = c_prev0[j0]
        for k in range(m):
            j = j0 + k
            L = length[j]
            if k == m - 1:
                out[j] = total
                c = (total - pos) / L
                bad = c < c_min[j] - 1e-9 * abs(c_min[j]) or c > c_max[j] * (1.0 + 1e-9)
                jump = abs(c - c_prev) > dc_max[j] * (1.0 + 1e-9)
                flags[j] = 4 if bad else (3 if jump else 0)
                pos = total
                c_prev = c
                continue
            # 1. box and feasibility of the run's end
            b_lo = max(c_min[j], (total - suf_max[k + 1] - pos) / L)
            b_hi = min(c_max[j], (total - suf_min[k + 1] - pos) / L)
            if b_lo > b_hi:
                b_lo = b_hi = 0.5 * (b_lo + b_hi)
            want = (target[j] - pos) / L
            c = _clip(want, b_lo, b_hi)
            flag = 0 if c == want else 1
            # 2. jump limit
            d = dc_max[j]
            j_lo = c_prev - d
            j_hi = c_prev + d
            if j_hi < b_lo or j_lo > b_hi:
                c = b_lo if j_hi < b_lo else b_hi
                flag = 3
            else:
                lo = max(b_lo, j_lo)
                hi = min(b_hi, j_hi)
                # 3. envelope
                e_lo = max(lo, env_lo[k])
                e_hi = min(hi, env_hi[k])
                if e_lo <= e_hi:
                    lo = e_lo
                    hi = e_hi
                y = _clip(c, lo, hi)
                if y != c:
                    flag = 2
                c = y
            pos += c * L
            out[j] = pos
            flags[j] = flag
            c_prev = c


@njit(cache=True, inline="always", error_model="numpy")
def _maximum(a: float, b: float) -> float:
    """``numpy.maximum`` of two floats as numpy gives it here: a NaN wins, ``b`` on a tie
    (so ``maximum(0.0, −0.0)`` is ``−0.0``)."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a > b else b


@njit(cache=True, inline="always", error_model="numpy")
def _minimum(a: float, b: float) -> float:
    """``numpy.minimum`` likewise: a NaN wins, ``b`` on a tie."""
    if a != a:
        return a
    if b != b:
        return b
    return a if a < b else b


@njit(cache=True, error_model="numpy")
def piece_bounds(rate: npt.NDArray[np.float64], row: npt.NDArray[np.int64],
                 v_start: npt.NDArray[np.float64], cruise: npt.NDArray[np.float64],
                 accel: npt.NDArray[np.float64], pull: npt.NDArray[np.bool_],
                 target: npt.NDArray[np.float64], length: npt.NDArray[np.float64],
                 duration: npt.NDArray[np.float64], run_first: npt.NDArray[np.bool_],
                 scalars: npt.NDArray[np.float64], switches: npt.NDArray[np.bool_],
                 out: npt.NDArray[np.float64]) -> None:
    """Every run piece's ratio box, jump limit and starting envelope (the law's, see
    :func:`flowtwin.compensation.advance.follow_law`), in ``out`` ``(5, p)``: ``c_min``,
    ``c_max``, the jump limit ``Δc`` at the junction before it (from the previous piece:
    the run's own first junction is set by the caller), the envelope's low and high end.

    ``rate``, ``row``, ``v_start``, ``cruise``, ``accel``: every piece's intended ratio,
    row, start speed and its row's cruise speed and acceleration; ``pull``: it may pull
    back; ``target``, ``length``, ``duration``: its cumulative target, path, time;
    ``run_first``: it starts a run. ``scalars``: ``min_flow_fraction``, ``retract_ratio``,
    the caps ``margin·max_ratio·grid``, ``margin·max_e_speed·grid``,
    ``margin·max_e_accel·grid``, ``margin·jump·grid``, the anchor's ``smooth_time_s`` and
    ``anchor_band``; ``switches``: pieces may pull, each of the three caps applies,
    anchors apply. The arithmetic is the array expressions', operation by operation.
    """
    min_flow, retract, cap_ratio, cap_speed, cap_accel, jump_grid, anchor_s, band_k = (
        scalars[0], scalars[1], scalars[2], scalars[3], scalars[4], scalars[5], scalars[6],
        scalars[7])
    pulls, has_ratio, has_speed, has_accel, anchors = (
        switches[0], switches[1], switches[2], switches[3], switches[4])
    inf = np.inf
    for i in range(rate.shape[0]):
        r = rate[i]
        c_min = min_flow * r
        if pulls and pull[i]:
            c_min = -retract * r
        c_cap = inf
        if has_ratio:
            c_cap = _minimum(c_cap, cap_ratio)
        if has_speed:
            c_cap = _minimum(c_cap, cap_speed / cruise[i] if cruise[i] > 0 else inf)
        if has_accel:
            c_cap = _minimum(c_cap, cap_accel / accel[i] if accel[i] > 0 else inf)
        c_max = _maximum(c_cap, r)
        prev_rate = rate[i - 1] if i > 0 else 0.0
        step = 0.0 if i > 0 and row[i] == row[i - 1] else abs(r - prev_rate)
        v = v_start[i]
        out[2, i] = _maximum(jump_grid, step * v) / v if v > 1e-9 else inf
        prev_target = 0.0 if i == 0 or run_first[i] else target[i - 1]
        c_star = (target[i] - prev_target) / length[i]
        band = band_k * abs(c_star)
        anchor = anchors and duration[i] >= anchor_s
        out[0, i] = c_min
        out[1, i] = c_max
        out[3, i] = c_star - band if anchor else c_min
        out[4, i] = c_star + band if anchor else c_max


@njit(cache=True)
def run_pieces(piece_run: IntArray, row: IntArray, s0: FloatArray, s1: FloatArray,
               rate: FloatArray, adv: FloatArray, row_run: IntArray, run_e: FloatArray,
               n_runs: int):  # type: ignore[no-untyped-def]
    """The pieces of the runs and every piece's target, in one pass.

    Parameters
    ----------
    piece_run
        Run of every piece, −1 outside the runs, ``(p,)`` (pieces of a run consecutive).
    row, s0, s1
        Row and path positions of every piece, ``(p,)``.
    rate
        Law's E per mm of every row, ``(n_rows,)``.
    adv
        Advance term of every piece, ``(p,)``.
    row_run, run_e
        Run of every eligible row and its exact E, in row order, ``(r,)``.
    n_runs
        Runs.

    Returns
    -------
    tuple
        ``sel`` (the run pieces), their rows and lengths, ``first_flag`` (a run's first
        piece), ``run_first``, ``run_last``, ``run_id``, the targets (cumulative E⁰
        within the run, ``E⁰ = rate·length``, plus the advance term; the run's exact
        E⁰ total at its last piece) and every run's exact E total: as the array
        expressions give them (sums in numpy's ``cumsum``/``bincount`` order).
    """
    n_p = piece_run.shape[0]
    m = 0
    for i in range(n_p):
        if piece_run[i] >= 0:
            m += 1
    sel = np.empty(m, dtype=np.int64)
    pr = np.empty(m, dtype=np.int64)
    length = np.empty(m)
    first_flag = np.empty(m, dtype=np.bool_)
    run_id = np.empty(m, dtype=np.int64)
    target = np.empty(m)
    k = 0
    n_first = 0
    for i in range(n_p):
        if piece_run[i] >= 0:
            sel[k] = i
            pr[k] = row[i]
            length[k] = s1[i] - s0[i]
            first = k == 0 or piece_run[i] != piece_run[sel[k - 1]]
            first_flag[k] = first
            if first:
                n_first += 1
            run_id[k] = n_first - 1
            k += 1
    run_first = np.empty(n_first, dtype=np.int64)
    run_last = np.empty(n_first, dtype=np.int64)
    j = 0
    for k in range(m):
        if first_flag[k]:
            run_first[j] = k
            if j > 0:
                run_last[j - 1] = k - 1
            j += 1
    if n_first > 0:
        run_last[n_first - 1] = m - 1
    cum = 0.0
    base = 0.0
    for k in range(m):
        e0 = rate[pr[k]] * length[k]
        cum = e0 if k == 0 else cum + e0
        if first_flag[k]:
            base = cum - e0
        rel = cum - base
        last = k == m - 1 or first_flag[k + 1]
        target[k] = rel if last else rel + adv[sel[k]]
    size = n_runs
    r0 = row_run[0] if row_run.shape[0] else 0
    for i in range(row_run.shape[0]):
        size = max(size, row_run[i] - r0 + 1)
    run_total = np.zeros(size)
    for i in range(row_run.shape[0]):
        run_total[row_run[i] - r0] += run_e[i]
    return sel, pr, length, first_flag, run_first, run_last, run_id, target, run_total
