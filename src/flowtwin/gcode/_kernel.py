"""Byte-level G-code scanning kernel (numba).

This is the reader's hot loop. It walks a ``uint8`` buffer line by line and

* executes the frequent commands itself: ``G0/G1``, ``G2/G3`` (XY plane, I/J or R,
  helical, linearised), ``G92``, ``G90/G91``, ``M82/M83``, ``G20/G21``, ``G28``,
  ``T<n>``, ``M220 S``, ``M221 S``, ``N`` line numbers with ``*`` checksums (the modal
  ones, ``G90/G91``, ``G92``, ``G20/G21`` and ``M82/M83``, are also recorded as events);
* records every other non-empty line as a span ``(line, start, end, move_index)`` for the
  Python side to interpret afterwards, in order: comment-only lines (the text after ``;``),
  commands whose words are all numbers (events such as ``M204 S800``: already parsed, their
  values packed in ``vals``) and the rest (extended commands, odd syntax) as text;
* stops and hands a line back to Python when that line changes the state in a way the
  kernel does not model (``G10/G11`` firmware retraction, ``M207/M208``, ``M200``,
  ``G17/G18/G19``), or when a word is malformed (Python then raises a precise error).

Each line is read in one pass: its words up to ``;``, ``*`` or the line end; the checksum
and the end of the line are looked for only when something follows the words. Arcs are
linearised by :func:`flowtwin.gcode._arc.emit_arc`.

Numbers are parsed as an integer mantissa divided by a power of ten, which is correctly
rounded for up to 15 significant digits (both operands are exact doubles), i.e. for every
number a slicer writes.

State vector layout (float64): see the ``S_*`` constants. Positions are toolhead
coordinates: a G-code coordinate ``v`` maps to ``v * unit + offset``.
"""

from __future__ import annotations

import numpy as np

from flowtwin._jit import njit
from flowtwin.gcode._arc import ARC_BAD, ARC_FULL, ARC_HUGE, emit, emit_arc, row_kind
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
ERR_ARC_HUGE = 5    # an arc of more than MAX_ARC_SEGMENTS chords
ERR_VALUE = 5       # non-finite or absurd coordinate

# --- lines left to Python (column 4 of ``other``) -------------------------------------
OTHER_TEXT = 0      # Python parses the line's text
OTHER_NUMERIC = 1   # a command whose words are all numbers, parsed here
OTHER_COMMENT = 2   # a comment-only line: the span is the text after ';'
N_OTHER_COLS = 7    # line, start, end, move index, kind, command key, value offset
#: Command key of ``OTHER_NUMERIC`` lines: ``(letter * 1_000_000 + number) << KEY_SHIFT | mask``.
KEY_SHIFT = 26
MAX_WORDS = 26      # values one line can add (one per letter)

# letter bits of the word mask (bit 0 = A)
_D, _E, _F, _I, _J = 1 << 3, 1 << 4, 1 << 5, 1 << 8, 1 << 9
_R, _S, _T = 1 << 17, 1 << 18, 1 << 19
_X, _Y, _Z = 1 << 23, 1 << 24, 1 << 25
_XYZ = _X | _Y | _Z


@njit(cache=True, inline="always")
def _record(other, n_other, lineno, start, eol, n_out, kind):  # type: ignore[no-untyped-def]
    other[n_other, 0] = lineno
    other[n_other, 1] = start
    other[n_other, 2] = eol
    other[n_other, 3] = n_out
    other[n_other, 4] = kind
    return n_other + 1


@njit(cache=True, nogil=True)
def _record_numeric(other, vals, n_other, n_vals, lineno, start, eol, n_out, c0, code_num,  # type: ignore[no-untyped-def]
                    mask, val):
    _record(other, n_other, lineno, start, eol, n_out, OTHER_NUMERIC)
    other[n_other, 5] = (c0 * 1_000_000 + code_num) << KEY_SHIFT | mask
    other[n_other, 6] = n_vals
    for q in range(26):
        if mask >> q & 1:
            vals[n_vals] = val[q]
            n_vals += 1
    return n_other + 1, n_vals


@njit(cache=True, inline="always")
def _line_end(buf, k, size):  # type: ignore[no-untyped-def]
    """End of the line at ``k`` and its first ``*`` before any ``;`` (-1 if none)."""
    star = -1
    while k < size:
        c = buf[k]
        if c == 10:
            break
        if c == 59:  # ';': the rest is comment
            while k < size and buf[k] != 10:
                k += 1
            break
        if c == 42 and star < 0:
            star = k
            while k < size and buf[k] != 10:
                k += 1
            break
        k += 1
    return k, star


@njit(cache=True, nogil=True)
def _checksum_ok(buf, start, star, eol):  # type: ignore[no-untyped-def]
    """Whether the number after ``*`` is the XOR of every byte of the line before it."""
    csum, _k, ok = _parse_number(buf, star + 1, eol)
    x = 0
    for q in range(start, star):
        x ^= buf[q]
    return ok and int(csum) == x


