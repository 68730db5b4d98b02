"""The compensated file under construction: pieces of the original moves.

A :class:`Draft` keeps, for every move row of the *original* file, the pieces it has become
(end position, E in grid units) and the feed its line is written with. Transformations
compose on it: each one renders the draft (:meth:`Draft.render`), lets the twin read and
plan the rendered file — whose rows are exactly the draft's pieces — and replaces pieces
by finer pieces (:meth:`Draft.split`), moves them, or changes their E. The final file is
always written from the original, so every line no transformation touched stays byte for
byte as it was.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import numpy.typing as npt

from flowtwin.atomic import atomic_write_bytes
from flowtwin.compensation.emit import EmitResult, PieceGeometry, emit_edits
from flowtwin.compensation.source import ScannedSource
from flowtwin.errors import GcodeError
from flowtwin.gcode.moves import MoveTable
from flowtwin.gcode.writer import rewrite_gcode

__all__ = ["Draft"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class Draft:
    """Pieces of the original rows.

    Attributes
    ----------
    scanned
        The original file's lines and states.
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

    scanned: ScannedSource
    table: MoveTable
    row_e: IntArray
    row: IntArray
    xyz_mm: FloatArray
    e_grid: IntArray
    feed_mm_min: FloatArray
    piece_feed_mm_min: FloatArray

    @classmethod
    def identity(cls, scanned: ScannedSource, table: MoveTable, row_e: IntArray) -> Draft:
        """The original file: one piece per row."""
        mv = table.moves
        n = len(table)
        xyz = np.column_stack([mv["x"], mv["y"], mv["z"]]).astype(np.float64)
        return cls(scanned, table, np.asarray(row_e, dtype=np.int64),
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
        n = self.n_rows
        counts = self.counts
        mv = self.table.moves
        orig = np.column_stack([mv["x"], mv["y"], mv["z"]]).astype(np.float64)
        changed = counts != 1
        single = np.flatnonzero(~changed)
        piece_of = np.searchsorted(self.row, single)
        moved = np.any(np.abs(self.xyz_mm[piece_of] - orig[single]) > 1e-9, axis=1)
        e_diff = self.e_grid[piece_of] != self.row_e[single]
        changed[single] = moved | e_diff
        changed |= np.isfinite(self.feed_mm_min)
        changed |= np.bincount(self.row, weights=np.isfinite(self.piece_feed_mm_min),
                               minlength=n) > 0
        return np.asarray(changed & (np.arange(n) >= 0))

    def geometry(self) -> PieceGeometry:
        """The pieces as :class:`~flowtwin.compensation.emit.PieceGeometry`."""
        return PieceGeometry(self.row, self.xyz_mm, self.e_grid, self.changed_rows(),
                             self.feed_mm_min, self.piece_feed_mm_min)

    def render(self, destination: str | os.PathLike[str]) -> EmitResult:
        """Write the draft as G-code (atomically) from the original file.

        With no change at all the original bytes are copied unchanged.

        Raises
        ------
        GcodeError
            The source cannot be read, or a line cannot be rewritten.
        """
        result = emit_edits(self.scanned, self.table, self.geometry())
        src = self.scanned.text.source
        if not result.edits:
            try:
                data = Path(src).read_bytes()
            except OSError as exc:
                raise GcodeError(f"cannot read the G-code file: {exc.strerror}",
                                 source=src) from exc
            atomic_write_bytes(destination, data)
            return result
        rewrite_gcode(src, destination, result.edits)
        return result

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
