"""Compiled kernel of the Klipper planner: look-ahead queue, junctions and print time.

This is Klipper's ``toolhead.py`` algorithm (``Move``, ``LookAheadQueue``, the print-time
bookkeeping of ``ToolHead``) re-expressed over flat arrays; the per-move limits have been
applied beforehand (:mod:`flowtwin.planner.klipper`). All velocities are tracked squared
(``_v2``, mm²/s²), as Klipper does.

Junction (move ``k`` after ``p``, both with XYZ motion), with θ the corner's interior
angle (``cos θ = −û_p·û_k``: 180° straight on, 90° a square corner) and
``δ = scv²(√2 − 1)/a_max`` the junction deviation in force when each move was queued::

    R            = sin(θ/2) / (1 − sin(θ/2))                 (circle radius / δ)
    v²_jd        = R · δ · a                                 (for both moves' δ and a)
    v²_centrip   = Δv² · tan(θ/2) / 4,  Δv² = 2·d·a          (circle meets mid-move)
    v²_extruder  = (icv / |r_E,k − r_E,p|)²                  (E ratio jump)
    max_start_v2 = min(all of the above, both cruise v², v²_start,p + Δv²_p)

The backward pass (``flush``) limits every junction to what can be reached from a stop
after the last queued move, once with the real accelerations (``Δv² = 2·d·a``) and once
with the "smoothed" ones (``2·d·a·(1 − minimum_cruise_ratio)``) whose mid-move peak caps
the cruise speed. Each move is then a trapezoid: ``accel_d = (v²_c − v²_s)/(2a)``,
``decel_d = (v²_c − v²_e)/(2a)``, times = distance / mean speed.

Print time: a flush after a stop restarts at ``min_restart + kin_flush_delay``; a
step-generation flush (tool change, motors off, pressure-advance smoothing change) sets
``min_restart`` to the end of the generated steps (last move end + kin_flush_delay) so
the next motion starts ``2·kin_flush_delay`` after the stop.
"""

from __future__ import annotations

import numpy as np

from flowtwin._jit import njit

__all__ = [
    "EX_ACCEL",
    "EX_DIST",
    "EX_ICV",
    "EX_RATIO",
    "EX_TINY",
    "EX_VEL",
    "OP_DWELL",
    "OP_HOME",
    "OP_LAST_MOVE_TIME",
    "OP_SET_KFD",
    "OP_SG_FLUSH",
    "OP_WAIT",
    "SEG_ACCEL",
    "SEG_ACCEL_TO_DECEL",
    "SEG_EXT",
    "SEG_JD",
    "SEG_VEL",
    "move_limits",
    "move_starts",
    "run_toolhead",
]

OP_WAIT = 0            # M400 / marker: _flush_lookahead()
OP_DWELL = 1           # G4: dwell(val)
OP_SG_FLUSH = 2        # flush_step_generation()
OP_SET_KFD = 3         # kin_flush_delay = val
OP_HOME = 4            # G28: stop; homing time not modelled, restart state cleared
OP_LAST_MOVE_TIME = 5  # get_last_move_time()

LOOKAHEAD_FLUSH_TIME = 0.250
BUFFER_TIME_HIGH = 2.0
NO_TIME = -1.0e300

# indices of the scalar state vector
_T, _MIN_RESTART, _STEP_GEN, _KFD, _NEED_PRIME, _JFLUSH, _HEAD, _TAIL = range(8)


@njit(cache=True, nogil=True)
def _set_junction(m, start_v2, cruise_v2, end_v2, move_d, accel, out_v, out_t):  # type: ignore[no-untyped-def]
    half_inv_accel = 0.5 / accel[m]
    accel_d = (cruise_v2 - start_v2) * half_inv_accel
    decel_d = (cruise_v2 - end_v2) * half_inv_accel
    cruise_d = move_d[m] - accel_d - decel_d
    start_v = np.sqrt(start_v2)
    cruise_v = np.sqrt(cruise_v2)
    end_v = np.sqrt(end_v2)
    out_v[m, 0] = start_v
    out_v[m, 1] = cruise_v
    out_v[m, 2] = end_v
    out_t[m, 0] = accel_d / ((start_v + cruise_v) * 0.5)
    out_t[m, 1] = cruise_d / cruise_v
    out_t[m, 2] = decel_d / ((end_v + cruise_v) * 0.5)


