"""Arc linearisation of the scanning kernel (numba): ``G2``/``G3`` in the XY plane.

An arc becomes equal-angle chords the way firmware splits it: Klipper's
``[gcode_arcs] resolution`` (``max(1, floor(L / resolution))`` segments of the helical
length ``L``) or a chord tolerance (Marlin-like: the fewest segments whose sagitta stays
within the tolerance).
"""

from __future__ import annotations

import math

from flowtwin._jit import njit

# --- row kinds (must match MoveKind) --------------------------------------------------
K_TRAVEL, K_EXTRUDE, K_RETRACT, K_XY, K_Z, K_ARC, K_FW, K_RAPID = 1, 2, 4, 8, 16, 32, 64, 128

#: :func:`emit_arc` results other than a row count.
ARC_BAD = -1   # no centre: neither I/J nor an R at least half the chord
ARC_FULL = -2  # the row buffer cannot hold the segments
ARC_HUGE = -3  # more segments than any printable arc has (a radius of kilometres)
#: Segments of the longest arc accepted: a full circle of 0.5 m radius is 3 142 chords at
#: Klipper's 1 mm resolution; more than this is a broken I/J/R, not a print.
MAX_ARC_SEGMENTS = 100_000


@njit(cache=True, inline="always")
def emit(out, n, line, tool, x, y, z, de, feed, flow, kind, e_acc):  # type: ignore[no-untyped-def]
    """Fill row ``n`` of ``out`` (every field but layer and feature).

    ``e_acc[int16(tool) + 32768]`` is the running E of each tool (summed in file order,
    as :func:`numpy.cumsum` would); the row's ``e`` is that sum after its ``de``.
    """
    t = (tool + 32768) % 65536
    acc = e_acc[t] + de
    e_acc[t] = acc
    r = out[n]
    r.e = acc
    r.x = x
    r.y = y
    r.z = z
    r.de = de
    r.feed_mm_s = feed
    r.line = line
    r.tool = tool
    r.kind = kind
    r.flow = flow


@njit(cache=True, inline="always")
def row_kind(dx: float, dy: float, dz: float, de: float, arc: bool, rapid: bool) -> int:
    """:class:`MoveKind` flags of a row from its displacement and E change."""
    k = 0
    if de > 0.0:
        k |= K_EXTRUDE
    elif de < 0.0:
        k |= K_RETRACT
    else:
        k |= K_TRAVEL
    if dx != 0.0 or dy != 0.0:
        k |= K_XY
    if dz != 0.0:
        k |= K_Z
    if arc:
        k |= K_ARC
    if rapid:
        k |= K_RAPID
    return k


@njit(cache=True, nogil=True)
def emit_arc(out, n_out, lineno, tool, x0, y0, z0, x1, y1, z1, de, feed, flow,  # type: ignore[no-untyped-def]
             cw, has_ij, r_p_ij, r_q_ij, has_r, r_mm, klipper, arc_param, e_acc):
    """Write the chords of one arc into ``out`` from row ``n_out``.

    ``(r_p_ij, r_q_ij)`` is the radius vector ``(-I, -J)`` and ``r_mm`` the ``R`` word,
    in mm. Returns the new row count, :data:`ARC_BAD`, :data:`ARC_HUGE` or
    :data:`ARC_FULL` (nothing written).
    """
    if has_ij:  # I, J: the radius vector is exactly (-I, -J)
        r_p = r_p_ij
        r_q = r_q_ij
        cx = x0 - r_p
        cy = y0 - r_q
    elif has_r:
        r = r_mm
        dx = x1 - x0
        dy = y1 - y0
        chord = math.sqrt(dx * dx + dy * dy)
        if chord == 0.0 or abs(r) * 2.0 < chord * (1.0 - 1e-9):
            return ARC_BAD
        h2 = r * r - chord * chord / 4.0
        h = math.sqrt(h2) if h2 > 0.0 else 0.0
        # centre to the right of the chord for CW with r>0 (short arc)
        sgn = 1.0 if (cw != (r < 0.0)) else -1.0
        mx = (x0 + x1) / 2.0
        my = (y0 + y1) / 2.0
        cx = mx + sgn * h * dy / chord
        cy = my - sgn * h * dx / chord
        r_p = x0 - cx
        r_q = y0 - cy
    else:
        return ARC_BAD
    # Angle as firmware computes it (Klipper gcode_arcs, Marlin plan_arc): the signed
    # angle between the radius vectors to start and target, in [0, 2π) counter-clockwise,
    # minus 2π clockwise; a full circle only when that angle is zero and the target is the
    # start (exactly for Klipper, within 1e-9 mm and 1e-9 rad in chord mode, as Marlin's
    # NEAR tests).
    rt_a = x1 - cx
    rt_b = y1 - cy
    sweep = math.atan2(r_p * rt_b - r_q * rt_a, r_p * rt_a + r_q * rt_b)
    if sweep < 0.0:
        sweep += 2.0 * math.pi
    if cw:
        sweep -= 2.0 * math.pi
    if klipper:
        if sweep == 0.0 and x0 == x1 and y0 == y1:
            sweep = 2.0 * math.pi
    elif abs(sweep) < 1e-9 and abs(x0 - x1) < 1e-9 and abs(y0 - y1) < 1e-9:
        sweep = 2.0 * math.pi
    radius = math.sqrt(r_p * r_p + r_q * r_q)
    planar = abs(sweep) * radius
    dz = z1 - z0
    length = math.sqrt(planar * planar + dz * dz)
    if klipper:
        count = math.floor(length / arc_param)
    else:
        tol = arc_param
        if radius > tol:
            step = 2.0 * math.acos(1.0 - tol / radius)
            count = math.ceil(abs(sweep) / step)
        else:
            count = 1.0
    if not count <= MAX_ARC_SEGMENTS:  # also NaN and inf
        return ARC_HUGE
    nseg = max(int(count), 1)
    if n_out + nseg > out.shape[0]:
        return ARC_FULL
    theta_seg = sweep / nseg
    z_seg = dz / nseg
    dseg = de / nseg
    px = x0
    py = y0
    pz = z0
    for s in range(1, nseg + 1):
        if s == nseg:
            qx = x1
            qy = y1
            qz = z1
        else:
            th = s * theta_seg
            cos_t = math.cos(th)
            sin_t = math.sin(th)
            # the start radius vector rotated by th
            qx = cx + r_p * cos_t - r_q * sin_t
            qy = cy + r_p * sin_t + r_q * cos_t
            qz = z0 + s * z_seg
        kind = row_kind(qx - px, qy - py, qz - pz, dseg, True, False)
        emit(out, n_out, lineno, tool, qx, qy, qz, dseg, feed, flow, kind, e_acc)
        n_out += 1
        px = qx
        py = qy
        pz = qz
    return n_out
