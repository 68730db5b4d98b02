"""Write ``.bgcode``: blocks from metadata and G-code text, or a whole text file converted.

:func:`write_bgcode` writes the blocks in the specification's order, each compressed,
encoded and followed by its CRC32 as :class:`BgcodeOptions` says; the G-code text is cut
into blocks of at most 64 KiB at line breaks and never held whole. :func:`text_to_bgcode`
converts a text G-code file, taking the metadata from its comments the way
:class:`~flowtwin.gcode.bgcode.read.BgcodeText` lays them out, so ``.bgcode`` → text →
``.bgcode`` keeps every block. The output is written atomically.
"""

from __future__ import annotations

import base64
import binascii
import os
import re
import zlib
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import IO

import heatshrink2

from flowtwin.atomic import atomic_open
from flowtwin.errors import GcodeError
from flowtwin.gcode.bgcode.format import (
    BLOCK_HEADER,
    FILE_HEADER,
    MAGIC,
    MAX_GCODE_BLOCK_BYTES,
    THUMBNAIL_KEYWORD,
    VERSION,
    BlockType,
    ChecksumType,
    Compression,
    GcodeEncoding,
    MetadataEncoding,
    Thumbnail,
    ThumbnailFormat,
)
from flowtwin.gcode.bgcode.meatpack import pack

__all__ = ["BgcodeOptions", "text_to_bgcode", "write_bgcode"]


@dataclass(frozen=True, slots=True)
class BgcodeOptions:
    """How to store a ``.bgcode`` (defaults: what PrusaSlicer writes).

    Attributes
    ----------
    checksum
        CRC32 after every block, or none.
    file_metadata, printer_metadata, print_metadata, slicer_metadata, gcode
        Compression of each kind of block.
    gcode_encoding
        ``NONE`` (text), ``MEATPACK`` (comment lines dropped) or ``MEATPACK_COMMENTS``.
    """

    checksum: ChecksumType = ChecksumType.CRC32
    file_metadata: Compression = Compression.NONE
    printer_metadata: Compression = Compression.NONE
    print_metadata: Compression = Compression.NONE
    slicer_metadata: Compression = Compression.DEFLATE
    gcode: Compression = Compression.HEATSHRINK_12_4
    gcode_encoding: GcodeEncoding = GcodeEncoding.MEATPACK_COMMENTS

    @classmethod
    def like(cls, compression: Mapping[str, Compression], checksum: ChecksumType,
             gcode_encoding: GcodeEncoding) -> BgcodeOptions:
        """Options that store a file as another was stored (``BgcodeInfo`` fields)."""
        known = {k: v for k, v in compression.items() if k in cls.__slots__}  # type: ignore[attr-defined]
        return cls(checksum=checksum, gcode_encoding=gcode_encoding, **known)


def _compress(data: bytes, compression: Compression) -> bytes:
    if compression == Compression.NONE:
        return data
    if compression == Compression.DEFLATE:
        return zlib.compress(data)
    window = 11 if compression == Compression.HEATSHRINK_11_4 else 12
    return bytes(heatshrink2.compress(data, window_sz2=window, lookahead_sz2=4))


class _BlockWriter:
    def __init__(self, out: IO[bytes], options: BgcodeOptions) -> None:
        self.out = out
        self.options = options
        out.write(FILE_HEADER.pack(MAGIC, VERSION, int(options.checksum)))

    def block(self, block_type: BlockType, compression: Compression, params: bytes,
              data: bytes) -> None:
        stored = _compress(data, compression)
        head = BLOCK_HEADER.pack(int(block_type), int(compression), len(data))
        if compression != Compression.NONE:
            head += len(stored).to_bytes(4, "little")
        self.out.write(head)
        self.out.write(params)
        self.out.write(stored)
        if self.options.checksum == ChecksumType.CRC32:
            crc = zlib.crc32(stored, zlib.crc32(params, zlib.crc32(head)))
            self.out.write(crc.to_bytes(4, "little"))

    def metadata(self, block_type: BlockType, compression: Compression,
                 meta: Mapping[str, str]) -> None:
        data = "".join(f"{k}={v}\n" for k, v in meta.items()).encode("utf-8")
        self.block(block_type, compression, int(MetadataEncoding.INI).to_bytes(2, "little"),
                   data)


def _gcode_blocks(chunks: Iterable[bytes]) -> Iterator[bytes]:
    """Whole lines, at most MAX_GCODE_BLOCK_BYTES per piece (a longer line alone)."""
    rest = b""
    for chunk in chunks:
        data = rest + chunk if rest else chunk
        start = 0
        while len(data) - start > MAX_GCODE_BLOCK_BYTES:
            cut = data.rfind(b"\n", start, start + MAX_GCODE_BLOCK_BYTES)
            if cut < 0:
                cut = data.find(b"\n", start + MAX_GCODE_BLOCK_BYTES)
                if cut < 0:
                    break
            yield data[start:cut + 1]
            start = cut + 1
        rest = data[start:]
    if rest:
        yield rest if rest.endswith(b"\n") else rest + b"\n"


