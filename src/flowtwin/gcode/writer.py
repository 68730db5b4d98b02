"""Rewrite a G-code file, changing only the lines a transformation touches.

Every byte of every untouched line is copied as it was (line endings, comments, trailing
spaces, a missing final newline), so a rewrite with no edits is byte-identical to the
input. The output is written atomically: it appears complete or not at all. A Prusa binary
G-code (``.bgcode``) source is edited as the text it stands for (the reader's line numbers)
and written back as ``.bgcode`` stored the same way (checksum, compressions, encoding).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import IO, BinaryIO

from flowtwin.atomic import atomic_open
from flowtwin.errors import GcodeError
from flowtwin.gcode import gz

__all__ = ["Edit", "rewrite_gcode"]

#: Replacement for one line: new text (one or more lines, without line endings), or
#: ``None`` to delete the line. Inserted lines take the line ending of the line replaced.
Edit = str | Sequence[str] | None

_CHUNK = 8 * 1024 * 1024


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


def _apply(stream: BinaryIO, sink: IO[bytes], edits: Mapping[int, Edit], name: str) -> int:
    """Copy ``stream`` to ``sink`` with ``edits``; return how many lines they touched.

    Untouched stretches are copied in bulk; only chunks holding an edited line are cut at
    their line breaks.
    """
    import numpy as np

    from flowtwin.gcode.inputs import line_chunks

    todo = sorted(edits)
    if todo and todo[0] < 1:
        raise GcodeError("edit for a line the file does not have", source=name,
                         line=todo[0], allowed="line numbers from 1")
    ti = 0
    first = 1   # number of the first line of the chunk
    for chunk in line_chunks(stream, name, _CHUNK):
        n = chunk.count(b"\n") + (0 if chunk.endswith(b"\n") else 1)
        if ti >= len(todo) or todo[ti] >= first + n:
            sink.write(chunk)
            first += n
            continue
        nl = np.flatnonzero(np.frombuffer(chunk, dtype=np.uint8) == 10)
        pos = 0
        while ti < len(todo) and todo[ti] < first + n:
            k = todo[ti] - first
            a = int(nl[k - 1]) + 1 if k > 0 else 0
            b = int(nl[k]) + 1 if k < nl.size else len(chunk)
            sink.write(chunk[pos:a])
            sink.write(_render(edits[todo[ti]], chunk[a:b]))
            pos = b
            ti += 1
        sink.write(chunk[pos:])
        first += n
    if ti < len(todo):
        raise GcodeError("edit for a line the file does not have", source=name,
                         line=todo[ti], allowed=f"1..{first - 1}")
    return ti


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
    try:
        if raw.peek(4)[:4] == b"GCDE":
            raw.close()
            return _rewrite_bgcode(src, Path(destination), edits)
        head = raw.peek(2)[:2] if hasattr(raw, "peek") else b""
        compress = head == b"\x1f\x8b"
        stream: BinaryIO = gz.reader(raw) if compress else raw
        with atomic_open(destination, "wb") as out:
            sink = gz.writer(out) if compress else out
            touched = _apply(stream, sink, edits, str(src))
            if compress:
                sink.close()
    finally:
        raw.close()
    return touched


def _rewrite_bgcode(src: Path, destination: Path, edits: Mapping[int, Edit]) -> int:
    """Edit a ``.bgcode`` as text, then store it as it was stored.

    The edited text goes to an unnamed temporary file in the destination's folder (it
    vanishes with the process, however it ends), which the encoder reads twice.
    """
    from flowtwin.gcode.bgcode.read import read_bgcode_info
    from flowtwin.gcode.bgcode.write import BgcodeOptions, text_to_bgcode
    from flowtwin.gcode.inputs import open_source

    with open(src, "rb") as fh:
        info = read_bgcode_info(fh, str(src))
    options = BgcodeOptions.like(info.compression, info.checksum, info.gcode_encoding)
    with tempfile.TemporaryFile(dir=destination.parent) as text:
        stream, name = open_source(src)
        try:
            touched = _apply(stream, text, edits, name)  # type: ignore[arg-type]
        finally:
            stream.close()
        text.flush()
        by_fd = Path(f"/proc/self/fd/{text.fileno()}")
        if by_fd.exists():
            text_to_bgcode(by_fd, destination, options=options,
                           file_metadata=info.file_metadata)
            return touched
        with tempfile.TemporaryDirectory(dir=destination.parent) as tmp:
            named = Path(tmp) / "edited.gcode"
            text.seek(0)
            with open(named, "wb") as out:
                while block := text.read(_CHUNK):
                    out.write(block)
            text_to_bgcode(named, destination, options=options,
                           file_metadata=info.file_metadata)
    return touched
