"""Byte-level G-code scanning kernel (numba).

This is the reader's hot loop. It walks a ``uint8`` buffer line by line and

* executes the frequent commands itself: ``G0/G1``, ``G2/G3`` (XY plane, I/J or R,
  helical, linearised), ``G92``, ``G90/G91``, ``M82/M83``, ``G20/G21``, ``G28``,
  ``T<n>``, ``M220 S``, ``M221 S``, ``N`` line numbers with ``*`` checksums;
* records every other non-empty line (comments, events, unknown commands) as a span
  ``(line, start, end, move_index)`` for the Python side to interpret afterwards, in order;
* stops and hands a line back to Python when that line changes the state in a way the
  kernel does not model (``G10/G11`` firmware retraction, ``M207/M208``, ``M200``,
  ``G17/G18/G19``), or when a word is malformed (Python then raises a precise error).

Numbers are parsed as an integer mantissa divided by a power of ten, which is correctly
rounded for up to 15 significant digits (both operands are exact doubles), i.e. for every
number a slicer writes.

State vector layout (float64): see the ``S_*`` constants. Positions are toolhead
coordinates: a G-code coordinate ``v`` maps to ``v * unit + offset``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from flowtwin.gcode._bytes import (
    MAX_ABS_VALUE,
    _is_word_end,
    _parse_number,
    _skippable_comment,
    _upper,
)

# --- state vector indices -------------------------------------------------------------
S_X, S_Y, S_Z = 0, 1, 2          # toolhead position, mm
S_EGC = 3                        # G-code E coordinate (mm after unit/volumetric factors)
S_OFF_X, S_OFF_Y, S_OFF_Z = 4, 5, 6  # G92 offsets: toolhead = gcode * unit + offset
S_FEED = 7                       # last F, mm/s (unit applied, M220 not applied)
S_SPEED_FACTOR = 8               # M220 / 100
S_FLOW = 9                       # M221 / 100
S_TOOL = 10
S_ABS_XYZ = 11                   # 1.0 = G90
S_ABS_E = 12                     # 1.0 = M82
S_UNIT = 13                      # 1.0 mm, 25.4 inch
S_E_FACTOR = 14                  # 1.0, or 1/filament area with M200 volumetric
S_HOME_X, S_HOME_Y, S_HOME_Z = 15, 16, 17
S_ARC_MODE = 18                  # 0: fixed segment length (Klipper), 1: chord tolerance
S_ARC_PARAM = 19                 # segment length mm, or chord tolerance mm
S_LINE = 20                      # number of the last line consumed (1-based)
S_ERR_LINE = 21                  # line of a malformed word
S_ERR_CODE = 22                  # error code (ERR_*)
S_PLANE = 23                     # 17, 18, 19
S_RAPID_FEED = 24                # unused placeholder (G0 uses the same F as G1)
N_STATE = 25

# --- status codes ---------------------------------------------------------------------
ST_DONE = 0
ST_MOVES_FULL = 1
ST_OTHER_FULL = 2
ST_PYTHON = 3
ST_ERROR = 4

# --- error codes ----------------------------------------------------------------------
ERR_NUMBER = 1      # a letter not followed by a valid number
ERR_CHECKSUM = 2    # '*' checksum does not match
ERR_ARC = 3         # arc without centre / radius, or radius too small
ERR_FEED = 4        # F <= 0 or not finite
ERR_VALUE = 5       # non-finite or absurd coordinate

# --- row kinds (must match MoveKind) --------------------------------------------------
K_TRAVEL, K_EXTRUDE, K_RETRACT, K_XY, K_Z, K_ARC, K_FW, K_RAPID = 1, 2, 4, 8, 16, 32, 64, 128

@njit(cache=True)
def _emit(out, n, line, tool, x, y, z, de, feed, flow, kind):  # type: ignore[no-untyped-def]
    r = out[n]
    r.x = x
    r.y = y
    r.z = z
    r.de = de
    r.feed_mm_s = feed
    r.line = line
    r.tool = tool
    r.kind = kind
    r.flow = flow


@njit(cache=True)
def _row_kind(dx: float, dy: float, dz: float, de: float, arc: bool, rapid: bool) -> int:
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


OTHER_TEXT = 0
OTHER_NUMERIC = 1


@njit(cache=True)
def _record_numeric(other, evals, n_other, lineno, start, eol, n_out, c0, code_num, has, val):  # type: ignore[no-untyped-def]
    other[n_other, 0] = lineno
    other[n_other, 1] = start
    other[n_other, 2] = eol
    other[n_other, 3] = n_out
    other[n_other, 4] = OTHER_NUMERIC
    other[n_other, 5] = c0 * 1_000_000 + int(code_num)
    mask = 0
    for q in range(26):
        if has[q]:
            mask |= 1 << q
            evals[n_other, 1 + q] = val[q]
    evals[n_other, 0] = float(mask)
    return n_other + 1


@njit(cache=True)
def scan(buf, pos, state, out, n_out, other, evals, n_other):  # type: ignore[no-untyped-def]
    """Scan ``buf`` from byte ``pos``.

    Parameters
    ----------
    buf : uint8[:]
        The file contents (or a chunk ending at a line end).
    pos : int
        Byte offset of the first line to read.
    state : float64[N_STATE]
        Reader state, updated in place.
    out : MOVE_DTYPE[cap]
        Move rows; the kernel fills x, y, z, de, feed_mm_s, line, tool, kind, flow.
    n_out : int
        Rows already filled.
    other : int64[cap2, 6]
        Lines left to Python, in order: line, start byte, end byte, move index, kind
        (``OTHER_TEXT``: Python parses the text; ``OTHER_NUMERIC``: a command whose words
        are all numbers, already parsed into ``evals``), command code
        (``letter * 1_000_000 + number``).
    evals : float64[cap2, 27]
        For ``OTHER_NUMERIC`` rows: a bit mask of the letters present (bit 0 = A), then the
        value of each letter A..Z.
    n_other : int
        Spans already filled.

    Returns
    -------
    status, pos, n_out, n_other
        ``pos`` is the start of the line that stopped the scan (ST_PYTHON, ST_ERROR, *_FULL)
        or ``len(buf)`` when done.
    """
    size = buf.shape[0]
    cap = out.shape[0]
    cap2 = other.shape[0]
    line = int(state[S_LINE])
    has = np.zeros(26, dtype=np.bool_)
    val = np.zeros(26)
    while pos < size:
        # find the end of the line
        start = pos
        eol = start
        while eol < size and buf[eol] != 10:
            eol += 1
        nxt = eol + 1
        # capacity: an arc may need many rows; keep a margin of 1 row + arc check later
        if n_out + 1 > cap:
            state[S_LINE] = line
            return ST_MOVES_FULL, start, n_out, n_other
        if n_other + 1 > cap2:
            state[S_LINE] = line
            return ST_OTHER_FULL, start, n_out, n_other
        lineno = line + 1
        i = start
        while i < eol and (buf[i] == 32 or buf[i] == 9 or buf[i] == 13):
            i += 1
        if i >= eol:  # blank
            line = lineno
            pos = nxt
            continue
        # checksum: '*' outside a comment
        cend = eol
        j = i
        star = -1
        while j < eol:
            if buf[j] == 59:
                break
            if buf[j] == 42:
                star = j
                break
            j += 1
        if star >= 0:
            csum, k, ok = _parse_number(buf, star + 1, eol)
            # the checksum covers every byte before '*'
            x = 0
            for q in range(start, star):
                x ^= buf[q]
            if not ok or int(csum) != x:
                state[S_ERR_LINE] = lineno
                state[S_ERR_CODE] = ERR_CHECKSUM
                state[S_LINE] = line
                return ST_ERROR, start, n_out, n_other
            cend = star
        # N line number
        c0 = _upper(buf[i])
        if c0 == 78:  # 'N'
            v, k, ok = _parse_number(buf, i + 1, cend)
            if not ok:
                state[S_ERR_LINE] = lineno
                state[S_ERR_CODE] = ERR_NUMBER
                state[S_LINE] = line
                return ST_ERROR, start, n_out, n_other
            i = k
            while i < cend and (buf[i] == 32 or buf[i] == 9):
                i += 1
            if i >= cend:
                line = lineno
                pos = nxt
                continue
            c0 = _upper(buf[i])
        if c0 == 59:  # comment-only line -> Python (metadata), unless known to be inert
            if _skippable_comment(buf, i, eol):
                line = lineno
                pos = nxt
                continue
            other[n_other, 0] = lineno
            other[n_other, 1] = start
            other[n_other, 2] = eol
            other[n_other, 3] = n_out
            other[n_other, 4] = OTHER_TEXT
            n_other += 1
            line = lineno
            pos = nxt
            continue
        # command letter + number
        code_num = -1.0
        if (c0 == 71 or c0 == 77 or c0 == 84) and i + 1 < cend and 48 <= buf[i + 1] <= 57:
            # G/M/T with an integer code (a '.' sub-code goes to Python)
            k = i + 1
            num = 0
            while k < cend and 48 <= buf[k] <= 57 and num < 100000:
                num = num * 10 + (buf[k] - 48)
                k += 1
            if k < cend and buf[k] == 46:
                code_num = -1.0
            elif k < cend and not _is_word_end(buf[k]):
                code_num = -1.0
            else:
                code_num = float(num)
            i = k
        if code_num < 0.0:
            # not a plain G/M/T command: Python (extended commands, unknown)
            other[n_other, 0] = lineno
            other[n_other, 1] = start
            other[n_other, 2] = eol
            other[n_other, 3] = n_out
            other[n_other, 4] = OTHER_TEXT
            n_other += 1
            line = lineno
            pos = nxt
            continue
        # parse parameter words up to the comment / checksum
        for q in range(26):
            has[q] = False
            val[q] = 0.0
        bad = False
        k = i
        while k < cend:
            c = buf[k]
            if c == 32 or c == 9 or c == 13:
                k += 1
                continue
            if c == 59:
                break
            cu = _upper(c)
            if 65 <= cu <= 90:
                v, k2, ok = _parse_number(buf, k + 1, cend)
                if not ok or (k2 < cend and not _is_word_end(buf[k2])):
                    bad = True
                    break
                # '1e5' is scientific notation, which G-code does not have: refuse it
                # rather than read it as X1 E5 (upper-case 'E' stays a parameter word)
                if (k2 + 1 < cend and buf[k2] == 101
                        and (48 <= buf[k2 + 1] <= 57 or buf[k2 + 1] == 45
                             or buf[k2 + 1] == 43)):
                    bad = True
                    break
                if not (abs(v) <= MAX_ABS_VALUE):
                    bad = True
                    break
                has[cu - 65] = True
                val[cu - 65] = v
                k = k2
            else:
                bad = True
                break
        if c0 == 84:  # T<n>
            if bad:
                # leave odd T lines to Python for the message
                state[S_LINE] = line
                return ST_PYTHON, start, n_out, n_other
            state[S_TOOL] = code_num
            n_other = _record_numeric(other, evals, n_other, lineno, start, eol, n_out, c0,
                                      code_num, has, val)
            line = lineno
            pos = nxt
            continue
        if c0 == 71 and (code_num == 0.0 or code_num == 1.0 or code_num == 2.0
                         or code_num == 3.0):
            if bad:
                state[S_ERR_LINE] = lineno
                state[S_ERR_CODE] = ERR_NUMBER
                state[S_LINE] = line
                return ST_ERROR, start, n_out, n_other
            unit = state[S_UNIT]
            absx = state[S_ABS_XYZ] != 0.0
            abse = state[S_ABS_E] != 0.0 and absx
            if has[5]:  # F
                f = val[5]
                if not (f > 0.0):
                    state[S_ERR_LINE] = lineno
                    state[S_ERR_CODE] = ERR_FEED
                    state[S_LINE] = line
                    return ST_ERROR, start, n_out, n_other
                state[S_FEED] = f * unit / 60.0
            x0 = state[S_X]
            y0 = state[S_Y]
            z0 = state[S_Z]
            x1 = x0
            y1 = y0
            z1 = z0
            if has[23]:
                x1 = val[23] * unit + state[S_OFF_X] if absx else x0 + val[23] * unit
            if has[24]:
                y1 = val[24] * unit + state[S_OFF_Y] if absx else y0 + val[24] * unit
            if has[25]:
                z1 = val[25] * unit + state[S_OFF_Z] if absx else z0 + val[25] * unit
            de = 0.0
            if has[4]:
                ev = val[4] * unit * state[S_E_FACTOR]
                if abse:
                    de = ev - state[S_EGC]
                    state[S_EGC] = ev
                else:
                    de = ev
                    state[S_EGC] = state[S_EGC] + ev
            feed = state[S_FEED] * state[S_SPEED_FACTOR]
            tool = int(state[S_TOOL])
            flow = state[S_FLOW]
            rapid = code_num == 0.0
            if code_num <= 1.0:
                if x1 != x0 or y1 != y0 or z1 != z0 or de != 0.0:
                    kind = _row_kind(x1 - x0, y1 - y0, z1 - z0, de, False, rapid)
                    _emit(out, n_out, lineno, tool,
                          x1, y1, z1, de, feed, flow, kind)
                    n_out += 1
                state[S_X] = x1
                state[S_Y] = y1
                state[S_Z] = z1
                line = lineno
                pos = nxt
                continue
            # ---- arcs (G2 clockwise, G3 counter-clockwise), XY plane ----
            if state[S_PLANE] != 17.0:
                state[S_LINE] = line
                return ST_PYTHON, start, n_out, n_other
            cw = code_num == 2.0
            if has[8] or has[9]:  # I, J: the radius vector is exactly (-I, -J)
                r_p = -(val[8] * unit) if has[8] else 0.0
                r_q = -(val[9] * unit) if has[9] else 0.0
                cx = x0 - r_p
                cy = y0 - r_q
            elif has[17]:  # R
                r = val[17] * unit
                dx = x1 - x0
                dy = y1 - y0
                chord = math.sqrt(dx * dx + dy * dy)
                if chord == 0.0 or abs(r) * 2.0 < chord * (1.0 - 1e-9):
                    state[S_ERR_LINE] = lineno
                    state[S_ERR_CODE] = ERR_ARC
                    state[S_LINE] = line
                    return ST_ERROR, start, n_out, n_other
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
                state[S_ERR_LINE] = lineno
                state[S_ERR_CODE] = ERR_ARC
                state[S_LINE] = line
                return ST_ERROR, start, n_out, n_other
            # Angle as firmware computes it (Klipper gcode_arcs, Marlin plan_arc): the
            # signed angle between the radius vectors to start and target, in [0, 2π)
            # counter-clockwise, minus 2π clockwise; a full circle only when that angle
            # is zero and the target is the start (exactly for Klipper, within 1e-9 mm
            # and 1e-9 rad in chord mode, as Marlin's NEAR tests).
            rt_a = x1 - cx
            rt_b = y1 - cy
            sweep = math.atan2(r_p * rt_b - r_q * rt_a, r_p * rt_a + r_q * rt_b)
            if sweep < 0.0:
                sweep += 2.0 * math.pi
            if cw:
                sweep -= 2.0 * math.pi
            klipper = state[S_ARC_MODE] == 0.0
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
                nseg = int(math.floor(length / state[S_ARC_PARAM]))
            else:
                tol = state[S_ARC_PARAM]
                if radius > tol:
                    step = 2.0 * math.acos(1.0 - tol / radius)
                    nseg = int(math.ceil(abs(sweep) / step))
                else:
                    nseg = 1
            if nseg < 1:
                nseg = 1
            if n_out + nseg > cap:
                state[S_LINE] = line
                # undo the E side effect: the kernel re-reads this line after growing
                if has[4]:
                    state[S_EGC] = state[S_EGC] - de
                return ST_MOVES_FULL, start, n_out, n_other
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
                kind = _row_kind(qx - px, qy - py, qz - pz, dseg, True, False)
                _emit(out, n_out, lineno, tool,
                      qx, qy, qz, dseg, feed, flow, kind)
                n_out += 1
                px = qx
                py = qy
                pz = qz
            state[S_X] = x1
            state[S_Y] = y1
            state[S_Z] = z1
            line = lineno
            pos = nxt
            continue
        # ---- other G/M codes the kernel executes ----
        if bad:
            # malformed parameters on a command we don't execute: Python decides
            state[S_LINE] = line
            return ST_PYTHON, start, n_out, n_other
        executed = True
        if c0 == 71:
            if code_num == 90.0:
                state[S_ABS_XYZ] = 1.0
            elif code_num == 91.0:
                state[S_ABS_XYZ] = 0.0
            elif code_num == 92.0:
                unit = state[S_UNIT]
                none = not (has[23] or has[24] or has[25] or has[4])
                if has[23] or none:
                    state[S_OFF_X] = state[S_X] - (val[23] * unit if has[23] else 0.0)
                if has[24] or none:
                    state[S_OFF_Y] = state[S_Y] - (val[24] * unit if has[24] else 0.0)
                if has[25] or none:
                    state[S_OFF_Z] = state[S_Z] - (val[25] * unit if has[25] else 0.0)
                if has[4] or none:
                    state[S_EGC] = (val[4] * unit * state[S_E_FACTOR]) if has[4] else 0.0
            elif code_num == 21.0:
                state[S_UNIT] = 1.0
            elif code_num == 20.0:
                state[S_UNIT] = 25.4
            elif code_num == 28.0:
                any_axis = has[23] or has[24] or has[25]
                if has[23] or not any_axis:
                    state[S_X] = state[S_HOME_X]
                if has[24] or not any_axis:
                    state[S_Y] = state[S_HOME_Y]
                if has[25] or not any_axis:
                    state[S_Z] = state[S_HOME_Z]
                executed = False  # also an event for the planner
            elif code_num == 17.0:
                state[S_PLANE] = 17.0
            else:
                executed = False
        else:  # M
            if code_num == 82.0:
                state[S_ABS_E] = 1.0
            elif code_num == 83.0:
                state[S_ABS_E] = 0.0
            elif code_num == 220.0 and has[18]:
                state[S_SPEED_FACTOR] = val[18] / 100.0
                executed = False
            elif code_num == 221.0 and has[18] and not has[19] and not has[3]:
                # M221 S<pct> (Marlin's M221 T<n> S<pct> targets one tool: Python)
                state[S_FLOW] = val[18] / 100.0
                executed = False
            else:
                executed = False
        if not executed:
            # G10/G11, M207/M208, M200, G18/G19 change what the kernel does: hand over
            if ((c0 == 71 and (code_num == 10.0 or code_num == 11.0 or code_num == 18.0
                               or code_num == 19.0))
                    or (c0 == 77 and (code_num == 207.0 or code_num == 208.0
                                      or code_num == 200.0
                                      or (code_num == 221.0 and not (has[18] and not has[19]
                                                                     and not has[3]))))):
                state[S_LINE] = line
                return ST_PYTHON, start, n_out, n_other
            n_other = _record_numeric(other, evals, n_other, lineno, start, eol, n_out, c0,
                                      code_num, has, val)
        line = lineno
        pos = nxt
    state[S_LINE] = line
    return ST_DONE, pos, n_out, n_other