def write_bgcode(destination: str | os.PathLike[str], gcode: Iterable[bytes], *,
                 printer_metadata: Mapping[str, str], print_metadata: Mapping[str, str],
                 slicer_metadata: Mapping[str, str],
                 file_metadata: Mapping[str, str] | None = None,
                 thumbnails: Sequence[Thumbnail] = (),
                 options: BgcodeOptions | None = None) -> int:
    """Write a ``.bgcode`` file atomically.

    Parameters
    ----------
    destination
        Output path (replaced atomically).
    gcode
        The G-code text in pieces of any size (streamed: cut at line breaks into blocks
        of at most 64 KiB).
    printer_metadata, print_metadata, slicer_metadata, file_metadata
        ``key → value`` tables (INI encoding); the file metadata block is left out when
        ``None``.
    thumbnails
        Images, one block each.
    options
        Checksum, compressions and G-code encoding.

    Returns
    -------
    int
        Number of G-code blocks written.
    """
    options = options or BgcodeOptions()
    n = 0
    with atomic_open(destination, "wb") as out:
        w = _BlockWriter(out, options)
        if file_metadata is not None:
            w.metadata(BlockType.FILE_METADATA, options.file_metadata, file_metadata)
        w.metadata(BlockType.PRINTER_METADATA, options.printer_metadata, printer_metadata)
        for t in thumbnails:
            params = (int(t.format).to_bytes(2, "little") + t.width.to_bytes(2, "little")
                      + t.height.to_bytes(2, "little"))
            w.block(BlockType.THUMBNAIL, Compression.NONE, params, t.data)
        w.metadata(BlockType.PRINT_METADATA, options.print_metadata, print_metadata)
        w.metadata(BlockType.SLICER_METADATA, options.slicer_metadata, slicer_metadata)
        enc = options.gcode_encoding
        params = int(enc).to_bytes(2, "little")
        for text in _gcode_blocks(gcode):
            data = text if enc == GcodeEncoding.NONE else pack(
                text, keep_comments=enc == GcodeEncoding.MEATPACK_COMMENTS)
            w.block(BlockType.GCODE, options.gcode, params, data)
            n += 1
    return n


# ----------------------------------------------------------- text G-code → .bgcode ---

_KV = re.compile(rb"^;\s*([^=;]*?[^=;\s])\s*=\s?(.*?)\s*$")
_GENERATED = re.compile(rb"^;\s*generated by (.*?)(?: on (.*?))?\s*$")
_PREPARED = re.compile(rb"^;\s*prepared by (.*?)\s*$")
_THUMB_BEGIN = re.compile(rb"^;\s*(thumbnail|thumbnail_JPG|thumbnail_QOI) begin (\d+)x(\d+) \d+")
_CONFIG = re.compile(rb"^;\s*prusaslicer_config = (begin|end)\s*$")
_FORMATS = {v.encode(): k for k, v in THUMBNAIL_KEYWORD.items()}


def _is_command(line: bytes) -> bool:
    s = line.strip()
    return bool(s) and not s.startswith(b";")


@dataclass
class _Layout:
    """Where a text file's metadata lines are (1-based line numbers to leave out)."""

    skip: set[int]
    file_metadata: dict[str, str] | None
    printer_metadata: dict[str, str]
    print_metadata: dict[str, str]
    slicer_metadata: dict[str, str]
    thumbnails: list[Thumbnail]


def _text(b: bytes) -> str:
    return b.decode("utf-8", "replace")


