"""Rewrite a G-code file, changing only the lines a transformation touches.

Every byte of every untouched line is copied as it was (line endings, comments, trailing
spaces, a missing final newline), so a rewrite with no edits is byte-identical to the
input. The output is written atomically: it appears complete or not at all. A Prusa binary
G-code (``.bgcode``) source is edited as the text it stands for (the reader's line numbers)
and written back as ``.bgcode`` stored the same way (checksum, compressions, encoding).
"""

from __future__ import annotations

import gzip
import os
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import BinaryIO

from flowtwin.atomic import atomic_open
from flowtwin.errors import GcodeError

__all__ = ["Edit", "rewrite_gcode"]

#: Replacement for one line: new text (one or more lines, without line endings), or
#: ``None`` to delete the line. Inserted lines take the line ending of the line replaced.
Edit = str | Sequence[str] | None

_CHUNK = 8 * 1024 * 1024


def _lines(stream: BinaryIO) -> Iterator[bytes]:
    """Yield lines with their endings; the last may lack one."""
    rest = b""
    while True:
        block = stream.read(_CHUNK)
        if not block:
            if rest:
                yield rest
            return
        data = rest + block
        start = 0
        while True:
            nl = data.find(b"\n", start)
            if nl < 0:
                break
            yield data[start:nl + 1]
            start = nl + 1
        rest = data[start:]


def _render(edit: Edit, original: bytes) -> bytes:
    if edit is None:
        return b""
    ending = b"\r\n" if original.endswith(b"\r\n") else (b"\n" if original.endswith(b"\n")
                                                         else b"")
    texts = [edit] if isinstance(edit, str) else list(edit)
    if not texts:
        return b""
    for text in texts:
        if "\n" in text or "\r" in text:
            raise GcodeError("an edit must not contain line breaks; give a list of lines",
                             value=text)
    body = (ending or b"\n").join(t.encode("utf-8") for t in texts)
    return body + ending


def rewrite_gcode(source: str | os.PathLike[str], destination: str | os.PathLike[str],
                  edits: Mapping[int, Edit] | None = None) -> int:
    """Copy ``source`` to ``destination`` applying per-line ``edits``.

    Parameters
    ----------
    source
        The G-code file to read (plain text, gzip or ``.bgcode``).
    destination
        Where to write; written atomically (a temporary file renamed into place). It may be
        the same path as ``source``.
    edits
        1-based line number → replacement (see :data:`Edit`). Lines not listed are copied
        byte for byte.

    Returns
    -------
    int
        Number of lines the edits touched.

    Raises
    ------
    GcodeError
        The source cannot be read, or an edit names a line the file does not have.
    """
    edits = dict(edits or {})
    src = Path(source)
    try:
        raw = open(src, "rb")
    except OSError as exc:
        raise GcodeError(f"cannot open G-code file: {exc.strerror}", source=src) from exc
    touched = 0
    last_line = 0
    try:
        if raw.peek(4)[:4] == b"GCDE":
            raw.close()
            return _rewrite_bgcode(src, Path(destination), edits)
        head = raw.peek(2)[:2] if hasattr(raw, "peek") else b""
        stream: BinaryIO = gzip.GzipFile(fileobj=raw) if head == b"\x1f\x8b" else raw  # type: ignore[assignment]
        compress = head == b"\x1f\x8b"
        with atomic_open(destination, "wb") as out:
            sink: BinaryIO = gzip.GzipFile(fileobj=out, mode="wb", mtime=0) if compress else out  # type: ignore[assignment]
            for number, line in enumerate(_lines(stream), start=1):
                last_line = number
                if number in edits:
                    sink.write(_render(edits[number], line))
                    touched += 1
                else:
                    sink.write(line)
            missing = sorted(n for n in edits if n > last_line or n < 1)
            if missing:
                raise GcodeError("edit for a line the file does not have", source=src,
                                 line=missing[0], allowed=f"1..{last_line}")
            if compress:
                sink.close()
    finally:
        raw.close()
    return touched


def _rewrite_bgcode(src: Path, destination: Path, edits: Mapping[int, Edit]) -> int:
    """Edit a ``.bgcode`` as text (in a temporary file), then store it as it was stored."""
    from flowtwin.gcode.bgcode.read import read_bgcode_info
    from flowtwin.gcode.bgcode.write import BgcodeOptions, text_to_bgcode

    with open(src, "rb") as fh:
        info = read_bgcode_info(fh, str(src))
    options = BgcodeOptions.like(info.compression, info.checksum, info.gcode_encoding)
    with tempfile.TemporaryDirectory(dir=destination.parent) as tmp:
        decoded, text = Path(tmp) / "decoded.gcode", Path(tmp) / "edited.gcode"
        _decode(src, decoded)
        touched = rewrite_gcode(decoded, text, edits)
        text_to_bgcode(text, destination, options=options, file_metadata=info.file_metadata)
    return touched


def _decode(src: Path, text: Path) -> None:
    from flowtwin.gcode.source import open_source

    stream, _ = open_source(src)
    try:
        with open(text, "wb") as out:
            while block := stream.read(_CHUNK):
                out.write(block)
    finally:
        stream.close()
