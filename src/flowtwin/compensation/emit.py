"""Writing a draft: the words of every piece, the move table it reads back as, the file.

A rewritten line becomes one line per piece, ``G0``/``G1`` as written (an arc becomes the
``G1`` chords the reader split it into), every piece in the line's own modes
(:mod:`flowtwin.compensation.original`): absolute coordinates on a 10⁻⁵ mm grid
(``G-code = toolhead − G92 offset``; the last piece ends exactly where the line did),
relative steps on the 10⁻⁵ mm grid adding up to the line's own step, E from whole grid
units, F on the first piece and wherever a piece has its own feed (the line's F is
restored after it). The line's comment stays on its first piece.

**Absolute E.** A rewritten stretch of lines whose E adds up to a different amount than
the original's leaves the written E coordinate ``δ`` ahead; the next rewritten line goes
on from there, and where the file needs the original coordinate again — before a line
that may carry an E word and is not rewritten — a ``G92 E<original coordinate>`` follows
the stretch. Untouched lines are copied byte for byte.

:func:`lay_out_draft` computes all words once, with the rows the reader will make of them
(:mod:`flowtwin.compensation._write_kernel`); :func:`draft_table` is the move table of
the written file without writing it (the twin simulates drafts in memory) and
:func:`write_draft` writes the file atomically.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from flowtwin.atomic import atomic_write_bytes
from flowtwin.compensation._rows_kernel import fill_rows, g92_after
from flowtwin.compensation._write_kernel import XYZ_DECIMALS, lay_out, write_text
from flowtwin.compensation.original import OriginalFile, check_rewritable
from flowtwin.errors import GcodeError
from flowtwin.gcode import gz
from flowtwin.gcode._columns import fill_columns
from flowtwin.gcode.moves import MOVE_DTYPE, Event, MoveKind, MoveTable

if TYPE_CHECKING:
    from flowtwin.compensation.draft import Draft

__all__ = ["Layout", "check_layout", "draft_table", "draft_text", "encode_draft", "lay_out_draft",
           "store_text", "write_draft"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


@dataclass(frozen=True, slots=True)
class Layout:
    """A draft as it will be written.

    Attributes
    ----------
    rows
        The move rows the written file reads back as (:data:`MOVE_DTYPE`), one per piece.
    changed_lines
        Original line numbers rewritten, ascending, shape ``(m,)``.
    line_p0, line_p1
        Pieces of every rewritten line, shape ``(m,)``.
    line_code
        ``1``: written as ``G1``, ``0``: as ``G0``, shape ``(m,)``.
    line_f_restore
        F restored after the line (F grid integer), −1: none, shape ``(m,)``.
    line_g92, line_has_g92
        ``G92 E`` written after the line (E grid) and whether, shape ``(m,)``.
    flags, q_xyz, q_dec, q_e, q_f
        Words of every piece (see :func:`flowtwin.compensation._write_kernel.lay_out`).
    layer_z
        Z of every layer the reader will find (mm).
    row_changed
        Original rows whose line is rewritten, shape ``(n_rows,)``.
    """

    rows: npt.NDArray[np.void]
    changed_lines: IntArray
    line_p0: IntArray
    line_p1: IntArray
    line_code: IntArray
    line_f_restore: IntArray
    line_g92: IntArray
    line_has_g92: BoolArray
    flags: npt.NDArray[np.int8]
    q_xyz: IntArray
    q_dec: npt.NDArray[np.int8]
    q_e: IntArray
    q_f: IntArray
    layer_z: list[float]
    row_changed: BoolArray

    @property
    def lines_rewritten(self) -> int:
        """Original lines replaced by pieces."""
        return int(self.changed_lines.size)


def lay_out_draft(draft: Draft, *, check: bool = True) -> Layout:
    """The words of every piece of ``draft`` and the rows the written file reads back as.

    ``check``: refuse lines that cannot be rewritten (for the file to write; a table to
    simulate needs no check).

    Raises
    ------
    GcodeError
        A line to rewrite carries a line number or checksum, or a relative step that is
        not on the 10⁻⁵ mm grid.
    """
    original = draft.original
    table = draft.table
    mv = table.moves
    n_rows = len(table)
    n = len(draft)
    row_line = np.asarray(mv["line"], dtype=np.int64)
    changed_rows = draft.changed_rows()
    changed_lines = _distinct_sorted(row_line[changed_rows])
    row_changed = np.isin(row_line, changed_lines) if changed_lines.size else \
        np.zeros(n_rows, dtype=bool)
    if check:
        check_rewritable(original, changed_lines)
        _check_relative_steps(draft, row_changed)
    piece_row = draft.row
    piece_line = row_line[piece_row]
    first_piece = np.concatenate(([True], piece_line[1:] != piece_line[:-1])) if n else \
        np.zeros(0, dtype=bool)
    last_piece = np.concatenate((piece_line[1:] != piece_line[:-1], [True])) if n else \
        np.zeros(0, dtype=bool)
    # a piece's own feed, else its row's (the guard), else the line's (NaN)
    piece_f = np.where(np.isfinite(draft.piece_feed_mm_min), draft.piece_feed_mm_min,
                       draft.feed_mm_min[piece_row])
    g92_after = _g92_after(original, row_line, changed_lines)
    orig_xyz = np.column_stack([mv["x"], mv["y"], mv["z"]]).astype(np.float64)
    out_xyz = np.empty((n, 3))
    out_de = np.empty(n)
    out_feed = np.empty(n)
    out_kind = np.empty(n, dtype=np.uint8)
    flags = np.zeros(n, dtype=np.int8)
    q_xyz = np.zeros((n, 3), dtype=np.int64)
    q_dec = np.zeros((n, 3), dtype=np.int8)
    q_e = np.zeros(n, dtype=np.int64)
    q_f = np.zeros(n, dtype=np.int64)
    g92_val = np.zeros(n, dtype=np.int64)
    g92_has = np.zeros(n, dtype=bool)
    lay_out(piece_row, np.ascontiguousarray(draft.xyz_mm, dtype=np.float64),
            draft.e_grid.astype(np.int64), piece_f.astype(np.float64), row_changed,
            first_piece, last_piece, orig_xyz, np.asarray(mv["de"], dtype=np.float64),
            np.asarray(mv["feed_mm_s"], dtype=np.float64), np.asarray(mv["kind"]),
            original.abs_xyz, original.abs_e, original.offset_xyz, original.speed_factor,
            original.e_before, original.row_e, original.e_reset, g92_after,
            np.asarray(table.start_xyze[:3], dtype=np.float64), original.e_decimals,
            out_xyz, out_de, out_feed, out_kind, flags, q_xyz, q_dec, q_e, q_f, g92_val,
            g92_has)
    # per rewritten line
    changed_piece = row_changed[piece_row]
    starts = np.flatnonzero(first_piece & changed_piece)
    ends = np.flatnonzero(last_piece & changed_piece) + 1
    first_row = piece_row[starts]
    kind0 = np.asarray(mv["kind"])[first_row]
    line_code = np.where(((kind0 & MoveKind.RAPID) != 0) & ((kind0 & MoveKind.ARC) == 0),
                         0, 1).astype(np.int64)
    line_f = np.rint(np.asarray(mv["feed_mm_s"], dtype=np.float64)[first_row] * 60.0
                     / original.speed_factor[first_row] * 10.0 ** XYZ_DECIMALS
                     ).astype(np.int64)
    f_restore = np.where(q_f[ends - 1] != line_f, line_f, -1).astype(np.int64)
    rows, layer_z = _rows(draft, out_xyz, out_de, out_feed, out_kind, changed_lines, starts,
                          ends,
                 f_restore, g92_has[ends - 1] if ends.size else np.zeros(0, dtype=bool),
                 first_piece & changed_piece, changed_piece)
    return Layout(rows, changed_lines.astype(np.int64), starts.astype(np.int64),
                  ends.astype(np.int64), line_code, f_restore, g92_val[ends - 1],
                  g92_has[ends - 1], flags, q_xyz, q_dec, q_e, q_f, layer_z, row_changed)


def check_layout(draft: Draft, layout: Layout) -> None:
    """Refuse a layout whose rewritten lines cannot be written: a line number or checksum
    on one of them, a relative step off the 10⁻⁵ mm grid.

    Raises
    ------
    GcodeError
        Naming the first such line.
    """
    check_rewritable(draft.original, layout.changed_lines)
    _check_relative_steps(draft, layout.row_changed)


def _distinct_sorted(values: IntArray) -> IntArray:
    """``np.unique(values)``; in one pass when the values are already in order (the
    lines of a file's rows)."""
    if values.size < 2 or not np.all(values[1:] >= values[:-1]):
        return np.unique(values)
    return values[np.concatenate(([True], values[1:] != values[:-1]))]


def _check_relative_steps(draft: Draft, row_changed: BoolArray) -> None:
    """A relative (``G91``) line is cut on a 10⁻⁵ mm grid: its step must be on it."""
    rel = np.flatnonzero(row_changed & ~draft.original.abs_xyz)
    if rel.size == 0:
        return
    mv = draft.table.moves
    end = np.column_stack([mv["x"], mv["y"], mv["z"]]).astype(np.float64)
    start = np.vstack([np.asarray(draft.table.start_xyze[:3], dtype=np.float64), end[:-1]])
    step = (end - start)[rel] * 10.0 ** XYZ_DECIMALS
    bad = np.abs(step - np.rint(step)) > 1e-3
    if np.any(bad):
        r, k = np.argwhere(bad)[0]
        raise GcodeError("relative step with more than 5 decimals", source=draft.original.source,
                         line=int(mv["line"][rel[r]]), field="XYZ"[k],
                         value=float((end - start)[rel[r], k]), allowed="at most 5 decimals")


def _g92_after(original: OriginalFile, row_line: IntArray, changed_lines: IntArray
               ) -> BoolArray:
    """Rows that end a rewritten stretch before a line that may read the E coordinate
    (``G92 E`` restores it there when it differs)."""
    out = np.zeros(row_line.size, dtype=bool)
    if changed_lines.size == 0:
        return out
    if g92_after(original.line_inert, original.abs_e, np.ascontiguousarray(row_line,
                 dtype=np.int64), np.ascontiguousarray(changed_lines, dtype=np.int64), out):
        return out
    return _g92_after_searched(original, row_line, changed_lines, out)


def _g92_after_searched(original: OriginalFile, row_line: IntArray, changed_lines: IntArray,
                        out: BoolArray) -> BoolArray:
    """:func:`_g92_after` by binary searches (lines or rows out of order)."""
    unsafe = np.flatnonzero(~original.line_inert) + 1  # line numbers
    k = np.searchsorted(unsafe, changed_lines, side="right")
    has_next = k < unsafe.size
    nxt = unsafe[np.minimum(k, unsafe.size - 1)] if unsafe.size else changed_lines
    j = np.searchsorted(changed_lines, nxt)
    next_changed = has_next & (j < changed_lines.size) & (
        changed_lines[np.minimum(j, changed_lines.size - 1)] == nxt)
    # only where the line read there is in absolute E (the mode of the next row)
    rows_at = np.searchsorted(row_line, nxt, side="left")
    abs_there = original.abs_e[np.minimum(rows_at, row_line.size - 1)]
    need = has_next & ~next_changed & abs_there
    # the last row of each such line
    last_row = np.searchsorted(row_line, changed_lines[need], side="right") - 1
    out[last_row] = True
    return out


def _rows(draft: Draft, xyz: FloatArray, de: FloatArray, feed: FloatArray,
          kind: npt.NDArray[np.uint8], changed_lines: IntArray, starts: IntArray,
          ends: IntArray, f_restore: IntArray, g92: BoolArray, line_first: BoolArray,
          changed_piece: BoolArray) -> tuple[npt.NDArray[np.void], list[float]]:
    """The reader's rows of the written file (line numbers of the written file)."""
    mv = draft.table.moves
    r = draft.row
    n = r.size
    out = np.zeros(n, dtype=MOVE_DTYPE)
    # line numbers: every rewritten line grows by its pieces, an F restore and a G92
    grow = (ends - starts) + (f_restore >= 0) + g92 - 1
    fill_rows(out, np.ascontiguousarray(r, dtype=np.int64), mv,
              np.ascontiguousarray(xyz, dtype=np.float64),
              np.ascontiguousarray(de, dtype=np.float64),
              np.ascontiguousarray(feed, dtype=np.float64),
              np.ascontiguousarray(kind, dtype=np.uint8),
              np.ascontiguousarray(changed_lines, dtype=np.int64),
              np.cumsum(grow).astype(np.int64), np.ascontiguousarray(line_first, dtype=bool),
              np.ascontiguousarray(changed_piece, dtype=bool))
    layer_z = list(draft.table.layer_z)
    if draft.original.layers_by_z:
        # no layer markers: the reader starts a layer at each extrusion above the last,
        # which an E-only piece (a push-back at the next layer's height) can be
        _f, _l, _z, layer_z = fill_columns(out, [], None, base=0, feature=-1, layer=-1,
                                           max_extrude_z=-np.inf)
        out["feature"] = mv["feature"][r]
    return out, layer_z


def draft_table(draft: Draft, layout: Layout | None = None, *,
                source: str | None = None) -> MoveTable:
    """The move table the written draft reads back as, without writing it.

    Parameters
    ----------
    draft
        The draft.
    layout
        Its layout (computed when not given).
    source
        Name of the table's source (default: the original's).
    """
    lay = lay_out_draft(draft, check=False) if layout is None else layout
    table = draft.table
    offsets = np.concatenate(([0], np.cumsum(draft.counts))).astype(np.int64)
    at = offsets[np.minimum([ev.move_index for ev in table.events], offsets.size - 1)
                 ].tolist() if table.events else []
    events = [Event(k, ev.line, ev.code, ev.params)
              for k, ev in zip(at, table.events, strict=True)]
    return MoveTable(moves=lay.rows, events=events,
                     start_xyze=np.asarray(table.start_xyze, dtype=np.float64).copy(),
                     features=list(table.features), layer_z=list(lay.layer_z),
                     metadata=dict(table.metadata),
                     unknown_commands=dict(table.unknown_commands),
                     warnings=list(table.warnings),
                     source=table.source if source is None else source,
                     n_lines=table.n_lines + int(np.sum(lay.line_p1 - lay.line_p0)
                                                 + np.sum(lay.line_f_restore >= 0)
                                                 + np.sum(lay.line_has_g92))
                     - lay.lines_rewritten)


def write_draft(draft: Draft, destination: str | os.PathLike[str],
                layout: Layout | None = None, encoded: bytes | None = None) -> Layout:
    """Write the draft as G-code, atomically; a draft without changes is the original's
    bytes. ``encoded``: :func:`encode_draft`'s bytes of this draft and layout, when made
    already. Returns the layout written."""
    lay = lay_out_draft(draft) if layout is None else layout
    original = draft.original
    if lay.changed_lines.size == 0:  # the original file's own bytes (gzip too)
        try:
            atomic_write_bytes(destination, Path(original.source).read_bytes())
        except OSError as exc:
            raise GcodeError(f"cannot read the G-code file: {exc.strerror}",
                             source=original.source) from exc
        return lay
    if original.bgcode:  # stored as the original was (compression, checksum, encoding)
        from flowtwin.gcode.bgcode.read import read_bgcode_info
        from flowtwin.gcode.bgcode.write import BgcodeOptions, text_to_bgcode

        with open(original.source, "rb") as fh:
            info = read_bgcode_info(fh, original.source)
        text_to_bgcode(draft_text(draft, lay), destination, file_metadata=info.file_metadata,
                       options=BgcodeOptions.like(info.compression, info.checksum,
                                                  info.gcode_encoding))
        return lay
    atomic_write_bytes(destination, encode_draft(draft, lay) if encoded is None else encoded)
    return lay


def draft_text(draft: Draft, lay: Layout) -> bytes:
    """The G-code text of the draft laid out as ``lay`` (with at least one changed line)."""
    original = draft.original
    text = original.text
    pieces = int(np.sum(lay.line_p1 - lay.line_p0))
    size = text.size + 160 * (pieces + 2 * lay.lines_rewritten) + 64
    buf = np.empty(size, dtype=np.uint8)
    used = write_text(text, original.line_start, lay.changed_lines, lay.line_p0,
                      lay.line_p1, lay.line_code, lay.line_f_restore, lay.line_g92,
                      lay.line_has_g92, lay.flags, lay.q_xyz, lay.q_dec, lay.q_e, lay.q_f,
                      original.e_decimals, buf)
    return buf[:used].tobytes()


def encode_draft(draft: Draft, lay: Layout) -> bytes:
    """The bytes :func:`write_draft` stores for a plain or gzip original with at least
    one changed line (:func:`store_text` of :func:`draft_text`)."""
    return store_text(draft, draft_text(draft, lay))


def store_text(draft: Draft, text: bytes) -> bytes:
    """The draft's text as stored: gzip-compressed (:func:`flowtwin.gcode.gz.compress`,
    no time stamp) when the original was, else as it is."""
    return gz.compress(text) if draft.original.gzip else text