@njit(cache=True, nogil=True)
def _flush(lazy, st, qbuf, move_d, accel, delta_v2, smooth_delta_v2, max_cruise_v2,  # type: ignore[no-untyped-def]
           max_start_v2, max_smoothed_v2, out_v, out_t, dl_m, dl_s, dl_e):
    """Klipper ``LookAheadQueue.flush``; returns how many queued moves are final."""
    st[_JFLUSH] = LOOKAHEAD_FLUSH_TIME
    head = int(st[_HEAD])
    qlen = int(st[_TAIL]) - head
    update_flush_count = lazy
    flush_count = qlen
    nd = 0
    next_end_v2 = 0.0
    next_smoothed_v2 = 0.0
    peak_cruise_v2 = 0.0
    for i in range(qlen - 1, -1, -1):
        m = qbuf[head + i]
        reachable_start_v2 = next_end_v2 + delta_v2[m]
        start_v2 = min(max_start_v2[m], reachable_start_v2)
        reachable_smoothed_v2 = next_smoothed_v2 + smooth_delta_v2[m]
        smoothed_v2 = min(max_smoothed_v2[m], reachable_smoothed_v2)
        if smoothed_v2 < reachable_smoothed_v2:
            # this move can accelerate
            if smoothed_v2 + smooth_delta_v2[m] > next_smoothed_v2 or nd > 0:
                # it can decelerate, or it is a full accel move after a full decel move
                if update_flush_count and peak_cruise_v2 != 0.0:
                    flush_count = i
                    update_flush_count = False
                peak_cruise_v2 = min(max_cruise_v2[m],
                                     (smoothed_v2 + reachable_smoothed_v2) * 0.5)
                if nd > 0:
                    if not update_flush_count and i < flush_count:
                        mc_v2 = peak_cruise_v2
                        for d in range(nd - 1, -1, -1):
                            ms_v2 = dl_s[d]
                            me_v2 = dl_e[d]
                            mc_v2 = min(mc_v2, ms_v2)
                            _set_junction(dl_m[d], min(ms_v2, mc_v2), mc_v2, min(me_v2, mc_v2),
                                          move_d, accel, out_v, out_t)
                    nd = 0
            if not update_flush_count and i < flush_count:
                cruise_v2 = min((start_v2 + reachable_start_v2) * 0.5, max_cruise_v2[m],
                                peak_cruise_v2)
                _set_junction(m, min(start_v2, cruise_v2), cruise_v2,
                              min(next_end_v2, cruise_v2), move_d, accel, out_v, out_t)
        else:
            # delay this move until peak_cruise_v2 is known
            dl_m[nd] = m
            dl_s[nd] = start_v2
            dl_e[nd] = next_end_v2
            nd += 1
        next_end_v2 = start_v2
        next_smoothed_v2 = smoothed_v2
    if update_flush_count:
        return 0
    if nd > 0:
        # unreachable for a queue that starts at a junction limit; finish them anyway
        mc_v2 = peak_cruise_v2 if peak_cruise_v2 > 0.0 else np.inf
        for d in range(nd - 1, -1, -1):
            ms_v2 = dl_s[d]
            mc_v2 = min(mc_v2, ms_v2)
            _set_junction(dl_m[d], min(ms_v2, mc_v2), mc_v2, min(dl_e[d], mc_v2),
                          move_d, accel, out_v, out_t)
    return flush_count


