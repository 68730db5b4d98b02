"""Prusa binary G-code (``.bgcode``): the constants and layouts of the published format.

Source: libbgcode ``doc/specifications.md`` (Prusa Research; the format, not its code).
A file is a 10-byte header (magic ``GCDE``, version, checksum type) followed by blocks in
this order: file metadata (optional), printer metadata, thumbnails (optional, one block
each), print metadata, slicer metadata, G-code blocks. Every block is a header (type,
compression, uncompressed size, and the compressed size when compressed), the block's
parameters (2 bytes; 6 for a thumbnail), the data, and a CRC32 when the file header asks
for one. All integers are little-endian. The CRC32 (zlib's polynomial) covers the
block header, parameters and data as stored.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass

__all__ = [
    "BLOCK_HEADER",
    "BLOCK_NAMES",
    "FILE_HEADER",
    "MAGIC",
    "MAX_GCODE_BLOCK_BYTES",
    "THUMBNAIL_KEYWORD",
    "VERSION",
    "BlockType",
    "ChecksumType",
    "Compression",
    "GcodeEncoding",
    "MetadataEncoding",
    "Thumbnail",
    "ThumbnailFormat",
    "block_header_size",
    "params_size",
]

MAGIC = b"GCDE"
#: The only version the specification defines.
VERSION = 1
#: magic, version, checksum type
FILE_HEADER = struct.Struct("<4sIH")
#: type, compression, uncompressed size (the compressed size follows when compressed)
BLOCK_HEADER = struct.Struct("<HHI")
#: G-code text per block before encoding, bytes (what PrusaSlicer writes; a printer
#: decodes one block at a time, so blocks stay small).
MAX_GCODE_BLOCK_BYTES = 65536


class ChecksumType(enum.IntEnum):
    """Checksum after every block (file header field)."""

    NONE = 0
    CRC32 = 1


class BlockType(enum.IntEnum):
    """Block type (block header field)."""

    FILE_METADATA = 0
    GCODE = 1
    SLICER_METADATA = 2
    PRINTER_METADATA = 3
    PRINT_METADATA = 4
    THUMBNAIL = 5


class Compression(enum.IntEnum):
    """Compression of a block's data (block header field)."""

    NONE = 0
    DEFLATE = 1
    HEATSHRINK_11_4 = 2   # window 2^11, look-ahead 2^4
    HEATSHRINK_12_4 = 3   # window 2^12, look-ahead 2^4


class MetadataEncoding(enum.IntEnum):
    """Encoding of a metadata block (its parameter): ``key=value`` lines."""

    INI = 0


class GcodeEncoding(enum.IntEnum):
    """Encoding of a G-code block (its parameter)."""

    NONE = 0
    MEATPACK = 1            # comment lines dropped
    MEATPACK_COMMENTS = 2   # comment lines kept


class ThumbnailFormat(enum.IntEnum):
    """Image format of a thumbnail block (its first parameter)."""

    PNG = 0
    JPG = 1
    QOI = 2


#: Name of each thumbnail format in text G-code (``; thumbnail_QOI begin 16x16 368``).
THUMBNAIL_KEYWORD = {ThumbnailFormat.PNG: "thumbnail", ThumbnailFormat.JPG: "thumbnail_JPG",
                     ThumbnailFormat.QOI: "thumbnail_QOI"}

BLOCK_NAMES = {BlockType.FILE_METADATA: "file metadata", BlockType.GCODE: "G-code",
               BlockType.SLICER_METADATA: "slicer metadata",
               BlockType.PRINTER_METADATA: "printer metadata",
               BlockType.PRINT_METADATA: "print metadata", BlockType.THUMBNAIL: "thumbnail"}


def block_header_size(compression: int) -> int:
    """Bytes of a block header: 8 uncompressed, 12 with the compressed size."""
    return 8 if compression == Compression.NONE else 12


def params_size(block_type: int) -> int:
    """Bytes of a block's parameters: 6 for a thumbnail (format, width, height), else 2."""
    return 6 if block_type == BlockType.THUMBNAIL else 2


@dataclass(frozen=True, slots=True)
class Thumbnail:
    """One thumbnail image as stored (``data`` is the PNG/JPG/QOI file)."""

    format: ThumbnailFormat
    width: int
    height: int
    data: bytes
