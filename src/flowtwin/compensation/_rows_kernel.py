"""Compiled kernels of the writer: the reader's rows of the written file in one pass, and
the original rows whose line is rewritten (:func:`changed_rows`).

:func:`fill_rows` fills the move table (:data:`flowtwin.gcode.moves.MOVE_DTYPE`) the
written draft reads back as, from the pieces' laid-out positions, E and feeds
(:func:`flowtwin.compensation._write_kernel.lay_out`) and their rows' other columns: the
running E of every tool summed in file order as the reader sums it (``numpy.cumsum``'s
order), and every row's line number in the written file (its line's, shifted by the lines
the rewritten lines before it grew by, plus its place among its line's pieces).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = ["changed_rows", "fill_rows", "g92_after"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

#: Tool numbers are int16: a running E for each.
_TOOLS = 1 << 16


@njit(cache=True)
def fill_rows(out, row, src, xyz, de, feed, kind, changed_lines, shift_after,  # type: ignore[no-untyped-def]
              line_first, changed_piece) -> None:
    """Fill ``out`` (``(n,)`` move rows, zeroed) for the ``n`` pieces.

    Parameters
    ----------
    out
        The rows to fill, ``MOVE_DTYPE``, shape ``(n,)``.
    row
        Row of the draft's table of every piece, shape ``(n,)``.
    src
        The draft's table (``MOVE_DTYPE``): layer, flow, tool, feature and line of every
        piece's row.
    xyz, de, feed, kind
        Every piece's end position ``(n, 3)``, E, feed (mm/s) and kind as written.
    changed_lines
        Rewritten lines, ascending, shape ``(c,)``.
    shift_after
        Lines the written file has gained after each rewritten line, shape ``(c,)``.
    line_first, changed_piece
        Pieces that start a rewritten line, pieces of a rewritten line, shape ``(n,)``.
    """
    n = row.shape[0]
    e_tool = np.zeros(_TOOLS)
    seen = np.zeros(_TOOLS, dtype=np.bool_)
    k = 0  # rewritten lines before the piece's line
    last_line = -1
    first_idx = 0
    c = changed_lines.shape[0]
    for i in range(n):
        r = row[i]
        out[i]["x"] = xyz[i, 0]
        out[i]["y"] = xyz[i, 1]
        out[i]["z"] = xyz[i, 2]
        out[i]["de"] = de[i]
        out[i]["feed_mm_s"] = feed[i]
        out[i]["kind"] = kind[i]
        out[i]["layer"] = src[r]["layer"]
        out[i]["flow"] = src[r]["flow"]
        tool = src[r]["tool"]
        out[i]["tool"] = tool
        out[i]["feature"] = src[r]["feature"]
        t = int(tool) + (_TOOLS >> 1)
        if seen[t]:
            e_tool[t] = e_tool[t] + de[i]
        else:  # (the first value itself, as a cumulative sum starts: keeps −0.0)
            e_tool[t] = de[i]
            seen[t] = True
        out[i]["e"] = e_tool[t]
        line = int(src[r]["line"])
        if line < last_line:  # out of order: search afresh
            k = 0
        last_line = line
        while k < c and changed_lines[k] < line:
            k += 1
        before = shift_after[k - 1] if k > 0 else 0
        if line_first[i]:
            first_idx = i
        within = i - first_idx if changed_piece[i] else 0
        out[i]["line"] = np.int32(line + before + within)


@njit(cache=True)
def changed_rows(row, n_rows, xyz, src, e_grid, row_e, feed, piece_feed):  # type: ignore[no-untyped-def]
    """Original rows whose line must be rewritten, shape ``(n_rows,)``: cut into other
    than one piece, or its one piece moved (by more than 10⁻⁹ mm on an axis) or given
    other E, or a feed written on the row or one of its pieces.

    Parameters
    ----------
    row
        Original row of every piece (non-decreasing), shape ``(n,)``.
    n_rows
        Original rows.
    xyz, e_grid, piece_feed
        Every piece's end position ``(n, 3)``, E (grid units) and feed (``nan``: none).
    src
        The original rows (``MOVE_DTYPE``): their end positions.
    row_e, feed
        Every original row's E (grid units) and written feed (``nan``: none).
    """
    out = np.zeros(n_rows, dtype=np.bool_)
    n = row.shape[0]
    p = 0
    for r in range(n_rows):
        start = p
        while p < n and row[p] == r:
            p += 1
        count = p - start
        if count != 1:
            changed = True
        else:
            changed = (abs(xyz[start, 0] - src[r]["x"]) > 1e-9
                       or abs(xyz[start, 1] - src[r]["y"]) > 1e-9
                       or abs(xyz[start, 2] - src[r]["z"]) > 1e-9
                       or e_grid[start] != row_e[r])
        if np.isfinite(feed[r]):
            changed = True
        for q in range(start, p):
            if np.isfinite(piece_feed[q]):
                changed = True
        out[r] = changed
    return out


@njit(cache=True)
def g92_after(line_inert: BoolArray, abs_e: BoolArray, row_line: IntArray,
              changed_lines: IntArray, out: BoolArray) -> bool:
    """Mark in ``out`` (zeroed, ``(n_rows,)``) the last row of every rewritten line
    whose next line that is not inert (1-based ``line_inert[l − 1]`` false) is not
    rewritten and is read in absolute E (``abs_e`` of the first row at or after it, or
    of the last row). One merge over lines, rows and rewritten lines, all ascending.

    Returns False (``out`` untouched) when ``row_line`` is not in order or
    ``changed_lines`` not strictly ascending: the caller then searches as before.
    """
    n_rows = row_line.shape[0]
    n_ch = changed_lines.shape[0]
    for i in range(1, n_rows):
        if row_line[i] < row_line[i - 1]:
            return False
    for k in range(1, n_ch):
        if changed_lines[k] <= changed_lines[k - 1]:
            return False
    n_lines = line_inert.shape[0]
    nxt = 0  # candidate next line (1-based), never decreasing
    j = 0  # first rewritten line ≥ nxt
    at = 0  # first row whose line is ≥ nxt
    last = 0  # first row whose line is > the rewritten line
    for k in range(n_ch):
        c = changed_lines[k]
        if nxt <= c:
            nxt = c + 1
        while nxt <= n_lines and line_inert[nxt - 1]:
            nxt += 1
        if nxt > n_lines:
            break  # no line after it may read E (nor after any later one)
        while j < n_ch and changed_lines[j] < nxt:
            j += 1
        if j < n_ch and changed_lines[j] == nxt:
            continue
        while at < n_rows and row_line[at] < nxt:
            at += 1
        if not abs_e[min(at, n_rows - 1)]:
            continue
        while last < n_rows and row_line[last] <= c:
            last += 1
        out[last - 1 if last >= 1 else n_rows - 1] = True
    return True
