"""Compiled kernels of the writer: every piece as it will be written and read back, and the
text of the rewritten file.

:func:`lay_out` walks every piece of the draft in file order with the reader's own state
(toolhead position, G-code E coordinate, modal feed) and decides, for the pieces of a
rewritten line, which words they carry and with which decimal numbers: coordinates as
integers on a 10⁻⁵ mm grid (10⁻⁹ where the original coordinate has more decimals), E on
the file's E grid, F on a 10⁻⁵ mm/min grid. It also gives the row the reader will make of
every piece, computed with the reader's own arithmetic (a decimal ``m·10⁻ᵏ`` reads as the
correctly rounded ``m / 10ᵏ``; toolhead = coordinate + offset; absolute ``E`` gives
``de = E − E_before``; feed = ``F / 60 · M220``), so the draft's move table is the table
the written file reads back as, bit for bit wherever the modes are absolute.
:func:`write_text` then renders the words as bytes between the untouched lines.
"""

from __future__ import annotations

import numpy as np

from flowtwin._jit import njit

__all__ = ["lay_out", "write_text"]

# word flags per piece
W_X, W_Y, W_Z, W_E, W_F = 1, 2, 4, 8, 16
#: Decimals of coordinates and feeds (the finer grid where a coordinate needs it).
XYZ_DECIMALS = 5
FINE_DECIMALS = 9
_K_TRAVEL, _K_EXTRUDE, _K_RETRACT, _K_XY, _K_Z, _K_RAPID = 1, 2, 4, 8, 16, 128


@njit(cache=True)
def _pow10(k: int) -> float:
    v = 1.0
    for _ in range(k):
        v *= 10.0
    return v


