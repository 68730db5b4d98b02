"""The written text read back and compared with the pieces it was written from.

Every compensated file is parsed again by flowtwin's own reader, a chunk at a time, and its
moves compared with the draft's table column by column (:data:`READ_BACK_COLUMNS`, bit for
bit) and its layer heights with the layout's: where they are the same, the draft's
simulation is the file's. The comparison needs only the text, the layout and the reader's
options, so it runs on the write-ahead worker while the main thread simulates the same
draft (:mod:`flowtwin.compensation.ahead`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flowtwin.compensation.emit import Layout
from flowtwin.gcode.reader import ReadOptions, iter_move_chunks

__all__ = ["READ_BACK_CHUNK_BYTES", "READ_BACK_COLUMNS", "ReadBack", "read_back"]

#: The move columns the read-back compares with the draft's table.
READ_BACK_COLUMNS = ("x", "y", "z", "e", "de", "feed_mm_s", "kind", "layer", "tool", "flow",
                     "feature", "line")
#: Text read back per chunk: the check holds one chunk's rows at a time, not the file's.
READ_BACK_CHUNK_BYTES = 1 << 20


@dataclass(frozen=True)
class ReadBack:
    """What the written text reads back as.

    Attributes
    ----------
    moves
        Moves read.
    same
        Every move equals the layout's row in :data:`READ_BACK_COLUMNS` (and there are no
        more of them than rows), and the layer heights equal the layout's.
    """

    moves: int
    same: bool


def read_back(source: Path | bytes, layout: Layout, options: ReadOptions) -> ReadBack:
    """Parse ``source`` (the written file, or its text) and compare it with ``layout``.

    Raises
    ------
    GcodeError
        The text cannot be read.
    """
    mine = layout.rows
    n = 0
    same = True
    last = None
    for chunk in iter_move_chunks(source, options=options, chunk_bytes=READ_BACK_CHUNK_BYTES):
        mv, k = chunk.moves, len(chunk)
        same = same and n + k <= len(mine) and all(
            np.array_equal(mv[name], mine[name][n:n + k]) for name in READ_BACK_COLUMNS)
        n += k
        last = chunk
    same = same and last is not None and np.array_equal(
        np.asarray(last.layer_z, dtype=np.float64), np.asarray(layout.layer_z, dtype=np.float64),
        equal_nan=True)
    return ReadBack(n, bool(same))