@njit(cache=True, nogil=True)
def _process(lazy, st, qbuf, move_d, accel, delta_v2, smooth_delta_v2, max_cruise_v2,  # type: ignore[no-untyped-def]
             max_start_v2, max_smoothed_v2, out_v, out_t, dl_m, dl_s, dl_e, t_start, gap):
    """Klipper ``ToolHead._process_lookahead``: plan, then put final moves on the clock."""
    count = _flush(lazy, st, qbuf, move_d, accel, delta_v2, smooth_delta_v2, max_cruise_v2,
                   max_start_v2, max_smoothed_v2, out_v, out_t, dl_m, dl_s, dl_e)
    if count == 0:
        return
    head = int(st[_HEAD])
    t = st[_T]
    if st[_NEED_PRIME] != 0.0:
        st[_NEED_PRIME] = 0.0
        restart = st[_MIN_RESTART] + st[_KFD]
        if restart > t:
            gap[qbuf[head]] += restart - t
            t = restart
    for idx in range(head, head + count):
        m = qbuf[idx]
        t_start[m] = t
        t += out_t[m, 0] + out_t[m, 1] + out_t[m, 2]
    st[_T] = t
    st[_STEP_GEN] = max(st[_STEP_GEN], t + st[_KFD])
    st[_HEAD] = head + count


