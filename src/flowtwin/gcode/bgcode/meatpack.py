"""MeatPack, the G-code character packing of ``.bgcode`` G-code blocks (numba kernels).

MeatPack (Scott Mudge's protocol, see the OctoPrint-MeatPack README) packs the 15 most
frequent G-code characters into 4 bits, two to a byte, low nibble first:
``0``–``9`` → 0–9, ``.`` → 10, space → 11 (``E`` once "no spaces" is on), newline → 12,
``G`` → 13, ``X`` → 14. The nibble 15 says "a full byte follows": low nibble 15 means the
full character comes first and the high nibble's character after it; high nibble 15
means the low nibble's character comes first and the full character after it; the byte
0xFF means two full characters follow. A newline in a low nibble ends the pair. Two
0xFF bytes and a command byte switch modes: 251 packing on, 250 packing off (raw bytes,
used for comment lines), 247 "no spaces" on, 246 off, 249 reset.

In ``.bgcode`` (libbgcode's specification) every G-code block starts packing afresh, with
"no spaces": the spaces of ``G`` lines are left out and a reader puts one back before
every parameter letter (``X Y Z E F I J R S G P W H C A``) of a line that starts with
``G``; empty lines disappear. :func:`unpack` gives the text a reader of the format gets.
:func:`pack` keeps comment lines byte for byte (or drops them), and of a command line the
command without the comment after it and the blanks around it (as PrusaSlicer's writer
does); the command comes back exactly unless it is a ``G`` line whose spacing the reader
cannot restore (then with one space before each parameter; see ``docs/gcode.md``).
"""

from __future__ import annotations

import numpy as np

from flowtwin._jit import njit

__all__ = ["drop_empty_lines", "pack", "unpack"]

_SIGNAL = 0xFF
_ENABLE_PACKING = 251
_DISABLE_PACKING = 250
_RESET_ALL = 249
_ENABLE_NO_SPACES = 247
_DISABLE_NO_SPACES = 246

#: 4-bit code → character (index 11 is a space, or ``E`` with "no spaces").
_CHARS = np.frombuffer(b"0123456789. \nGX", dtype=np.uint8).copy()
#: character → 4-bit code in "no spaces" mode, 15 = not packable.
_CODES = np.full(256, 15, dtype=np.uint8)
for _k, _c in enumerate(b"0123456789.E\nGX"):
    _CODES[_c] = _k
#: parameter letters before which a reader puts a space back in a ``G`` line.
_PARAM = np.zeros(256, dtype=np.bool_)
for _c in b"XYZEFIJRSGPWHCA":
    _PARAM[_c] = True


@njit(cache=True, inline="always")
def _emit(out, o, c, add_space):  # type: ignore[no-untyped-def]
    """Append character ``c`` as a reader of the format does; return (o, add_space)."""
    new_line = False
    if c == 71 and (o == 0 or out[o - 1] == 10):  # 'G' starts a line
        add_space = True
        new_line = True
    elif c == 10:
        add_space = False
    if not new_line and add_space and _PARAM[c] and (o == 0 or out[o - 1] != 32):
        out[o] = 32
        o += 1
    if c != 10 or o == 0 or out[o - 1] != 10:
        out[o] = c
        o += 1
    return o, add_space


@njit(cache=True)
def _unpack(src, out):  # type: ignore[no-untyped-def]
    """Decode one block; return the number of bytes written to ``out`` (or -1: bad command)."""
    o = 0
    packing = False
    no_spaces = False
    signals = 0
    command = False
    full_queue = 0
    held = 0            # character waiting for a full one (low nibble was 15)
    add_space = False
    for k in range(src.shape[0]):
        b = src[k]
        if b == _SIGNAL:
            if signals > 0:
                command = True
                signals = 0
            else:
                signals += 1
            continue
        if command:
            command = False
            if b == _ENABLE_PACKING:
                packing = True
            elif b == _DISABLE_PACKING or b == _RESET_ALL:
                packing = False
            elif b == _ENABLE_NO_SPACES:
                no_spaces = True
            elif b == _DISABLE_NO_SPACES:
                no_spaces = False
            continue
        n_in = 2 if signals > 0 else 1
        for step in range(n_in):
            c = _SIGNAL if (n_in == 2 and step == 0) else b
            if not packing:
                o, add_space = _emit(out, o, c, add_space)
            elif full_queue > 0:
                o, add_space = _emit(out, o, c, add_space)
                if held > 0:
                    o, add_space = _emit(out, o, held, add_space)
                    held = 0
                full_queue -= 1
            else:
                lo = c & 0xF
                hi = c >> 4
                if lo == 0xF:
                    full_queue += 1
                    if hi == 0xF:
                        full_queue += 1
                    else:
                        held = 69 if (hi == 11 and no_spaces) else _CHARS[hi]
                else:
                    ch = 69 if (lo == 11 and no_spaces) else _CHARS[lo]
                    o, add_space = _emit(out, o, ch, add_space)
                    if ch != 10:
                        if hi == 0xF:
                            full_queue += 1
                        else:
                            ch = 69 if (hi == 11 and no_spaces) else _CHARS[hi]
                            o, add_space = _emit(out, o, ch, add_space)
        signals = 0
    return o