def _scan(lines: Iterable[bytes], name: str) -> _Layout:
    """First pass: the header (comments before the first command) and the trailer
    (comments after the last command) give the metadata blocks."""
    header: list[tuple[int, bytes]] = []
    trailer: list[tuple[int, bytes]] = []
    in_header = True
    for number, raw in enumerate(lines, start=1):
        line = raw.rstrip(b"\r\n")
        if _is_command(line):
            in_header = False
            trailer.clear()
            continue
        (header if in_header else trailer).append((number, line))
    if in_header:           # no command at all: everything is header
        trailer = []
    skip: set[int] = set()
    file_meta: dict[str, str] | None = None
    printer: dict[str, str] = {}
    thumbs: list[Thumbnail] = []
    thumb: tuple[ThumbnailFormat, int, int, int, list[bytes]] | None = None
    run = 0   # printer metadata: the first unbroken run of key = value lines (1 in it, 2 after)
    for number, line in header:
        if thumb is not None:
            fmt, w, h, start, rows = thumb
            if re.match(rb"^;\s*" + re.escape(THUMBNAIL_KEYWORD[fmt].encode()) + rb" end", line):
                try:
                    data = base64.b64decode(b"".join(rows), validate=True)
                except (binascii.Error, ValueError) as exc:
                    raise GcodeError(f"thumbnail is not valid base64 ({exc})", source=name,
                                     line=start) from exc
                thumbs.append(Thumbnail(fmt, w, h, data))
                skip.update(range(start, number + 1))
                thumb = None
            else:
                rows.append(line.lstrip(b";").strip())
            continue
        stripped = line.strip()
        kv = _KV.match(stripped)
        if run == 1 and kv is None:
            run = 2
        if not stripped or stripped.strip(b"; \t") == b"":
            skip.add(number)
            continue
        if (m := _THUMB_BEGIN.match(stripped)) is not None:
            thumb = (_FORMATS[m.group(1)], int(m.group(2)), int(m.group(3)), number, [])
            continue
        if file_meta is None and (m := _GENERATED.match(stripped)) is not None:
            file_meta = {"Producer": _text(m.group(1))}
            if m.group(2):
                file_meta["Produced on"] = _text(m.group(2))
            skip.add(number)
            continue
        if file_meta is not None and (m := _PREPARED.match(stripped)) is not None:
            file_meta["Prepared by"] = _text(m.group(1))
            skip.add(number)
            continue
        if kv is not None and run < 2:
            run = 1
            printer[_text(kv.group(1))] = _text(kv.group(2))
            skip.add(number)
    if thumb is not None:
        raise GcodeError("thumbnail block has no end line", source=name, line=thumb[3],
                         allowed=f"'; {THUMBNAIL_KEYWORD[thumb[0]]} end'")
    print_meta: dict[str, str] = {}
    slicer: dict[str, str] = {}
    in_config = False
    for number, line in trailer:
        stripped = line.strip()
        if not stripped or stripped.strip(b"; \t") == b"":
            skip.add(number)
            continue
        if (m := _CONFIG.match(stripped)) is not None:
            in_config = m.group(1) == b"begin"
            skip.add(number)
            continue
        if (m := _KV.match(stripped)) is not None:
            (slicer if in_config else print_meta)[_text(m.group(1))] = _text(m.group(2))
            skip.add(number)
    return _Layout(skip, file_meta, printer, print_meta, slicer, thumbs)


def _lines(stream: IO[bytes]) -> Iterator[bytes]:
    rest = b""
    while True:
        block = stream.read(1 << 20)
        if not block:
            if rest:
                yield rest
            return
        data = rest + block
        parts = data.split(b"\n")
        rest = parts.pop()
        for p in parts:
            yield p + b"\n"


def text_to_bgcode(source: str | os.PathLike[str] | bytes, destination: str | os.PathLike[str],
                   *, options: BgcodeOptions | None = None,
                   file_metadata: Mapping[str, str] | None = None) -> int:
    """Convert a text G-code file (plain, gzip or ``.bgcode``) to ``.bgcode``.

    The comments before the first command give the file metadata (``; generated by …``),
    the printer metadata (their first unbroken run of ``; key = value`` lines) and the
    thumbnails; ``; key = value``
    comments after the last command give the print metadata, and the
    ``; prusaslicer_config = begin`` … ``end`` block the slicer metadata; every other
    line goes into the G-code blocks in its place. The source is read twice (memory
    stays flat in file size).

    Parameters
    ----------
    source
        Path or bytes of the text G-code.
    destination
        Output path (written atomically; may be the source).
    options
        Storage settings (PrusaSlicer's by default).
    file_metadata
        Replaces the file metadata found in the text (e.g. to keep keys of an original
        ``.bgcode`` that the text does not show).

    Returns
    -------
    int
        Number of G-code blocks written.
    """
    from flowtwin.gcode.inputs import open_source

    name = source if isinstance(source, bytes) else os.fspath(source)

    def lines() -> Iterator[bytes]:
        stream, _ = open_source(source)
        try:
            yield from _lines(stream)
        finally:
            stream.close()

    label = "<bytes>" if isinstance(source, bytes) else str(name)
    layout = _scan(lines(), label)
    skip = layout.skip

    def gcode() -> Iterator[bytes]:
        batch: list[bytes] = []
        size = 0
        for number, line in enumerate(lines(), start=1):
            if number in skip:
                continue
            batch.append(line)
            size += len(line)
            if size >= MAX_GCODE_BLOCK_BYTES:
                yield b"".join(batch)
                batch, size = [], 0
        if batch:
            yield b"".join(batch)

    meta = dict(file_metadata) if file_metadata is not None else layout.file_metadata
    return write_bgcode(destination, gcode(), printer_metadata=layout.printer_metadata,
                        print_metadata=layout.print_metadata,
                        slicer_metadata=layout.slicer_metadata, file_metadata=meta,
                        thumbnails=layout.thumbnails, options=options)