@njit(cache=True, nogil=True)
def scan(buf, pos, state, out, n_out, other, vals, n_other, n_vals, e_acc):  # type: ignore[no-untyped-def]
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
        Move rows; the kernel fills every field but layer and feature.
    n_out : int
        Rows already filled.
    other : int64[cap2, N_OTHER_COLS]
        Lines left to Python, in order: line, start byte, end byte, move index, kind
        (``OTHER_TEXT``: Python parses the text ``buf[start:end]``; ``OTHER_COMMENT``: a
        comment-only line, ``buf[start:end]`` is the text after ``;``; ``OTHER_NUMERIC``: a
        command whose words are all numbers, already parsed), then for ``OTHER_NUMERIC``
        the command key (``(letter * 1_000_000 + number) << KEY_SHIFT | mask``, the mask
        of the letters present, bit 0 = A) and the offset of their values in ``vals``.
    vals : float64[cap3]
        Values of the ``OTHER_NUMERIC`` words, in letter order, packed.
    n_other, n_vals : int
        Rows of ``other`` and values of ``vals`` already filled.
    e_acc : float64[65536]
        Running E per tool (index ``int16(tool) + 32768``), updated in place.

    Returns
    -------
    status, pos, n_out, n_other, n_vals
        ``pos`` is the start of the line that stopped the scan (ST_PYTHON, ST_ERROR, *_FULL)
        or ``len(buf)`` when done.
    """
    size = buf.shape[0]
    cap = out.shape[0]
    cap2 = other.shape[0]
    cap3 = vals.shape[0]
    line = int(state[S_LINE])
    val = np.zeros(26)
    while pos < size:
        start = pos
        # capacity: an arc may need many rows; it checks again for itself
        if n_out + 1 > cap:
            state[S_LINE] = line
            return ST_MOVES_FULL, start, n_out, n_other, n_vals
        if n_other + 1 > cap2 or n_vals + MAX_WORDS > cap3:
            state[S_LINE] = line
            return ST_OTHER_FULL, start, n_out, n_other, n_vals
        lineno = line + 1
        i = start
        c = 10
        while i < size:
            c = buf[i]
            if c == 32 or c == 9 or c == 13:
                i += 1
            else:
                break
        if i >= size or c == 10:  # blank
            line = lineno
            pos = i + 1
            continue
        if c == 59:  # comment-only line -> Python (metadata), unless known to be inert
            eol = i + 1
            while eol < size and buf[eol] != 10:
                eol += 1
            if not _skippable_comment(buf, i, eol):
                n_other = _record(other, n_other, lineno, i + 1, eol, n_out, OTHER_COMMENT)
            line = lineno
            pos = eol + 1
            continue
        # N line number
        c0 = _upper(c)
        if c0 == 78:  # 'N'
            v, k, ok = _parse_number(buf, i + 1, size)
            if not ok:
                eol, star = _line_end(buf, i + 1, size)
                state[S_ERR_LINE] = lineno
                state[S_ERR_CODE] = (ERR_CHECKSUM if star >= 0
                                     and not _checksum_ok(buf, start, star, eol)
                                     else ERR_NUMBER)
                state[S_LINE] = line
                return ST_ERROR, start, n_out, n_other, n_vals
            i = k
            while i < size and (buf[i] == 32 or buf[i] == 9):
                i += 1
            c = buf[i] if i < size else 10
            if c == 10 or c == 42 or c == 13:
                # nothing but a line number (and a checksum)
                eol, star = _line_end(buf, i, size)
                if star >= 0 and not _checksum_ok(buf, start, star, eol):
                    state[S_ERR_LINE] = lineno
                    state[S_ERR_CODE] = ERR_CHECKSUM
                    state[S_LINE] = line
                    return ST_ERROR, start, n_out, n_other, n_vals
                if c == 13:  # CR then text: not blank, let the generic path decide
                    c0 = 13
                else:
                    line = lineno
                    pos = eol + 1
                    continue
            else:
                c0 = _upper(c)
            if c0 == 59:  # "N5 ;comment": Python (the comment follows the command syntax)
                eol, star = _line_end(buf, i, size)
                if not _skippable_comment(buf, i, eol):
                    n_other = _record(other, n_other, lineno, start, eol, n_out, OTHER_TEXT)
                line = lineno
                pos = eol + 1
                continue
        # command letter + number
        code_num = -1
        k = i
        if (c0 == 71 or c0 == 77 or c0 == 84) and i + 1 < size and 48 <= buf[i + 1] <= 57:
            # G/M/T with an integer code (a '.' sub-code goes to Python)
            k = i + 1
            num = 0
            while k < size and 48 <= buf[k] <= 57 and num < 100000:
                num = num * 10 + (buf[k] - 48)
                k += 1
            if k < size and buf[k] != 10 and (buf[k] == 46 or not _is_word_end(buf[k])):
                code_num = -1
            else:
                code_num = num
        if code_num < 0:
            # not a plain G/M/T command: Python (extended commands, unknown)
            eol, star = _line_end(buf, k, size)
            if star >= 0 and not _checksum_ok(buf, start, star, eol):
                state[S_ERR_LINE] = lineno
                state[S_ERR_CODE] = ERR_CHECKSUM
                state[S_LINE] = line
                return ST_ERROR, start, n_out, n_other, n_vals
            n_other = _record(other, n_other, lineno, start, eol, n_out, OTHER_TEXT)
            line = lineno
            pos = eol + 1
            continue
        # parameter words up to the comment / checksum / line end
        mask = 0
        bad = False
        while k < size:
            c = buf[k]
            if c == 32 or c == 9 or c == 13:
                k += 1
                continue
            if c == 10 or c == 59 or c == 42:
                break
            cu = _upper(c)
            if 65 <= cu <= 90:
                v, k2, ok = _parse_number(buf, k + 1, size)
                if not ok or (k2 < size and buf[k2] != 10 and not _is_word_end(buf[k2])):
                    bad = True
                    break
                # '1e5' is scientific notation, which G-code does not have: refuse it
                # rather than read it as X1 E5 (upper-case 'E' stays a parameter word)
                if (k2 + 1 < size and buf[k2] == 101
                        and (48 <= buf[k2 + 1] <= 57 or buf[k2 + 1] == 45
                             or buf[k2 + 1] == 43)):
                    bad = True
                    break
                if not (abs(v) <= MAX_ABS_VALUE):
                    bad = True
                    break
                mask |= 1 << (cu - 65)
                val[cu - 65] = v
                k = k2
            else:
                bad = True
                break
        # the rest of the line: comment, checksum (verified before anything is executed)
        if k < size and buf[k] == 10:
            eol = k
        else:
            eol, star = _line_end(buf, k, size)
            if star >= 0 and not _checksum_ok(buf, start, star, eol):
                state[S_ERR_LINE] = lineno
                state[S_ERR_CODE] = ERR_CHECKSUM
                state[S_LINE] = line
                return ST_ERROR, start, n_out, n_other, n_vals
        nxt = eol + 1
        if c0 == 84:  # T<n>
            if bad:
                # leave odd T lines to Python for the message
                state[S_LINE] = line
                return ST_PYTHON, start, n_out, n_other, n_vals
            state[S_TOOL] = code_num
            n_other, n_vals = _record_numeric(other, vals, n_other, n_vals, lineno, start, eol,
                                              n_out, c0, code_num, mask, val)
            line = lineno
            pos = nxt
            continue
        if c0 == 71 and code_num <= 3:
            if bad:
                state[S_ERR_LINE] = lineno
                state[S_ERR_CODE] = ERR_NUMBER
                state[S_LINE] = line
                return ST_ERROR, start, n_out, n_other, n_vals
            unit = state[S_UNIT]
            absx = state[S_ABS_XYZ] != 0.0
            abse = state[S_ABS_E] != 0.0 and absx
            if mask & _F:
                f = val[5]
                if not (f > 0.0):
                    state[S_ERR_LINE] = lineno
                    state[S_ERR_CODE] = ERR_FEED
                    state[S_LINE] = line
                    return ST_ERROR, start, n_out, n_other, n_vals
                state[S_FEED] = f * unit / 60.0
            x0 = state[S_X]
            y0 = state[S_Y]
            z0 = state[S_Z]
            x1 = x0
            y1 = y0
            z1 = z0
            if mask & _X:
                x1 = val[23] * unit + state[S_OFF_X] if absx else x0 + val[23] * unit
            if mask & _Y:
                y1 = val[24] * unit + state[S_OFF_Y] if absx else y0 + val[24] * unit
            if mask & _Z:
                z1 = val[25] * unit + state[S_OFF_Z] if absx else z0 + val[25] * unit
            de = 0.0
            if mask & _E:
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
            if code_num <= 1:
                if x1 != x0 or y1 != y0 or z1 != z0 or de != 0.0:
                    kind = row_kind(x1 - x0, y1 - y0, z1 - z0, de, False, code_num == 0)
                    emit(out, n_out, lineno, tool, x1, y1, z1, de, feed, flow, kind, e_acc)
                    n_out += 1
                state[S_X] = x1
                state[S_Y] = y1
                state[S_Z] = z1
                line = lineno
                pos = nxt
                continue
            # ---- arcs (G2 clockwise, G3 counter-clockwise), XY plane ----
            if state[S_PLANE] != 17.0:
                if mask & _E:  # Python raises for this line: leave E as it was
                    state[S_EGC] = state[S_EGC] - de
                state[S_LINE] = line
                return ST_PYTHON, start, n_out, n_other, n_vals
            has_ij = (mask & (_I | _J)) != 0
            n_new = emit_arc(out, n_out, lineno, tool, x0, y0, z0, x1, y1, z1, de, feed, flow,
                             code_num == 2, has_ij,
                             -(val[8] * unit) if mask & _I else 0.0,
                             -(val[9] * unit) if mask & _J else 0.0,
                             (mask & _R) != 0, val[17] * unit,
                             state[S_ARC_MODE] == 0.0, state[S_ARC_PARAM], e_acc)
            if n_new == ARC_BAD or n_new == ARC_HUGE:
                state[S_ERR_LINE] = lineno
                state[S_ERR_CODE] = ERR_ARC if n_new == ARC_BAD else ERR_ARC_HUGE
                state[S_LINE] = line
                return ST_ERROR, start, n_out, n_other, n_vals
            if n_new == ARC_FULL:
                state[S_LINE] = line
                # undo the E side effect: the kernel re-reads this line after growing
                if mask & _E:
                    state[S_EGC] = state[S_EGC] - de
                return ST_MOVES_FULL, start, n_out, n_other, n_vals
            n_out = n_new
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
            return ST_PYTHON, start, n_out, n_other, n_vals
        # executed here and not recorded; the modal commands (G90/G91, G92, G20/G21,
        # M82/M83) are executed *and* recorded: the events are the reader's modal state
        # for whoever rewrites the file (compensation writes every line in its own modes)
        executed = True
        if c0 == 71:
            if code_num == 90:
                state[S_ABS_XYZ] = 1.0
                executed = False
            elif code_num == 91:
                state[S_ABS_XYZ] = 0.0
                executed = False
            elif code_num == 92:
                executed = False
                unit = state[S_UNIT]
                none = (mask & (_XYZ | _E)) == 0
                if mask & _X or none:
                    state[S_OFF_X] = state[S_X] - (val[23] * unit if mask & _X else 0.0)
                if mask & _Y or none:
                    state[S_OFF_Y] = state[S_Y] - (val[24] * unit if mask & _Y else 0.0)
                if mask & _Z or none:
                    state[S_OFF_Z] = state[S_Z] - (val[25] * unit if mask & _Z else 0.0)
                if mask & _E or none:
                    state[S_EGC] = (val[4] * unit * state[S_E_FACTOR]) if mask & _E else 0.0
            elif code_num == 21:
                state[S_UNIT] = 1.0
                executed = False
            elif code_num == 20:
                state[S_UNIT] = 25.4
                executed = False
            elif code_num == 28:
                any_axis = (mask & _XYZ) != 0
                if mask & _X or not any_axis:
                    state[S_X] = state[S_HOME_X]
                if mask & _Y or not any_axis:
                    state[S_Y] = state[S_HOME_Y]
                if mask & _Z or not any_axis:
                    state[S_Z] = state[S_HOME_Z]
                executed = False  # also an event for the planner
            elif code_num == 17:
                state[S_PLANE] = 17.0
            else:
                executed = False
        else:  # M
            if code_num == 82:
                state[S_ABS_E] = 1.0
                executed = False
            elif code_num == 83:
                state[S_ABS_E] = 0.0
                executed = False
            elif (code_num == 220 and mask & _S) or (code_num == 221
                                                     and (mask & (_S | _T | _D)) == _S):
                # M220 S<pct>, M221 S<pct> (Marlin's M221 T<n> S<pct> targets one tool:
                # Python); a factor that is not positive is an error Python names
                if not (val[18] > 0.0):
                    state[S_LINE] = line
                    return ST_PYTHON, start, n_out, n_other, n_vals
                if code_num == 220:
                    state[S_SPEED_FACTOR] = val[18] / 100.0
                else:
                    state[S_FLOW] = val[18] / 100.0
                executed = False
            else:
                executed = False
        if not executed:
            # G10/G11, M207/M208, M200, G18/G19 change what the kernel does: hand over
            if ((c0 == 71 and (code_num == 10 or code_num == 11 or code_num == 18
                               or code_num == 19))
                    or (c0 == 77 and (code_num == 207 or code_num == 208 or code_num == 200
                                      or (code_num == 221
                                          and (mask & (_S | _T | _D)) != _S)))):
                state[S_LINE] = line
                return ST_PYTHON, start, n_out, n_other, n_vals
            n_other, n_vals = _record_numeric(other, vals, n_other, n_vals, lineno, start, eol,
                                              n_out, c0, code_num, mask, val)
        line = lineno
        pos = nxt
    state[S_LINE] = line
    return ST_DONE, pos, n_out, n_other, n_vals