def unpack(data: bytes) -> bytes:
    """Decode a MeatPack-encoded G-code block into text (see the module docstring)."""
    src = np.frombuffer(data, dtype=np.uint8)
    out = np.empty(4 * src.shape[0] + 16, dtype=np.uint8)
    n = _unpack(src, out)
    return out[:n].tobytes()


@njit(cache=True)
def _drop_empty(buf, n, out):  # type: ignore[no-untyped-def]
    """Copy the lines of ``buf[:n]`` that hold something besides blanks and a bare ``;``,
    each ending with a newline; return the length written."""
    o = 0
    i = 0
    while i < n:
        j = i
        while j < n and buf[j] != 10:
            j += 1
        s = i
        while s < j and (buf[s] == 32 or buf[s] == 9):
            s += 1
        e = j
        while e > s and (buf[e - 1] == 32 or buf[e - 1] == 9):
            e -= 1
        keep = e > s
        if keep and buf[s] == 59:  # ';' then only blanks?
            t = s + 1
            while t < e and (buf[t] == 32 or buf[t] == 9):
                t += 1
            keep = t < e
        if keep:
            for k in range(i, j):
                out[o] = buf[k]
                o += 1
            out[o] = 10
            o += 1
        i = j + 1
    return o


def drop_empty_lines(text: bytes) -> bytes:
    """The block's text as the format's readers give it: blank lines and lines holding only
    ``;`` removed, every line ending with a newline."""
    src = np.frombuffer(text, dtype=np.uint8)
    out = np.empty(src.shape[0] + 1, dtype=np.uint8)
    n = _drop_empty(src, src.shape[0], out)
    return out[:n].tobytes()


@njit(cache=True)
def _spaced_equals(s, a, b, line, la, lb):  # type: ignore[no-untyped-def]
    """True if a reader turns ``s[a:b]`` (a line starting with ``G``) into ``line[la:lb]``."""
    j = la
    for k in range(a, b):
        c = s[k]
        if k > a and _PARAM[c] and s[k - 1] != 32:
            if j >= lb or line[j] != 32:
                return False
            j += 1
        if j >= lb or line[j] != c:
            return False
        j += 1
    return j == lb


@njit(cache=True)
def _put_pair(out, o, c1, c2):  # type: ignore[no-untyped-def]
    p1 = _CODES[c1]
    p2 = _CODES[c2]
    if p1 != 15 and p2 != 15:
        out[o] = p1 | (p2 << 4)
        return o + 1
    if p1 != 15:
        out[o] = p1 | 0xF0
        out[o + 1] = c2
        return o + 2
    if p2 != 15:
        out[o] = 0x0F | (p2 << 4)
        out[o + 1] = c1
        return o + 2
    out[o] = 0xFF
    out[o + 1] = c1
    out[o + 2] = c2
    return o + 3


@njit(cache=True)
def _pack_chars(tmp, m, out, o):  # type: ignore[no-untyped-def]
    """Pack ``tmp[:m]`` (a line ending with a newline) two characters to a byte."""
    k = 0
    while k < m:
        c1 = tmp[k]
        c2 = tmp[k + 1] if k + 1 < m else 10   # a newline pads the last pair
        o = _put_pair(out, o, c1, c2)
        k += 2
    return o


