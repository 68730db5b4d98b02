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

__all__ = ["FLAG_NAMES", "track_runs"]

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