@njit(cache=True)
def lay_out(piece_row, xyz, e_grid, piece_f, row_changed, row_first_piece, row_last_piece,  # type: ignore[no-untyped-def]
            orig_xyz, orig_de, orig_feed, orig_kind, abs_xyz, abs_e, offset, speed_factor,
            e_before, row_e, e_reset, g92_after, start_xyz, e_decimals,
            out_xyz, out_de, out_feed, out_kind, flags, q_xyz, q_dec, q_e, q_f, g92_val,
            g92_has):
    """Words of every piece of a rewritten line and the row the reader makes of every piece.

    The written file's E coordinate runs ``delta`` grid units ahead of the original's
    after a rewritten line whose E differs; the next rewritten line continues from there,
    and where the original's coordinate is needed again (``g92_after`` of the line's last
    row) a ``G92 E`` sets it back.

    Parameters
    ----------
    piece_row
        Original row of every piece, ``(n,)``.
    xyz, e_grid, piece_f
        Piece ends (toolhead, mm), E (grid units), own feed (mm/min, NaN: the line's).
    row_changed
        Original row is written anew (every row of a rewritten line), ``(n_rows,)``.
    row_first_piece, row_last_piece
        Piece is the first / last of its line, ``(n,)`` (for unchanged rows: both).
    orig_xyz, orig_de, orig_feed, orig_kind
        The original rows as read, ``(n_rows, ...)``.
    abs_xyz, abs_e, offset, speed_factor, e_before, row_e
        The modes and E of every original row
        (:class:`~flowtwin.compensation.original.OriginalFile`).
    e_reset
        A ``G92 E`` of the original precedes the row, ``(n_rows,)``.
    g92_after
        Restore the original E coordinate after the line ending with this row (if it
        differs), ``(n_rows,)``.
    start_xyz
        Toolhead before the first row.
    e_decimals
        Decimals of the E grid.
    out_xyz, out_de, out_feed, out_kind
        Output: the reader's row of every piece.
    flags, q_xyz, q_dec, q_e, q_f
        Output: written words (``W_*`` bits), coordinate integers and their decimals,
        E integer (the coordinate in absolute E, the amount in relative), F integer.
    g92_val, g92_has
        Output: the ``G92 E`` value written after a piece (the last of its line), and
        whether one is.
    """
    n = piece_row.shape[0]
    px = start_xyz[0]
    py = start_xyz[1]
    pz = start_xyz[2]
    e_scale = _pow10(e_decimals)
    xyz_scale = _pow10(XYZ_DECIMALS)
    fine_scale = _pow10(FINE_DECIMALS)
    delta = 0                 # written E coordinate − original, grid units
    e_int = 0                 # E coordinate of the written file, grid units
    line_f_q = 0
    prev_row = -1
    for j in range(n):
        r = piece_row[j]
        g92_has[j] = False
        if r != prev_row and e_reset[r]:
            delta = 0
        prev_row = r
        if not row_changed[r]:
            # an untouched line reads back as it did (a G92 E before it where needed)
            if abs_xyz[r]:
                px = orig_xyz[r, 0]
                py = orig_xyz[r, 1]
                pz = orig_xyz[r, 2]
            else:
                prev = orig_xyz[r - 1] if r > 0 else start_xyz
                px = px + (orig_xyz[r, 0] - prev[0])
                py = py + (orig_xyz[r, 1] - prev[1])
                pz = pz + (orig_xyz[r, 2] - prev[2])
            if abs_e[r] and orig_de[r] != 0.0:
                delta = 0
            out_xyz[j, 0] = px
            out_xyz[j, 1] = py
            out_xyz[j, 2] = pz
            out_de[j] = orig_de[r]
            out_feed[j] = orig_feed[r]
            out_kind[j] = orig_kind[r]
            flags[j] = 0
            continue
        factor = speed_factor[r]
        first = row_first_piece[j]
        if first:
            # the line's own feed, recovered on the F grid from the reader's feed
            line_f_q = int(np.rint(orig_feed[r] * 60.0 / factor * xyz_scale))
            e_int = e_before[r] + delta
        f_q = line_f_q
        if not np.isnan(piece_f[j]):
            f_q = int(np.rint(piece_f[j] * xyz_scale))
        fl = W_F if (first or f_q != q_f[j - 1]) else 0
        q_f[j] = f_q
        last = row_last_piece[j]
        nx = px
        ny = py
        nz = pz
        for k in range(3):
            target = orig_xyz[r, k] if last else xyz[j, k]
            cur = px if k == 0 else (py if k == 1 else pz)
            if abs(target - cur) <= 1e-9:
                continue
            if abs_xyz[r]:
                v = target - offset[r, k]
                q = np.rint(v * xyz_scale)
                dec = XYZ_DECIMALS
                if last and abs(q - v * xyz_scale) > 1e-4:  # the original has more decimals
                    q = np.rint(v * fine_scale)
                    dec = FINE_DECIMALS
                val = q / (xyz_scale if dec == XYZ_DECIMALS else fine_scale) + offset[r, k]
            else:
                q = np.rint((target - cur) * xyz_scale)
                dec = XYZ_DECIMALS
                if q == 0.0:
                    continue
                val = cur + q / xyz_scale
            q_xyz[j, k] = np.int64(q)
            q_dec[j, k] = dec
            fl |= 1 << k
            if k == 0:
                nx = val
            elif k == 1:
                ny = val
            else:
                nz = val
        e = e_grid[j]
        de = 0.0
        if e != 0:
            fl |= W_E
            before = e_int / e_scale
            e_int += e
            if abs_e[r]:
                q_e[j] = e_int
                de = e_int / e_scale - before
            else:
                q_e[j] = e
                de = e / e_scale
        flags[j] = fl
        f_val = f_q / xyz_scale
        out_feed[j] = f_val / 60.0 * factor
        out_de[j] = de
        kk = _K_EXTRUDE if de > 0.0 else (_K_RETRACT if de < 0.0 else _K_TRAVEL)
        if nx != px or ny != py:
            kk |= _K_XY
        if nz != pz:
            kk |= _K_Z
        if orig_kind[r] & _K_RAPID:
            kk |= _K_RAPID
        out_kind[j] = kk
        px = nx
        py = ny
        pz = nz
        out_xyz[j, 0] = px
        out_xyz[j, 1] = py
        out_xyz[j, 2] = pz
        if last:
            orig_end = e_before[r] + row_e[r]
            delta = e_int - orig_end
            if g92_after[r] and delta != 0:
                g92_val[j] = orig_end
                g92_has[j] = True
                delta = 0


@njit(cache=True)
def _put(buf, n, b):  # type: ignore[no-untyped-def]
    buf[n] = b
    return n + 1


@njit(cache=True)
def _put_int(buf, n, v):  # type: ignore[no-untyped-def]
    if v == 0:
        buf[n] = 48
        return n + 1
    digits = np.empty(20, dtype=np.uint8)
    k = 0
    while v > 0:
        digits[k] = 48 + v % 10
        v //= 10
        k += 1
    for i in range(k - 1, -1, -1):
        buf[n] = digits[i]
        n += 1
    return n


