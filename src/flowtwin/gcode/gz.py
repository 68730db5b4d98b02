"""gzip-compressed G-code: read and written with ISA-L's deflate (python-isal).

A ``.gcode.gz`` is read and written as the standard gzip format (RFC 1952): any gzip
reader opens what flowtwin writes, and flowtwin opens any gzip file. The codec is
Intel's ISA-L through ``isal.igzip`` (the standard library's API): on the Benchy's
compensated text (13.9 MB) its level 3 compresses in 0.04 s of CPU against 0.52 s for
zlib's level 6 (gzip's default) and 1.33 s for level 9, for a file 8 % larger than level
6's (4.79 against 4.42 MB); it decompresses 3-4x faster than zlib. Measured on this
project's 2-core VM (docs/performance.md).
"""

from __future__ import annotations

from typing import IO, BinaryIO, cast

__all__ = ["LEVEL", "compress", "reader", "writer"]

#: ISA-L's compression level (0-3; 3 packs tightest).
LEVEL = 3


def compress(data: bytes) -> bytes:
    """``data`` as one gzip member (level :data:`LEVEL`, no time stamp: the same bytes for
    the same text)."""
    from isal import igzip

    return igzip.compress(data, compresslevel=LEVEL, mtime=0)


def reader(raw: BinaryIO) -> BinaryIO:
    """A decompressing binary stream over ``raw``. Bad data raise ``gzip.BadGzipFile``
    (an ``OSError``) or ``EOFError`` (truncated), as the standard library's reader."""
    from isal import igzip

    return cast(BinaryIO, igzip.IGzipFile(fileobj=raw, mode="rb"))


def writer(raw: IO[bytes]) -> IO[bytes]:
    """A compressing binary stream into ``raw`` (level :data:`LEVEL`, no time stamp);
    close it to write the trailer (``raw`` stays open)."""
    from isal import igzip

    return cast(IO[bytes], igzip.IGzipFile(fileobj=raw, mode="wb", mtime=0,
                                           compresslevel=LEVEL))
