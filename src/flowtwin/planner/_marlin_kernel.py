"""Compiled core of the Marlin planner model (private; see :mod:`flowtwin.planner.marlin`).

Everything here works on flat float arrays, mm and s. The wrapper validates the inputs
and builds the per-move axis deltas, the table of firmware settings in force at each
move (``params[state[i]]``), the forced stops and the dwells.

The model follows Marlin 2.x ``Planner::_populate_block``, ``reverse_pass``,
``recalculate_trapezoids`` (Marlin/src/module/planner.cpp; read to understand, written
anew). With ``v²`` written ``v2``, for a block of length ``L`` and acceleration ``a``:

* nominal speed ``v_nom = F · min(1, min_i vmax_i / |F·d_i/L|)`` (M203 per axis);
* acceleration ``a = M204 P`` (XYZ and E), ``T`` (XYZ only) or ``R`` (E only), then
  ``a ≤ amax_i · L / |d_i|`` for every axis with motion (M201), except E-only blocks;
* the junction limit ``J2`` with the previous block (classic jerk or junction deviation);
* reverse pass ``v2_in[k] = min(J2[k], v2_in[k+1] + 2 a_k L_k, cap[k])`` where ``cap`` is
  the look-ahead of a buffer of ``B`` blocks (the exit of the block being executed is
  fixed with only ``B - 2`` blocks behind it, the last ending at the minimum planner
  speed): ``cap[k] = v2_min + Σ_{m=k}^{k+B-3} 2 a_m L_m``;
* forward pass ``v2_in[k] = min(v2_in[k], v2_in[k-1] + 2 a_{k-1} L_{k-1})``;
* one trapezoid per block: ``v2_peak = min(v2_nom, (2 a L + v2_in + v2_out) / 2)``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = [
    "N_PARAMS",
    "P_ACCEL_P",
    "P_ACCEL_R",
    "P_ACCEL_T",
    "P_AMAX",
    "P_JD",
    "P_JERK",
    "P_LA_K",
    "P_MIN_FEED",
    "P_MIN_SEG_T",
    "P_MIN_TRAVEL",
    "P_VMAX",
    "junction_classic_legacy",
    "junction_classic_reworked",
    "junction_deviation_sqr",
    "plan_kernel",
]

# Columns of the settings table ``params`` (one row per distinct firmware state).
P_VMAX = 0        # 4 columns X Y Z E: M203, mm/s
P_AMAX = 4        # 4 columns: M201, mm/s²
P_ACCEL_P = 8     # M204 P
P_ACCEL_R = 9     # M204 R
P_ACCEL_T = 10    # M204 T
P_JERK = 11       # 4 columns: M205 X Y Z E, mm/s
P_JD = 15         # M205 J, mm (ignored in classic-jerk mode)
P_MIN_FEED = 16   # M205 S, mm/s
P_MIN_TRAVEL = 17 # M205 T, mm/s
P_MIN_SEG_T = 18  # M205 B, s
P_LA_K = 19       # M900 K, s
N_PARAMS = 20

#: Below this length (mm) an axis delta counts as no motion; Marlin drops blocks with
#: fewer than MIN_STEPS_PER_SEGMENT steps, which needs steps/mm this model does not have.
_EPS_MM = 1e-9
#: cos θ above which JD treats the junction as a full reversal (Marlin: 0.999999).
_JD_REVERSAL_COS = 0.999999


@njit(cache=True, inline="always")
def _acos_neg_franklin(cos_theta: float) -> float:
    """``acos(-cos_theta)`` by the MinMax arcsine polynomial Marlin uses for JD.

    W. R. Franklin, "Arcsine and arccosine approximations" (short note): a degree-7
    polynomial in ``t = |c|`` approximating ``asin`` with max error ±0.033 rad; the
    result bottoms out at ~0.033 rad for a straight continuation, which Marlin relies on
    to avoid dividing by zero.
    """
    neg = -1.0 if cos_theta < 0.0 else 1.0
    t = neg * cos_theta
    asinx = 0.032843707 + t * (-1.451838349 + t * (29.66153956 + t * (
        -131.1123477 + t * (262.8130562 + t * (-242.7199627 + t * 84.31466202)))))
    return 0.5 * math.pi + neg * asinx


@njit(cache=True, nogil=True)
def junction_deviation_sqr(prev_unit: npt.NDArray[np.float64],
                           unit: npt.NDArray[np.float64], accel: float,
                           amax: npt.NDArray[np.float64], jd_mm: float, length_mm: float,
                           small_segments: bool, v2_min: float,
                           ju: npt.NDArray[np.float64]) -> float:
    """Junction-deviation speed limit squared (mm²/s²) between two unit vectors.

    Marlin's JD (Grbl's centripetal model, planner.cpp ``HAS_JUNCTION_DEVIATION``):
    with ``cos θ = -u_prev·u`` (θ the angle between the reversed previous direction and
    the new one) and ``sin(θ/2) = sqrt((1 - cos θ)/2)``,
    ``v2 = a_j · δ · sin(θ/2) / (1 - sin(θ/2))`` where ``a_j`` is the block acceleration
    limited by M201 along the unit vector ``u - u_prev``. A full reversal
    (``cos θ > 0.999999``) gives ``v2_min``. ``JD_HANDLE_SMALL_SEGMENTS``: a block shorter
    than 1 mm turning by more than 45° (cos θ < -0.7071) is also capped at
    ``L · a_j / φ``, ``φ ≈ acos(-cos θ)`` the turning angle (the speed on an arc of that
    chord). The caller still caps the result at both nominal speeds. ``ju`` is scratch
    space of shape ``(4,)``.
    """
    cos_theta = 0.0
    for ax in range(4):
        cos_theta -= prev_unit[ax] * unit[ax]
    if cos_theta > _JD_REVERSAL_COS:
        return v2_min
    mag = 0.0
    for ax in range(4):
        ju[ax] = unit[ax] - prev_unit[ax]
        mag += ju[ax] * ju[ax]
    ja = accel
    if mag > 0.0:                # collinear: no direction change, nothing to limit
        inv = 1.0 / math.sqrt(mag)
        for ax in range(4):
            c = abs(ju[ax] * inv)
            if c > 0.0 and ja * c > amax[ax]:
                ja = amax[ax] / c
    if cos_theta < -_JD_REVERSAL_COS:
        cos_theta = -_JD_REVERSAL_COS
    s = math.sqrt(0.5 * (1.0 - cos_theta))
    v2 = ja * jd_mm * s / (1.0 - s)
    if small_segments and length_mm < 1.0 and cos_theta < -0.7071067812:
        limit = length_mm * ja / _acos_neg_franklin(cos_theta)
        if limit < v2:
            v2 = limit
    return v2


@njit(cache=True, nogil=True)
def junction_classic_legacy(prev_speed: npt.NDArray[np.float64],
                            speed: npt.NDArray[np.float64], prev_nominal: float,
                            nominal: float, prev_safe: float, safe: float,
                            jerk: npt.NDArray[np.float64]) -> float:
    """Classic-jerk junction speed (mm/s), Marlin ≤ 2.1.2 / Prusa firmware form.

    The junction speed starts at the smaller nominal speed ``v_j``; the previous block's
    axis speeds are scaled to it (``v_exit = v_prev,i · v_j / v_nom,prev``) while the new
    block's stay at its own nominal (``v_entry = v_i``). Per axis the "jerk" is the
    difference when the axis keeps its direction, and ``max(|v_exit|, |v_entry|)`` when it
    reverses; ``v_j`` is scaled by ``min_i(jerk_max,i / jerk_i)``. If both blocks' *safe*
    speeds (the speed each could start from or stop at within the jerk limits) exceed
    0.99 ``v_j``, the junction takes the new block's safe speed instead.
    """
    vj = min(nominal, prev_nominal)
    scale = vj / prev_nominal
    factor = 1.0
    for ax in range(4):
        v_exit = prev_speed[ax] * scale
        v_entry = speed[ax]
        if v_exit > v_entry:
            if v_entry > 0.0 or v_exit < 0.0:
                j = v_exit - v_entry
            else:
                j = max(v_exit, -v_entry)
        else:
            if v_entry < 0.0 or v_exit > 0.0:
                j = v_entry - v_exit
            else:
                j = max(-v_exit, v_entry)
        if j > jerk[ax] and jerk[ax] / j < factor:
            factor = jerk[ax] / j
    vj *= factor
    threshold = 0.99 * vj
    if prev_safe > threshold and safe > threshold:
        vj = safe
    return vj


@njit(cache=True, nogil=True)
def junction_classic_reworked(prev_speed: npt.NDArray[np.float64],
                              speed: npt.NDArray[np.float64], prev_nominal: float,
                              nominal: float, jerk: npt.NDArray[np.float64]) -> float:
    """Classic-jerk junction speed (mm/s), Marlin bugfix-2.1.x after the 2023 rework.

    Both blocks' axis velocities are scaled to the shared junction speed
    ``v_j = min(v_nom,prev, v_nom)``; the jerk is the signed per-axis difference
    ``|v_i - v_prev,i|`` at that speed, and ``v_j`` is scaled by
    ``min_i(jerk_max,i / jerk_i)``.
    """
    factor = 1.0
    if nominal < prev_nominal:
        vj = nominal
        s = nominal / prev_nominal
        for ax in range(4):
            j = abs(speed[ax] - prev_speed[ax] * s)
            if j * factor > jerk[ax]:
                factor = jerk[ax] / j
    else:
        vj = prev_nominal
        s = prev_nominal / nominal
        for ax in range(4):
            j = abs(speed[ax] * s - prev_speed[ax])
            if j * factor > jerk[ax]:
                factor = jerk[ax] / j
    return vj * factor


@njit(cache=True, nogil=True)
def plan_kernel(moves: Any, start_xyz: npt.NDArray[np.float64],
                state: npt.NDArray[np.int32], params: npt.NDArray[np.float64],
                stop_before: npt.NDArray[np.bool_], dwell_before: npt.NDArray[np.float64],
                use_jd: bool, legacy_jerk: bool, jd_small_segments: bool,
                lin_advance: bool, v_min: float, buffer_blocks: int, slowdown_queued: int,
                phases: Any, axis_d: npt.NDArray[np.float64]) -> tuple[float, int]:
    """Plan all moves; fill ``phases`` and return ``(total time s, bad move or -1)``.

    Parameters
    ----------
    moves
        Move rows (:data:`~flowtwin.gcode.moves.MOVE_DTYPE`), ``(n,)``: end positions,
        E change (times ``flow`` for the E axis; as written for LIN_ADVANCE's e/D), feed
        (F/60 × M220, mm/s) and tool (a change drains the planner).
    start_xyz
        Position before the first move, mm, ``(3,)``.
    state
        Row of ``params`` in force for each move, ``(n,)``.
    params
        Firmware settings, ``(n_states, N_PARAMS)`` (see the ``P_*`` columns).
    stop_before
        ``stop_before[i]``: the planner drains (full stop) before move ``i``, ``(n + 1,)``.
    dwell_before
        Seconds of dwell before move ``i`` (``i = n``: after the last), ``(n + 1,)``.
    use_jd, legacy_jerk, jd_small_segments, lin_advance
        Firmware build options (junction deviation or classic jerk, its variant,
        ``JD_HANDLE_SMALL_SEGMENTS``, ``LIN_ADVANCE``).
    v_min
        Minimum planner speed, mm/s.
    buffer_blocks
        ``BLOCK_BUFFER_SIZE`` (≥ 3), or 0 for unlimited look-ahead.
    slowdown_queued
        Queued moves assumed by the ``SLOWDOWN`` rule (0 = off).
    phases
        Output rows (:data:`~flowtwin.planner.timeline.PHASE_DTYPE`), ``(n,)``.
    axis_d
        Motor distances of the three motion axes per move, ``(n, 3)``, for machines
        whose motors are not X, Y, Z (a delta's towers: Marlin applies M203, M201 and
        classic jerk to the towers); ``(0, 3)``: the motors are X, Y, Z. The move's
        length and its junction-deviation direction stay cartesian.

    Returns
    -------
    total, bad
        Total time including dwells (s); index of the first move with motion but no
        positive finite feed rate (nothing is planned then), else -1.
    """
    n = moves.shape[0]
    mx = moves.x
    my = moves.y
    mz = moves.z
    mde = moves.de
    mflow = moves.flow
    mfeed = moves.feed_mm_s
    mtool = moves.tool
    v2_min = v_min * v_min
    length = np.zeros(n)
    accel = np.zeros(n)
    nominal = np.zeros(n)
    jmax2 = np.zeros(n)
    d = np.zeros(4)
    speed = np.zeros(4)
    prev_speed = np.zeros(4)
    unit = np.zeros(4)
    prev_unit = np.zeros(4)
    scratch = np.zeros(4)
    cart = np.zeros(4)
    motors = axis_d.shape[0] == n and n > 0
    prev_nominal = 0.0
    prev_safe = 0.0
    have_prev = False
    pending_stop = False
    sqrt_half = math.sqrt(0.5)
    px = start_xyz[0]
    py = start_xyz[1]
    pz = start_xyz[2]
    for i in range(n):
        if stop_before[i] or (i > 0 and mtool[i] != mtool[i - 1]):
            pending_stop = True
        p = params[state[i]]
        dx = mx[i] - px
        dy = my[i] - py
        dz = mz[i] - pz
        px = mx[i]
        py = my[i]
        pz = mz[i]
        de_raw = mde[i]
        ex = de_raw * mflow[i]
        cart[0] = dx
        cart[1] = dy
        cart[2] = dz
        cart[3] = ex
        if motors:
            d[0] = axis_d[i, 0]
            d[1] = axis_d[i, 1]
            d[2] = axis_d[i, 2]
        else:
            d[0] = dx
            d[1] = dy
            d[2] = dz
        d[3] = ex
        lxyz = math.sqrt(dx * dx + dy * dy + dz * dz)
        has_e = abs(ex) > _EPS_MM
        if lxyz > _EPS_MM:
            big = lxyz
            xyz = True
        elif has_e:
            big = abs(ex)
            xyz = False
        else:
            continue                     # zero-length block: Marlin drops it
        fr = mfeed[i]
        if not (fr > 0.0 and fr < math.inf):
            return 0.0, i
        floor = p[P_MIN_FEED] if has_e else p[P_MIN_TRAVEL]
        if fr < floor:
            fr = floor
        inv_s = fr / big
        if slowdown_queued >= 2:
            seg_t = 1.0 / inv_s
            if seg_t < p[P_MIN_SEG_T]:
                inv_s = 1.0 / (seg_t + 2.0 * (p[P_MIN_SEG_T] - seg_t) / slowdown_queued)
        factor = 1.0
        for ax in range(4):
            cs = abs(d[ax]) * inv_s
            if cs > p[P_VMAX + ax]:
                f = p[P_VMAX + ax] / cs
                if f < factor:
                    factor = f
        v_nom = big * inv_s * factor
        for ax in range(4):
            speed[ax] = d[ax] * inv_s * factor
        # Acceleration: M204 R for E-only blocks, else P (with E) or T, LA cap, M201 caps.
        if not xyz:
            a = p[P_ACCEL_R]
        else:
            a = p[P_ACCEL_P] if has_e else p[P_ACCEL_T]
            k = p[P_LA_K]
            if lin_advance and k > 0.0 and de_raw > 0.0:
                e_d = de_raw / lxyz
                if e_d <= 3.0:
                    if use_jd:
                        e_jerk = math.sqrt(sqrt_half * p[P_JD] * p[P_AMAX + 3]
                                           / (1.0 - sqrt_half))
                    else:
                        e_jerk = p[P_JERK + 3]
                    cap = e_jerk / (k * e_d)
                    if cap < a:
                        a = cap
            for ax in range(4):
                da = abs(d[ax])
                if da > 0.0:
                    cap = p[P_AMAX + ax] * big / da
                    if cap < a:
                        a = cap
        length[i] = big
        accel[i] = a
        nominal[i] = v_nom
        # Junction limit with the previous block.
        first = pending_stop or not have_prev
        if use_jd:
            # Unit vector over XYZ, or over XYZE for blocks that move E (Marlin ≥ 2.0.9).
            norm = math.sqrt(lxyz * lxyz + ex * ex) if has_e else lxyz
            for ax in range(4):
                unit[ax] = cart[ax] / norm if (ax < 3 or has_e) else 0.0
            if first:
                v2 = v2_min
            else:
                v2 = junction_deviation_sqr(prev_unit, unit, a, p[P_AMAX:P_AMAX + 4],
                                            p[P_JD], big, jd_small_segments, v2_min,
                                            scratch)
                v2 = min(v2, v_nom * v_nom, prev_nominal * prev_nominal)
            for ax in range(4):
                prev_unit[ax] = unit[ax]
        else:
            jerk = p[P_JERK:P_JERK + 4]
            if legacy_jerk:
                safe = v_nom
                for ax in range(4):
                    cs = abs(speed[ax])
                    if cs > jerk[ax]:
                        s = v_nom * jerk[ax] / cs
                        if s < safe:
                            safe = s
                if first:
                    v2 = v2_min
                else:
                    vj = junction_classic_legacy(prev_speed, speed, prev_nominal, v_nom,
                                                 prev_safe, safe, jerk)
                    v2 = vj * vj
                prev_safe = safe
            else:
                if first:
                    v2 = v2_min
                else:
                    vj = junction_classic_reworked(prev_speed, speed, prev_nominal, v_nom,
                                                   jerk)
                    v2 = vj * vj
        if v2 < v2_min:
            v2 = v2_min
        jmax2[i] = v2
        for ax in range(4):
            prev_speed[ax] = speed[ax]
        prev_nominal = v_nom
        have_prev = True
        pending_stop = False

    # Compact the real blocks, then reverse and forward passes on squared speeds.
    idx = np.nonzero(length > 0.0)[0]
    m = idx.shape[0]
    two_al = np.empty(m)
    for k in range(m):
        two_al[k] = 2.0 * accel[idx[k]] * length[idx[k]]
    v2_in = np.empty(m + 1)
    v2_in[m] = v2_min
    window = buffer_blocks - 2 if buffer_blocks > 0 else 0
    prefix = np.zeros(m + 1)
    if window > 0:
        for k in range(m):
            prefix[k + 1] = prefix[k] + two_al[k]
    for k in range(m - 1, -1, -1):
        v2 = min(jmax2[idx[k]], v2_in[k + 1] + two_al[k])
        if window > 0:
            cap = v2_min + prefix[min(k + window, m)] - prefix[k]
            if cap < v2:
                v2 = cap
        v2_in[k] = v2
    for k in range(1, m):
        reach = v2_in[k - 1] + two_al[k - 1]
        if reach < v2_in[k]:
            v2_in[k] = reach

    # Trapezoids. A block never exceeds its nominal speed: when a (legacy classic-jerk)
    # junction is faster than the previous block's nominal, that block ends at its
    # nominal and the speed steps up at the junction.
    o_t = phases.t_start
    o_vi = phases.start_v
    o_vc = phases.cruise_v
    o_vo = phases.end_v
    o_a = phases.accel
    o_ta = phases.accel_t
    o_tc = phases.cruise_t
    o_td = phases.decel_t
    move_t = np.zeros(n)
    for k in range(m):
        i = idx[k]
        a = accel[i]
        big = length[i]
        vn2 = nominal[i] * nominal[i]
        vi2 = min(v2_in[k], vn2)
        vo2 = min(v2_in[k + 1], vn2)
        vc2 = min(vn2, 0.5 * (two_al[k] + vi2 + vo2))
        vc2 = max(vc2, vi2, vo2)
        vi = math.sqrt(vi2)
        vo = math.sqrt(vo2)
        vc = math.sqrt(vc2)
        ta = (vc - vi) / a
        td = (vc - vo) / a
        dc = big - 0.5 * (vc + vi) * ta - 0.5 * (vc + vo) * td
        tc = dc / vc if dc > 0.0 else 0.0
        o_vi[i] = vi
        o_vc[i] = vc
        o_vo[i] = vo
        o_a[i] = a
        o_ta[i] = ta
        o_tc[i] = tc
        o_td[i] = td
        move_t[i] = ta + tc + td
    t = 0.0
    for i in range(n):
        t += dwell_before[i]
        o_t[i] = t
        t += move_t[i]
    return t + float(dwell_before[n]), -1