@njit(cache=True)
def _put_decimal(buf, n, q, dec):  # type: ignore[no-untyped-def]
    """``q·10⁻ᵈᵉᶜ`` as text, trailing zeros (and a bare point) dropped."""
    if q < 0:
        n = _put(buf, n, 45)
        q = -q
    p = 1
    for _ in range(dec):
        p *= 10
    whole = q // p
    frac = q % p
    n = _put_int(buf, n, whole)
    if frac != 0:
        n = _put(buf, n, 46)
        k = dec
        while frac % 10 == 0:
            frac //= 10
            k -= 1
        digits = np.empty(20, dtype=np.uint8)
        for i in range(k - 1, -1, -1):
            digits[i] = 48 + frac % 10
            frac //= 10
        for i in range(k):
            n = _put(buf, n, digits[i])
    return n


@njit(cache=True, nogil=True)
def write_text(text, line_start, changed_line, line_p0, line_p1, line_code, line_f_restore,  # type: ignore[no-untyped-def]
               line_g92, line_has_g92, flags, q_xyz, q_dec, q_e, q_f, e_decimals, buf):
    """The rewritten file: untouched lines copied, rewritten lines as their pieces.

    Parameters
    ----------
    text, line_start
        The original bytes and line starts (``n_lines + 1``).
    changed_line
        1-based numbers of the rewritten lines, ascending, ``(m,)``.
    line_p0, line_p1
        Pieces of each rewritten line, ``(m,)``.
    line_code
        ``0``: ``G0``, ``1``: ``G1``, ``(m,)``.
    line_f_restore
        F to restore after the line (integer on the F grid), or −1, ``(m,)``.
    line_g92, line_has_g92
        ``G92 E`` to write after the line (E grid), and whether, ``(m,)``.
    flags, q_xyz, q_dec, q_e, q_f
        Words of every piece (:func:`lay_out`).
    e_decimals
        Decimals of the E grid.
    buf
        Output buffer (large enough); returns the number of bytes written.
    """
    n = 0
    n_lines = line_start.shape[0] - 1
    src = 0  # next original byte to copy
    for i in range(changed_line.shape[0]):
        ln = changed_line[i]
        a = line_start[ln - 1]
        b = line_start[ln]
        for k in range(src, a):
            buf[n] = text[k]
            n += 1
        src = b
        # the line's ending and its comment (from ';' to the end, without the ending)
        end = b
        crlf = False
        has_nl = end > a and text[end - 1] == 10
        if has_nl:
            end -= 1
            if end > a and text[end - 1] == 13:
                end -= 1
                crlf = True
        c0 = end
        for k in range(a, end):
            if text[k] == 59:
                c0 = k
                break
        n_out = line_p1[i] - line_p0[i] + (1 if line_f_restore[i] >= 0 else 0) \
            + (1 if line_has_g92[i] else 0)
        written = 0
        for j in range(line_p0[i], line_p1[i]):
            n = _put(buf, n, 71)
            n = _put(buf, n, 49 if line_code[i] == 1 else 48)
            fl = flags[j]
            for k in range(3):
                if fl & (1 << k):
                    n = _put(buf, n, 32)
                    n = _put(buf, n, 88 + k)
                    n = _put_decimal(buf, n, q_xyz[j, k], q_dec[j, k])
            if fl & 8:
                n = _put(buf, n, 32)
                n = _put(buf, n, 69)
                n = _put_decimal(buf, n, q_e[j], e_decimals)
            if fl & 16:
                n = _put(buf, n, 32)
                n = _put(buf, n, 70)
                n = _put_decimal(buf, n, q_f[j], XYZ_DECIMALS)
            if j == line_p0[i] and c0 < end:
                n = _put(buf, n, 32)
                for k in range(c0, end):
                    buf[n] = text[k]
                    n += 1
            written += 1
            if written < n_out or has_nl:
                if crlf:
                    n = _put(buf, n, 13)
                n = _put(buf, n, 10)
        if line_f_restore[i] >= 0:
            n = _put(buf, n, 71)
            n = _put(buf, n, 49)
            n = _put(buf, n, 32)
            n = _put(buf, n, 70)
            n = _put_decimal(buf, n, line_f_restore[i], XYZ_DECIMALS)
            written += 1
            if written < n_out or has_nl:
                if crlf:
                    n = _put(buf, n, 13)
                n = _put(buf, n, 10)
        if line_has_g92[i]:
            for c in (71, 57, 50, 32, 69):
                n = _put(buf, n, c)
            n = _put_decimal(buf, n, line_g92[i], e_decimals)
            written += 1
            if has_nl:
                if crlf:
                    n = _put(buf, n, 13)
                n = _put(buf, n, 10)
    for k in range(src, line_start[n_lines]):
        buf[n] = text[k]
        n += 1
    return n