@njit(cache=True)
def _pack(src, keep_comments, out, tmp):  # type: ignore[no-untyped-def]
    n = src.shape[0]
    o = 0
    for cmd in (_ENABLE_PACKING, _ENABLE_NO_SPACES):
        out[o] = _SIGNAL
        out[o + 1] = _SIGNAL
        out[o + 2] = cmd
        o += 3
    packing = True
    i = 0
    while i < n:
        j = i
        while j < n and src[j] != 10:
            j += 1
        e = j
        if e > i and src[e - 1] == 13:
            e -= 1
        s = i
        while s < e and (src[s] == 32 or src[s] == 9):
            s += 1
        t = e
        while t > s and (src[t - 1] == 32 or src[t - 1] == 9):
            t -= 1
        if s == t:                      # blank: readers drop it anyway
            i = j + 1
            continue
        if src[s] == 59:                # comment line: raw bytes, packing off
            if keep_comments:
                if packing:
                    out[o] = _SIGNAL
                    out[o + 1] = _SIGNAL
                    out[o + 2] = _DISABLE_PACKING
                    o += 3
                    packing = False
                for k in range(i, e):
                    out[o] = src[k]
                    o += 1
                out[o] = 10
                o += 1
            i = j + 1
            continue
        if not packing:
            out[o] = _SIGNAL
            out[o + 1] = _SIGNAL
            out[o + 2] = _ENABLE_PACKING
            o += 3
            packing = True
        # the command: a comment after it and the blanks around it are not kept
        c = s
        while c < t and src[c] != 59:
            c += 1
        while c > s and (src[c - 1] == 32 or src[c - 1] == 9):
            c -= 1
        m = 0
        if src[s] == 71 and s + 1 < c and 48 <= src[s + 1] <= 57:
            # without spaces, if the reader puts exactly these spaces back; else as written
            for k in range(s, c):
                if src[k] != 32:
                    tmp[m] = src[k]
                    m += 1
            if not _spaced_equals(tmp, 0, m, src, s, c):
                m = 0
                for k in range(s, c):
                    tmp[m] = src[k]
                    m += 1
                if not _spaced_equals(tmp, 0, m, src, s, c):
                    # neither: without spaces (the reader gives one space per parameter)
                    m = 0
                    for k in range(s, c):
                        if src[k] != 32 and src[k] != 9:
                            tmp[m] = src[k]
                            m += 1
        else:
            for k in range(s, c):
                tmp[m] = src[k]
                m += 1
        tmp[m] = 10
        m += 1
        o = _pack_chars(tmp, m, out, o)
        i = j + 1
    return o


def pack(text: bytes, *, keep_comments: bool) -> bytes:
    """MeatPack-encode one G-code block's text.

    Parameters
    ----------
    text
        Whole lines of G-code (at most :data:`~flowtwin.gcode.bgcode.format.MAX_GCODE_BLOCK_BYTES`
        is what a block holds, but any length works).
    keep_comments
        Keep comment lines (encoding ``MEATPACK_COMMENTS``); otherwise they are dropped.

    Returns
    -------
    bytes
        The encoded block; :func:`unpack` gives back the text (see the module docstring
        for the spacing of ``G`` lines and the blank lines it does not keep).
    """
    src = np.frombuffer(text, dtype=np.uint8)
    n = src.shape[0]
    out = np.empty(2 * n + 3 * (n // 2) + 64, dtype=np.uint8)
    tmp = np.empty(n + 2, dtype=np.uint8)
    size = _pack(src, keep_comments, out, tmp)
    # libbgcode's decoder (PrusaSlicer, the bgcode tool) sizes its output buffer at twice
    # the encoded block and loses a character when it must grow it right after putting a
    # space back; pad the block with newline pairs (which decode to nothing after the
    # last newline) so that the text never outgrows twice its encoding
    decoded = _unpack(out[:size], np.empty(4 * size + 16, dtype=np.uint8))
    need = decoded // 2 + 2 - size
    if need > 0:
        tail = np.empty(need + 3, dtype=np.uint8)
        tail[:3] = (_SIGNAL, _SIGNAL, _ENABLE_PACKING)
        tail[3:] = 0xCC
        return out[:size].tobytes() + tail.tobytes()
    return out[:size].tobytes()