@njit(cache=True, nogil=True)
def run_toolhead(move_d, ux, uy, uz, er, is_kin, valid, max_cruise_v2, accel,  # type: ignore[no-untyped-def]
                 smooth_delta_v2, jdev, icv, min_move_t, op_pos, op_code, op_val, kfd0,
                 lazy, out_v, out_t, t_start, gap, op_time, op_gap):
    """Plan all moves and commands; fill the phase and time outputs.

    Parameters
    ----------
    move_d : float64[n]
        Path length (XYZ, or |E| for extrude-only moves), mm.
    ux, uy, uz, er : float64[n]
        Unit direction and E per path length of each move.
    is_kin, valid : bool[n]
        Move has XYZ motion; move is queued at all (zero-length moves are not).
    max_cruise_v2, accel, smooth_delta_v2 : float64[n]
        Limits after ``limit_speed`` (velocity², mm/s², smoothed Δv²).
    jdev, icv, min_move_t : float64[n]
        Junction deviation in force, extruder corner velocity, shortest move time.
    op_pos, op_code, op_val : int64[m], int64[m], float64[m]
        Commands: before move ``op_pos``, what (``OP_*``) and its value.
    kfd0 : float
        Initial kin_flush_delay, s.
    lazy : bool
        Emulate Klipper's lazy (partial) flushing as moves arrive.
    out_v, out_t : float64[n, 3]
        Output start/cruise/end speed and accel/cruise/decel time of each move.
    t_start, gap : float64[n]
        Output start time of each move and restart gap inserted before it, s.
    op_time, op_gap : float64[m]
        Output print time after each command and the time it added, s.

    Returns
    -------
    float
        Print time when everything is done, s.
    """
    n = move_d.shape[0]
    delta_v2 = 2.0 * move_d * accel
    max_start_v2 = np.zeros(n)
    max_smoothed_v2 = np.zeros(n)
    qbuf = np.empty(n + 1, np.int64)
    dl_m = np.empty(n + 1, np.int64)
    dl_s = np.empty(n + 1)
    dl_e = np.empty(n + 1)
    st = np.zeros(8)
    st[_T] = 0.0
    st[_MIN_RESTART] = NO_TIME
    st[_STEP_GEN] = NO_TIME
    st[_KFD] = kfd0
    st[_NEED_PRIME] = 1.0
    st[_JFLUSH] = BUFFER_TIME_HIGH
    n_ops = op_pos.shape[0]
    j = 0
    for k in range(n + 1):
        while j < n_ops and op_pos[j] <= k:
            code = op_code[j]
            t0 = st[_T]
            if code == OP_WAIT or code == OP_HOME or code == OP_SG_FLUSH:
                _process(False, st, qbuf, move_d, accel, delta_v2, smooth_delta_v2,
                         max_cruise_v2, max_start_v2, max_smoothed_v2, out_v, out_t,
                         dl_m, dl_s, dl_e, t_start, gap)
                st[_NEED_PRIME] = 1.0
                st[_JFLUSH] = BUFFER_TIME_HIGH
                t0 = st[_T]
                if code == OP_HOME:
                    st[_MIN_RESTART] = NO_TIME
                    st[_STEP_GEN] = NO_TIME
                elif code == OP_SG_FLUSH:
                    st[_MIN_RESTART] = max(st[_MIN_RESTART], st[_STEP_GEN])
            elif code == OP_DWELL or code == OP_LAST_MOVE_TIME:
                if st[_NEED_PRIME] != 0.0:
                    _process(False, st, qbuf, move_d, accel, delta_v2, smooth_delta_v2,
                             max_cruise_v2, max_start_v2, max_smoothed_v2, out_v, out_t,
                             dl_m, dl_s, dl_e, t_start, gap)
                    st[_NEED_PRIME] = 1.0
                    st[_JFLUSH] = BUFFER_TIME_HIGH
                    t0 = st[_T]
                    st[_T] = max(st[_T], st[_MIN_RESTART] + st[_KFD])
                else:
                    _process(False, st, qbuf, move_d, accel, delta_v2, smooth_delta_v2,
                             max_cruise_v2, max_start_v2, max_smoothed_v2, out_v, out_t,
                             dl_m, dl_s, dl_e, t_start, gap)
                    t0 = st[_T]
                if code == OP_DWELL:
                    st[_T] += max(0.0, op_val[j])
            elif code == OP_SET_KFD:
                st[_KFD] = op_val[j]
            op_time[j] = st[_T]
            op_gap[j] = st[_T] - t0
            j += 1
        if k == n:
            break
        if not valid[k]:
            continue
        tail = int(st[_TAIL])
        qbuf[tail] = k
        st[_TAIL] = tail + 1
        if tail - int(st[_HEAD]) == 0:
            continue
        p = qbuf[tail - 1]
        # ---- Move.calc_junction(prev_move) ----
        if is_kin[k] and is_kin[p]:
            diff_r = er[k] - er[p]
            if diff_r != 0.0:
                ext_v2 = (icv[k] / abs(diff_r)) ** 2
            else:
                ext_v2 = max_cruise_v2[k]
            msv2 = min(ext_v2, max_cruise_v2[k], max_cruise_v2[p],
                       max_start_v2[p] + delta_v2[p])
            cos_theta = -(ux[k] * ux[p] + uy[k] * uy[p] + uz[k] * uz[p])
            sin_d2 = np.sqrt(max(0.5 * (1.0 - cos_theta), 0.0))
            cos_d2 = np.sqrt(max(0.5 * (1.0 + cos_theta), 0.0))
            one_minus_sin_d2 = 1.0 - sin_d2
            if one_minus_sin_d2 > 0.0 and cos_d2 > 0.0:
                r_jd = sin_d2 / one_minus_sin_d2
                quarter_tan_d2 = 0.25 * sin_d2 / cos_d2
                msv2 = min(msv2, r_jd * jdev[k] * accel[k], r_jd * jdev[p] * accel[p],
                           delta_v2[k] * quarter_tan_d2, delta_v2[p] * quarter_tan_d2)
            max_start_v2[k] = msv2
            max_smoothed_v2[k] = min(msv2, max_smoothed_v2[p] + smooth_delta_v2[p])
        st[_JFLUSH] -= min_move_t[k]
        if lazy and st[_JFLUSH] <= 0.0:
            _process(True, st, qbuf, move_d, accel, delta_v2, smooth_delta_v2,
                     max_cruise_v2, max_start_v2, max_smoothed_v2, out_v, out_t,
                     dl_m, dl_s, dl_e, t_start, gap)
    # end of input: empty the queue (Klipper does this at the end of a file)
    _process(False, st, qbuf, move_d, accel, delta_v2, smooth_delta_v2, max_cruise_v2,
             max_start_v2, max_smoothed_v2, out_v, out_t, dl_m, dl_s, dl_e, t_start, gap)
    return st[_T]


