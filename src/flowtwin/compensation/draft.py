"""The compensated file under construction: pieces of the original moves.

A :class:`Draft` keeps, for every move row of the *original* file, the pieces it has become
(end position, E in grid units) and the feed its line is written with. Transformations
compose on it: each one lets the twin plan and simulate the draft's move table — the table
the written file reads back as (:meth:`Draft.to_table`, computed in memory) — and replaces
pieces by finer pieces (:meth:`Draft.split`), moves them, or changes their E. The file is
written from the original (:meth:`Draft.render`), so every line no transformation touched
stays byte for byte as it was.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt

from flowtwin.compensation._rows_kernel import changed_rows
from flowtwin.compensation.emit import (
    Layout,
    check_layout,
    draft_table,
    lay_out_draft,
    write_draft,
)
from flowtwin.compensation.original import OriginalFile
from flowtwin.gcode.moves import MoveTable

__all__ = ["Draft"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class Draft:
    """Pieces of the original rows.

    Attributes
    ----------
    original
        The original file's text and the modes of its rows.
    table
        The original file's move rows.
    row_e
        E of every original row in grid units, shape ``(n_rows,)``.
    row
        Original row of every piece (non-decreasing), shape ``(n,)``.
    xyz_mm
        Toolhead position at the end of every piece, mm, shape ``(n, 3)``.
    e_grid
        E of every piece, grid units, shape ``(n,)``.
    feed_mm_min
        Feed written on each original row's line (``nan``: as in the original),
        shape ``(n_rows,)``.
    piece_feed_mm_min
        Feed of each piece (``nan``: its line's), shape ``(n,)``.
    """

    original: OriginalFile
    table: MoveTable
    row_e: IntArray
    row: IntArray
    xyz_mm: FloatArray
    e_grid: IntArray
    feed_mm_min: FloatArray
    piece_feed_mm_min: FloatArray

    @classmethod
    def identity(cls, original: OriginalFile, table: MoveTable) -> Draft:
        """The original file: one piece per row."""
        mv = table.moves
        n = len(table)
        row_e = original.row_e
        xyz = np.column_stack([mv["x"], mv["y"], mv["z"]]).astype(np.float64)
        return cls(original, table, np.asarray(row_e, dtype=np.int64),
                   np.arange(n, dtype=np.int64), xyz, np.asarray(row_e, dtype=np.int64).copy(),
                   np.full(n, np.nan), np.full(n, np.nan))

    def __len__(self) -> int:
        return int(self.row.shape[0])

    @property
    def n_rows(self) -> int:
        """Rows of the original file."""
        return len(self.table)

    @property
    def counts(self) -> IntArray:
        """Pieces per original row."""
        return np.bincount(self.row, minlength=self.n_rows).astype(np.int64)

    def start_xyz(self) -> FloatArray:
        """Toolhead position at the start of every piece, mm, shape ``(n, 3)``."""
        out = np.empty_like(self.xyz_mm)
        if len(self):
            out[0] = self.table.start_xyze[:3]
            out[1:] = self.xyz_mm[:-1]
        return out

    def changed_rows(self) -> npt.NDArray[np.bool_]:
        """Original rows whose line must be rewritten."""
        return changed_rows(np.ascontiguousarray(self.row, dtype=np.int64), self.n_rows,
                            np.ascontiguousarray(self.xyz_mm, dtype=np.float64),
                            self.table.moves, np.ascontiguousarray(self.e_grid, dtype=np.int64),
                            np.ascontiguousarray(self.row_e, dtype=np.int64),
                            np.ascontiguousarray(self.feed_mm_min, dtype=np.float64),
                            np.ascontiguousarray(self.piece_feed_mm_min, dtype=np.float64))

    def layout(self, *, check: bool = True) -> Layout:
        """The words of every piece as they will be written (:mod:`.emit`).

        ``check``: refuse lines that cannot be rewritten (for the file to write; a table
        to simulate needs no check).

        Raises
        ------
        GcodeError
            With ``check``: a line to rewrite carries a line number or checksum, or a
            relative step that is not on the 10⁻⁵ mm grid.
        """
        return lay_out_draft(self, check=check)

    def check(self, layout: Layout) -> Layout:
        """``layout`` (this draft's, made without the check) once checked as
        :meth:`layout` checks it.

        Raises
        ------
        GcodeError
            As :meth:`layout`.
        """
        check_layout(self, layout)
        return layout

    def to_table(self, layout: Layout | None = None, *, source: str | None = None
                 ) -> MoveTable:
        """The move table the written draft reads back as (computed, not read)."""
        return draft_table(self, layout, source=source)

    def render(self, destination: str | os.PathLike[str],
               layout: Layout | None = None, *, encoded: bytes | None = None) -> Layout:
        """Write the draft as G-code (atomically) from the original file; with no change
        at all the original bytes are copied unchanged. ``encoded``: the bytes
        :func:`~flowtwin.compensation.emit.encode_draft` made of this draft and layout.

        Raises
        ------
        GcodeError
            A line to rewrite cannot be (a checksum, a relative step off the grid).
        """
        return write_draft(self, destination, layout, encoded)

    def split(self, piece: IntArray, xyz_mm: FloatArray, e_grid: IntArray,
              piece_feed_mm_min: FloatArray | None = None) -> Draft:
        """Replace the pieces by sub-pieces.

        Parameters
        ----------
        piece
            Current piece each sub-piece belongs to (non-decreasing, every piece at least
            once), shape ``(m,)``.
        xyz_mm
            End position of every sub-piece, mm, shape ``(m, 3)``.
        e_grid
            E of every sub-piece, grid units, shape ``(m,)``.
        piece_feed_mm_min
            Feed of every sub-piece (``nan``: its line's); default: the piece's.
        """
        piece = np.asarray(piece, dtype=np.int64)
        step = np.diff(piece)
        if piece.size and (piece[0] != 0 or piece[-1] != self.row.size - 1
                           or (step.size and not 0 <= step.min() <= step.max() <= 1)):
            # the writer lays every line out from its pieces in order: a piece lost or out
            # of order here would corrupt the output, so it is an internal error
            raise RuntimeError("a draft's sub-pieces must cover every piece, in order")
        feed = (self.piece_feed_mm_min[piece] if piece_feed_mm_min is None
                else np.asarray(piece_feed_mm_min, dtype=np.float64))
        return replace(self, row=self.row[piece], xyz_mm=np.asarray(xyz_mm, dtype=np.float64),
                       e_grid=np.asarray(e_grid, dtype=np.int64), piece_feed_mm_min=feed)

    def with_e(self, e_grid: IntArray) -> Draft:
        """The same pieces with new E."""
        return replace(self, e_grid=np.asarray(e_grid, dtype=np.int64))

    def with_feed(self, feed_mm_min: FloatArray) -> Draft:
        """The same pieces, lines written with these feeds (``nan``: as written)."""
        return replace(self, feed_mm_min=np.asarray(feed_mm_min, dtype=np.float64))
