"""Where G-code comes from: a path (plain, gzip or .bgcode), standard input, bytes or a stream.

:func:`open_source` gives a binary stream (gzip is recognised by its magic bytes, Prusa's
binary ``.bgcode`` by its own: it is read as the text G-code it stands for, see
:class:`~flowtwin.gcode.bgcode.read.BgcodeText`) and :func:`line_chunks` cuts it into
pieces that end on a line break, so the reader's memory stays bounded.
"""

from __future__ import annotations

import gzip
import io
import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

from flowtwin.errors import GcodeError

__all__ = ["DEFAULT_CHUNK_BYTES", "line_chunks", "open_source", "source_name"]

_GZIP_MAGIC = b"\x1f\x8b"
_BGCODE_MAGIC = b"GCDE"
#: Bytes read per chunk.
DEFAULT_CHUNK_BYTES = 16 * 1024 * 1024


def open_source(source: str | os.PathLike[str] | bytes | BinaryIO) -> tuple[BinaryIO, str]:
    """Return a binary stream of text G-code and a display name.

    gzip is decompressed and a binary ``.bgcode`` decoded (block by block, as it is read)
    transparently.

    Raises
    ------
    GcodeError
        The file cannot be opened (a corrupt ``.bgcode`` block raises while it is read).
    """
    if isinstance(source, bytes | bytearray | memoryview):
        raw: BinaryIO = io.BytesIO(bytes(source))
        name = "<bytes>"
    elif isinstance(source, str | os.PathLike):
        name = os.fspath(source)
        if name == "-":
            raw = sys.stdin.buffer
            name = "<stdin>"
        else:
            try:
                raw = open(name, "rb")
            except OSError as exc:
                raise GcodeError(f"cannot open G-code file: {exc.strerror}",
                                 source=name) from exc
    else:
        raw = source
        name = getattr(source, "name", "<stream>")
        name = name if isinstance(name, str) else "<stream>"
    peek = raw.peek(4)[:4] if hasattr(raw, "peek") else b""
    if not peek and isinstance(raw, io.BytesIO):
        peek = raw.getvalue()[:4]
    if peek[:2] == _GZIP_MAGIC:
        from flowtwin.gcode import gz

        return gz.reader(raw), name
    if peek == _BGCODE_MAGIC:
        from flowtwin.gcode.bgcode.read import BgcodeText

        return BgcodeText(raw, name, close_source=True), name  # type: ignore[return-value]
    return raw, name


def line_chunks(stream: BinaryIO, name: str, chunk_bytes: int) -> Iterator[bytes]:
    """Yield pieces of ``stream`` that end on a line break (the last may not).

    Each piece is copied at most once: the partial line left from the previous block is
    joined with the part of the new block up to its last line break.
    """
    rest = b""  # never holds a line break
    while True:
        try:
            block = stream.read(chunk_bytes)
        except (OSError, EOFError, gzip.BadGzipFile) as exc:
            raise GcodeError(f"cannot read G-code: {exc}", source=name) from exc
        if not block:
            if rest:
                yield rest
            return
        cut = block.rfind(b"\n")
        if cut < 0:
            rest = rest + block
            continue
        if rest:
            piece = b"".join((rest, memoryview(block)[:cut + 1]))
        else:
            piece = block if cut + 1 == len(block) else block[:cut + 1]
        rest = block[cut + 1:]
        yield piece


def source_name(source: str | os.PathLike[str] | bytes | BinaryIO) -> str:
    """Display name of a source (for messages)."""
    if isinstance(source, str | os.PathLike):
        return "<stdin>" if os.fspath(source) == "-" else str(Path(source))
    return "<bytes>" if isinstance(source, bytes | bytearray) else "<stream>"
