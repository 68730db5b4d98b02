"""Compiled kernels of firmware pressure advance (private; see :mod:`.advance`).

Klipper smoothing
-----------------
Klipper's extruder position is the advanced position ``P(x) = e(x) + K·v(x)`` (``K = 0`` on
moves without XY motion or with decreasing E) averaged by a triangular window of half
width ``h = smooth_time/2`` (Klipper docs, Kinematics.md / kin_extruder.c)::

    S(t) = ∫ P(x) (h − |t − x|) dx / h²,  x ∈ [t − h, t + h]

Differentiating under the integral::

    S'(t)   = (∫_t^{t+h} P dx − ∫_{t−h}^t P dx) / h²
    S''(t)  = (P(t+h) − 2 P(t) + P(t−h)) / h²

``P`` is quadratic on every planner phase (``e`` quadratic, ``v`` linear), so on every
piece of time where ``t − h``, ``t`` and ``t + h`` each stay inside one phase, ``S'`` is
a cubic whose coefficients are the second differences of ``P``, ``P'`` and ``P''`` divided
by ``h²``. The pieces are cut at every phase boundary ``b`` and at ``b ± h``. ``S'(t)``
and ``S(t)`` at each piece start are integrated exactly over the window, with ``P``
re-centred at ``t`` (``ξ = x − t``) so no large positions are subtracted.

Marlin Linear Advance 1.5 (marlinfw.org/docs/features/lin_advance.html)
-------------------------------------------------------------------------
An advance ``adv`` (mm) is tracked. On an LA block the extruder runs at a fixed speed
offset ``ρ = K·a_E`` (``a_E`` the block's E acceleration): before deceleration the advance
grows towards ``K·v_E,cruise``, during deceleration it shrinks towards ``K·v_E,end``, each
time stopping when the target is reached. On other blocks it is held.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = ["klipper_smooth", "marlin_eligible", "marlin_moves", "marlin_track",
           "merge_breakpoints"]


@njit(cache=True, nogil=True)
def merge_breakpoints(b: npt.NDArray[np.float64], h: float, lo: float, hi: float
                      ) -> npt.NDArray[np.float64]:
    """Sorted unique union of ``b``, ``b + h``, ``b − h``, ``lo`` and ``hi`` within ``[lo, hi]``.

    ``b`` must be sorted. O(len(b)).
    """
    n = b.shape[0]
    out = np.empty(3 * n + 2)
    k = 0
    out[k] = lo
    k += 1
    i0 = 0
    i1 = 0
    i2 = 0
    last = lo
    while True:
        c0 = b[i0] - h if i0 < n else np.inf
        c1 = b[i1] if i1 < n else np.inf
        c2 = b[i2] + h if i2 < n else np.inf
        if c0 <= c1 and c0 <= c2:
            v = c0
            i0 += 1
        elif c1 <= c2:
            v = c1
            i1 += 1
        else:
            v = c2
            i2 += 1
        if v == np.inf or v >= hi:
            break
        if v > last:
            out[k] = v
            k += 1
            last = v
    if hi > last:
        out[k] = hi
        k += 1
    return out[:k]


@njit(cache=True, nogil=True)
def marlin_eligible(de: npt.NDArray[np.float64], x: npt.NDArray[np.float64],
                    y: npt.NDArray[np.float64], z: npt.NDArray[np.float64], x0: float,
                    y0: float, z0: float, out: npt.NDArray[np.bool_]) -> None:
    """Marlin's LA eligibility per move: ``de > 0``, XYZ length ``D > 0`` and ``de/D <= 3``.

    ``x, y, z`` are the end positions (the start of move ``i`` is the end of ``i - 1``,
    of move 0 ``(x0, y0, z0)``); ``D = sqrt(dx² + dy² + dz²)`` summed left to right.
    """
    px = x0
    py = y0
    pz = z0
    for i in range(de.shape[0]):
        dx = x[i] - px
        dy = y[i] - py
        dz = z[i] - pz
        dist = np.sqrt(dx * dx + dy * dy + dz * dz)
        out[i] = de[i] > 0.0 and dist > 0.0 and de[i] / dist <= 3.0
        px = x[i]
        py = y[i]
        pz = z[i]


@njit(cache=True, nogil=True)
def _seg_of(bt0: npt.NDArray[np.float64], x: float, j: int) -> int:
    """Index of the segment containing ``x`` (right-continuous), starting from guess ``j``."""
    nb = bt0.shape[0]
    while j + 1 < nb and bt0[j + 1] <= x:
        j += 1
    while j > 0 and bt0[j] > x:
        j -= 1
    return j


@njit(cache=True, nogil=True)
def klipper_smooth(bt0: npt.NDArray[np.float64], bdt: npt.NDArray[np.float64],
                   bv0: npt.NDArray[np.float64], ba: npt.NDArray[np.float64],
                   be0: npt.NDArray[np.float64], bk: npt.NDArray[np.float64],
                   u: npt.NDArray[np.float64], reg_end: npt.NDArray[np.int64],
                   reg_h: npt.NDArray[np.float64], move_t0: npt.NDArray[np.float64],
                   move_t1: npt.NDArray[np.float64],
                   out_coef: npt.NDArray[np.float64], out_e0: npt.NDArray[np.float64],
                   out_move: npt.NDArray[np.int64], out_gap: npt.NDArray[np.bool_]) -> None:
    """Smoothed advanced speed (cubic per piece) and position at every piece start.

    Also the owner of each piece: the move whose ``[move_t0, move_t1)`` holds the piece's
    midpoint (``out_gap`` False), else the last move started before it (``out_gap`` True,
    ``-1`` before the first move).

    Base segment ``j`` covers ``[bt0[j], bt0[j] + bdt[j])`` with speed ``bv0 + ba τ``,
    position ``be0`` at its start and advance ``bk`` (s); the first and last base segments
    must be at rest (they are extended to ±infinity). Piece ``k`` is
    ``[u[k], u[k+1])``; pieces ``reg_end[r-1] <= k < reg_end[r]`` (``reg_end`` increasing,
    its last entry ``len(u) - 1``) have the window half width ``reg_h[r]`` (0: no smoothing
    and no advance).
    """
    nb = bt0.shape[0]
    jc = 0
    jm = 0
    jp = 0
    ja = 0
    jb = 0
    nm = move_t0.shape[0]
    owner = -1
    r = 0
    for k in range(u.shape[0] - 1):
        t = u[k]
        while k >= reg_end[r]:
            r += 1
        h = reg_h[r]
        # The segments holding t - h, t and t + h throughout the piece: looked up at the
        # piece's midpoint, because t ± h may round to the wrong side of a breakpoint b ∓ h.
        tm = 0.5 * (t + u[k + 1])
        while owner + 1 < nm and move_t0[owner + 1] <= tm:
            owner += 1
        out_move[k] = owner
        out_gap[k] = owner < 0 or tm >= move_t1[owner]
        jc = _seg_of(bt0, tm, jc)
        dc = t - bt0[jc]
        if h == 0.0:
            out_coef[k, 0] = bv0[jc] + ba[jc] * dc
            out_coef[k, 1] = ba[jc]
            out_coef[k, 2] = 0.0
            out_coef[k, 3] = 0.0
            out_e0[k] = be0[jc] + dc * (bv0[jc] + 0.5 * ba[jc] * dc)
            continue
        jm = _seg_of(bt0, tm - h, jm)
        jp = _seg_of(bt0, tm + h, jp)
        ja = _seg_of(bt0, t - h, ja)  # segments overlapping the window [t - h, t + h]
        jb = _seg_of(bt0, t + h, jb)
        kk = bk[jc]
        p1 = bv0[jc] + kk * ba[jc]
        pref = be0[jc] + kk * bv0[jc] + dc * (p1 + 0.5 * ba[jc] * dc)
        i_plus = 0.0
        w_plus = 0.0
        i_minus = 0.0
        w_minus = 0.0
        dp_val = 0.0
        dp_slope = -2.0 * (p1 + ba[jc] * dc)
        dp_curv = -2.0 * ba[jc]
        for j in range(min(ja, jm), max(jb, jp) + 1):
            d = t - bt0[j]
            kj = bk[j]
            q1 = bv0[j] + kj * ba[j]
            q2 = 0.5 * ba[j]
            r0 = (be0[j] - pref) + kj * bv0[j] + d * (q1 + q2 * d)
            r1 = q1 + 2.0 * q2 * d
            r2 = q2
            r1_3 = r1 / 3.0  # (divisions hoisted out of the two window sides)
            r2_3 = r2 / 3.0
            start = bt0[j] - t
            end = start + bdt[j]
            if j == 0:
                start = -h
            if j == nb - 1:
                end = h
            # minus side [-h, 0]
            xa = max(start, -h)
            xb = min(end, 0.0)
            if xb > xa:
                f = (xb * (r0 + xb * (0.5 * r1 + xb * r2_3))
                     - xa * (r0 + xa * (0.5 * r1 + xa * r2_3)))
                g = (xb * xb * (0.5 * r0 + xb * (r1_3 + 0.25 * xb * r2))
                     - xa * xa * (0.5 * r0 + xa * (r1_3 + 0.25 * xa * r2)))
                i_minus += f
                w_minus += h * f + g
            # plus side [0, h]
            xa = max(start, 0.0)
            xb = min(end, h)
            if xb > xa:
                f = (xb * (r0 + xb * (0.5 * r1 + xb * r2_3))
                     - xa * (r0 + xa * (0.5 * r1 + xa * r2_3)))
                g = (xb * xb * (0.5 * r0 + xb * (r1_3 + 0.25 * xb * r2))
                     - xa * xa * (0.5 * r0 + xa * (r1_3 + 0.25 * xa * r2)))
                i_plus += f
                w_plus += h * f - g
            if j == jp:
                dp_val += r0 + h * (r1 + h * r2)
                dp_slope += r1 + 2.0 * r2 * h
                dp_curv += 2.0 * r2
            if j == jm:
                dp_val += r0 - h * (r1 - h * r2)
                dp_slope += r1 - 2.0 * r2 * h
                dp_curv += 2.0 * r2
        inv_h2 = 1.0 / (h * h)
        out_coef[k, 0] = (i_plus - i_minus) * inv_h2
        if jm == jc and jp == jc:
            # t - h, t and t + h in one phase: the second difference of the quadratic P is
            # exactly h² P'' = h² a (dp_val would hold the rounding of the re-centring
            # instead of 0 on a cruise, and the integrator would take it for a ramp)
            out_coef[k, 1] = ba[jc]
        else:
            out_coef[k, 1] = dp_val * inv_h2
        out_coef[k, 2] = 0.5 * dp_slope * inv_h2
        out_coef[k, 3] = dp_curv * inv_h2 / 6.0
        out_e0[k] = pref + (w_plus + w_minus) * inv_h2


@njit(cache=True, nogil=True)
def marlin_track(t0: npt.NDArray[np.float64], dt: npt.NDArray[np.float64],
                 v0: npt.NDArray[np.float64], a: npt.NDArray[np.float64],
                 e0: npt.NDArray[np.float64], move: npt.NDArray[np.int64],
                 gap: npt.NDArray[np.bool_], phase: npt.NDArray[np.int8],
                 target_max: npt.NDArray[np.float64], target_end: npt.NDArray[np.float64],
                 rate: npt.NDArray[np.float64], o_t0: npt.NDArray[np.float64],
                 o_dt: npt.NDArray[np.float64], o_v0: npt.NDArray[np.float64],
                 o_a: npt.NDArray[np.float64], o_e0: npt.NDArray[np.float64],
                 o_src: npt.NDArray[np.int64], state: npt.NDArray[np.float64]) -> int:
    """Marlin LA 1.5 advance tracking; returns the number of output segments (≤ 2n).

    ``target_max``, ``target_end`` (mm) and ``rate`` (mm/s) per move; ``rate == 0`` marks
    blocks without advance. ``o_src`` gets the base segment each output piece came from.
    ``state[0]``: the advance (mm) before the first segment, replaced by the one after the
    last (a feed simulated in pieces carries it).
    """
    adv = state[0]
    k = 0
    for j in range(t0.shape[0]):
        m = move[j]
        direction = 0.0
        target = 0.0
        rho = 0.0
        if not gap[j] and m >= 0 and rate[m] > 0.0:
            rho = rate[m]
            if phase[j] == 2:
                target = target_end[m]
                if adv > target:
                    direction = -1.0
            else:
                target = target_max[m]
                if adv < target:
                    direction = 1.0
        if direction == 0.0:
            o_t0[k] = t0[j]
            o_dt[k] = dt[j]
            o_v0[k] = v0[j]
            o_a[k] = a[j]
            o_e0[k] = e0[j] + adv
            o_src[k] = j
            k += 1
            continue
        t_reach = abs(target - adv) / rho
        if t_reach >= dt[j]:
            o_t0[k] = t0[j]
            o_dt[k] = dt[j]
            o_v0[k] = v0[j] + direction * rho
            o_a[k] = a[j]
            o_e0[k] = e0[j] + adv
            o_src[k] = j
            k += 1
            adv += direction * rho * dt[j]
        else:
            o_t0[k] = t0[j]
            o_dt[k] = t_reach
            o_v0[k] = v0[j] + direction * rho
            o_a[k] = a[j]
            o_e0[k] = e0[j] + adv
            o_src[k] = j
            k += 1
            if dt[j] - t_reach > 0.0:
                o_t0[k] = t0[j] + t_reach
                o_dt[k] = dt[j] - t_reach
                o_v0[k] = v0[j] + a[j] * t_reach
                o_a[k] = a[j]
                o_e0[k] = e0[j] + t_reach * (v0[j] + 0.5 * a[j] * t_reach) + target
                o_src[k] = j
                k += 1
            adv = target
    state[0] = adv
    return k


@njit(cache=True, nogil=True)
def marlin_moves(move: npt.NDArray[np.int64], gap: npt.NDArray[np.bool_],
                 phase: npt.NDArray[np.int8], v0: npt.NDArray[np.float64],
                 a: npt.NDArray[np.float64], dt: npt.NDArray[np.float64], n: int,
                 v_cruise: npt.NDArray[np.float64], v_end: npt.NDArray[np.float64],
                 a_e: npt.NDArray[np.float64]) -> None:
    """Per-move E cruise speed, end speed and acceleration from the nominal feed's phases
    (``v_cruise``: the cruise speed, raised to the end of acceleration and the start of
    deceleration; ``v_end``: the end of deceleration, else ``v_cruise``; ``a_e``: the
    largest ``|a|`` of the two ramps). Outputs of length ``n``, filled here."""
    nb = move.shape[0]
    has_dec = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        v_cruise[i] = 0.0
        v_end[i] = 0.0
        a_e[i] = 0.0
    for j in range(nb):
        if not gap[j] and move[j] >= 0 and phase[j] == 1:
            v_cruise[move[j]] = v0[j]
    for j in range(nb):
        m = move[j]
        if gap[j] or m < 0:
            continue
        if phase[j] == 0:
            v_cruise[m] = max(v_cruise[m], v0[j] + a[j] * dt[j])
            a_e[m] = abs(a[j])
    for j in range(nb):
        m = move[j]
        if gap[j] or m < 0:
            continue
        if phase[j] == 2:
            v_cruise[m] = max(v_cruise[m], v0[j])
            v_end[m] = v0[j] + a[j] * dt[j]
            a_e[m] = max(a_e[m], abs(a[j]))
            has_dec[m] = True
    for i in range(n):
        if not has_dec[i]:
            v_end[i] = v_cruise[i]