# error codes of move_limits
ERR_NONE = 0
ERR_SPEED = 1          # move without a positive speed
ERR_RANGE_X = 2        # +1, +2 for Y, Z: end beyond position_min/max
ERR_EXTRUDE_ONLY = 5   # extrude-only/retract move longer than max_extrude_only_distance
ERR_CROSS_SECTION = 6  # extrusion above max_extrude_cross_section
ERR_NO_EXTRUDER = 7    # E motion on a printer without an [extruder]

#: columns of the per-segment settings table of move_limits
SEG_VEL, SEG_ACCEL, SEG_ACCEL_TO_DECEL, SEG_JD, SEG_EXT = range(5)
#: columns of the extruder table of move_limits
EX_VEL, EX_ACCEL, EX_DIST, EX_RATIO, EX_TINY, EX_ICV = range(6)
#: Klipper's acceleration of an extrude-only move before the extruder limits it, mm/s².
EXTRUDE_ONLY_ACCEL = 99999999.9
#: Shorter XYZ paths are extrude-only moves (Klipper ``Move.__init__``), mm.
MIN_KINEMATIC_D = 1e-9


@njit(cache=True, inline="always")
def _home(px, py, pz, hm, home):  # type: ignore[no-untyped-def]
    """Position after a G28 of the axes in ``hm`` (bits X=1, Y=2, Z=4)."""
    if hm & 1:
        px = home[0]
    if hm & 2:
        py = home[1]
    if hm & 4:
        pz = home[2]
    return px, py, pz


@njit(cache=True, nogil=True)
def move_starts(x, y, z, start, home_mask, home, sx, sy, sz, length):  # type: ignore[no-untyped-def]
    """Start position and XYZ length of every move (Klipper ``Move.__init__``).

    ``home_mask[k]`` (bits X=1, Y=2, Z=4) puts those axes at ``home`` before move ``k``
    (G28). A move shorter than 1 nm in XYZ is extrude-only: Klipper drops its XYZ motion,
    so the next move starts where this one started. (:func:`move_limits` tracks the
    position the same way.)
    """
    n = x.shape[0]
    px = start[0]
    py = start[1]
    pz = start[2]
    for k in range(n):
        px, py, pz = _home(px, py, pz, home_mask[k], home)
        sx[k] = px
        sy[k] = py
        sz[k] = pz
        dx = x[k] - px
        dy = y[k] - py
        dz = z[k] - pz
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        length[k] = d
        if d >= MIN_KINEMATIC_D:
            px = x[k]
            py = y[k]
            pz = z[k]


@njit(cache=True, nogil=True)
def move_limits(x, y, z, de, feed, start, home_mask, home, seg, seg_tab, ex_tab,  # type: ignore[no-untyped-def]
                z_vel, z_accel, pmin, pmax, cap_v, cap_a, move_d, ux, uy, uz, er, is_kin,
                valid, max_cruise_v2, accel, smooth_delta_v2, jdev, icv, min_move_t, err):
    """Per-move geometry and limits: Klipper ``Move.__init__`` and every ``check_move``.

    For a move with XYZ length ``d`` (else an extrude-only move of length ``|ΔE|`` with
    acceleration 99999999.9 and speed not capped by ``max_velocity``)::

        v       = min(F, max_velocity);  a = max_accel;  Δv²_smooth = 2·d·max_accel_to_decel
        Z move: r = d/|Δz|;   v ≤ max_z_velocity·r,   a ≤ max_z_accel·r
        kinematics caps (``cap_v``, ``cap_a``, when given): v ≤ cap_v, a ≤ cap_a
        E move without XY, or retraction: r = |ΔE|/d;  v ≤ v_e,max/r,  a ≤ a_e,max/r
        Δv²_smooth = min(Δv²_smooth, 2·d·a)

    A move that changes an axis and ends outside ``pmin .. pmax`` on it is refused.
    ``home_mask[k]`` (bits X=1, Y=2, Z=4) puts the named axes at ``home`` before move
    ``k`` (G28), as in :func:`move_starts`. ``err`` receives ``(code, move index, value,
    allowed)`` of the first move Klipper would refuse (code 0: none).
    """
    n = x.shape[0]
    has_caps = cap_v.shape[0] == n and n > 0
    px = start[0]
    py = start[1]
    pz = start[2]
    for k in range(n):
        px, py, pz = _home(px, py, pz, home_mask[k], home)
        dx = x[k] - px
        dy = y[k] - py
        dz = z[k] - pz
        d_e = de[k]
        s = seg[k]
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        speed = feed[k]
        kin = d >= MIN_KINEMATIC_D
        if kin:
            # an extrude-only move keeps the old XYZ (Klipper drops sub-nm motion)
            px = x[k]
            py = y[k]
            pz = z[k]
            velocity = min(speed, seg_tab[s, SEG_VEL])
            a = seg_tab[s, SEG_ACCEL]
        else:
            dx = 0.0
            dy = 0.0
            dz = 0.0
            d = abs(d_e)
            velocity = speed
            a = EXTRUDE_ONLY_ACCEL
        is_kin[k] = kin
        move_d[k] = d
        if d == 0.0:
            valid[k] = False
            ux[k] = 0.0
            uy[k] = 0.0
            uz[k] = 0.0
            er[k] = 0.0
            continue
        valid[k] = True
        if not speed > 0.0:
            err[0] = ERR_SPEED
            err[1] = k
            err[2] = speed
            err[3] = 0.0
            return
        inv_d = 1.0 / d
        ux[k] = dx * inv_d
        uy[k] = dy * inv_d
        uz[k] = dz * inv_d
        r_e = d_e * inv_d
        er[k] = r_e
        v2 = velocity * velocity
        sdv2 = 2.0 * d * seg_tab[s, SEG_ACCEL_TO_DECEL]
        if kin:
            ends = (x[k], y[k], z[k])
            moved = (dx != 0.0, dy != 0.0, dz != 0.0)
            for ax in range(3):
                if moved[ax] and (ends[ax] < pmin[ax] or ends[ax] > pmax[ax]):
                    err[0] = ERR_RANGE_X + ax
                    err[1] = k
                    err[2] = ends[ax]
                    err[3] = pmax[ax] if ends[ax] > pmax[ax] else pmin[ax]
                    return
            if dz != 0.0:
                z_ratio = d / abs(dz)
                lim = z_vel * z_ratio
                v2 = min(v2, lim * lim)
                a = min(a, z_accel * z_ratio)
            if has_caps:
                lim = cap_v[k]
                v2 = min(v2, lim * lim)
                a = min(a, cap_a[k])
        if d_e != 0.0:
            if ex_tab.shape[0] == 0:
                err[0] = ERR_NO_EXTRUDER
                err[1] = k
                err[2] = d_e
                err[3] = 0.0
                return
            e = int(seg_tab[s, SEG_EXT])
            if (dx == 0.0 and dy == 0.0) or r_e < 0.0:
                if abs(d_e) > ex_tab[e, EX_DIST]:
                    err[0] = ERR_EXTRUDE_ONLY
                    err[1] = k
                    err[2] = abs(d_e)
                    err[3] = ex_tab[e, EX_DIST]
                    return
                inv_r = 1.0 / abs(r_e)
                lim = ex_tab[e, EX_VEL] * inv_r
                v2 = min(v2, lim * lim)
                a = min(a, ex_tab[e, EX_ACCEL] * inv_r)
            elif r_e > ex_tab[e, EX_RATIO] and d_e > ex_tab[e, EX_TINY]:
                err[0] = ERR_CROSS_SECTION
                err[1] = k
                err[2] = r_e
                err[3] = ex_tab[e, EX_RATIO]
                return
        max_cruise_v2[k] = v2
        accel[k] = a
        smooth_delta_v2[k] = min(sdv2, 2.0 * d * a)
        jdev[k] = seg_tab[s, SEG_JD]
        icv[k] = ex_tab[int(seg_tab[s, SEG_EXT]), EX_ICV] if ex_tab.shape[0] else 0.0
        min_move_t[k] = d / np.sqrt(v2) if v2 > 0.0 else np.inf   # 0: refused by the caller
    err[0] = ERR_NONE
