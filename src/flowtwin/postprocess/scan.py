"""Find the lines a post-processor rewrites: slicer time figures and progress commands.

One streaming pass over the text G-code (a ``.bgcode`` is read as the text it stands for,
with the reader's line numbers): a compiled expression picks out ``M73``, ``M600``/``M601``
and comment lines that mention a time, and the texts of a few requested lines are kept.
Memory is bounded by the chunk size, not the file size.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from flowtwin.gcode.inputs import line_chunks, open_source

__all__ = ["FLOWTWIN_MARK", "ScanResult", "scan_gcode"]

#: Start of the comment line flowtwin writes (found again on a second run and replaced).
FLOWTWIN_MARK = "; postprocessed by flowtwin"
_CHUNK = 8 * 1024 * 1024
_CANDIDATE = re.compile(
    rb"^[ \t]*(?:(?:M73|M600|M601)(?![.\d])[^\n]*"
    rb"|;[^\n]*?(?:[Tt][Ii][Mm][Ee]|postprocessed by flowtwin)[^\n]*)$",
    re.MULTILINE)


@dataclass(slots=True)
class ScanResult:
    """What one pass over a G-code found.

    Attributes
    ----------
    candidates
        ``(line, text)`` of every ``M73`` line and every comment that mentions a time
        (text without its line ending), in file order.
    stops
        Lines of ``M600`` (filament change) and ``M601`` (pause), where Prusa's ``M73 C``
        counts down to.
    first_command
        ``(line, text)`` of the first line that is not blank or a comment (``None`` in a
        file of comments only).
    wanted
        Requested line number → its text.
    lines
        Lines in the file.
    last
        Text of the last line.
    """

    candidates: list[tuple[int, str]] = field(default_factory=list)
    stops: list[int] = field(default_factory=list)
    first_command: tuple[int, str] | None = None
    wanted: dict[int, str] = field(default_factory=dict)
    lines: int = 0
    last: str = ""


def _text(raw: bytes) -> str:
    return raw.rstrip(b"\r\n").decode("utf-8", "replace")


def scan_gcode(source: str | os.PathLike[str], wanted: Iterable[int] = ()) -> ScanResult:
    """Scan ``source`` (plain, gzip or ``.bgcode``) once; see :class:`ScanResult`.

    Parameters
    ----------
    source
        The G-code file.
    wanted
        1-based line numbers whose texts to keep.
    """
    want = sorted({int(w) for w in wanted if int(w) > 0})
    wi = 0
    out = ScanResult()
    stream, name = open_source(source)
    base = 0   # lines before the current chunk
    try:
        for chunk in line_chunks(stream, name, _CHUNK):
            n_nl = chunk.count(b"\n")
            n_lines = n_nl + (0 if chunk.endswith(b"\n") else 1)
            if out.first_command is None:
                out.first_command = _first_command(chunk, base)
            pos, line = 0, base + 1
            for m in _candidates(chunk):
                line += chunk.count(b"\n", pos, m.start())
                pos = m.start()
                raw = m.group(0)
                head = raw.lstrip()
                if head[:1] == b"M" and head[:4] in (b"M600", b"M601"):
                    out.stops.append(line)
                else:
                    out.candidates.append((line, _text(raw)))
            if wi < len(want) and want[wi] <= base + n_lines:
                nl = np.flatnonzero(np.frombuffer(chunk, dtype=np.uint8) == 10)
                starts = np.concatenate(([0], nl + 1))
                while wi < len(want) and want[wi] <= base + n_lines:
                    k = want[wi] - base - 1
                    end = int(nl[k]) if k < nl.size else len(chunk)
                    out.wanted[want[wi]] = _text(chunk[int(starts[k]):end])
                    wi += 1
            base += n_lines
            end = len(chunk) - 1 if chunk.endswith(b"\n") else len(chunk)
            out.last = _text(chunk[chunk.rfind(b"\n", 0, end) + 1:end])
    finally:
        stream.close()
    out.lines = base
    return out


#: What every candidate line holds (lower case): the expression is tried only there.
_NEEDLES = (b"m73", b"m600", b"m601", b"time", b"postprocessed by flowtwin")


def _candidates(chunk: bytes) -> list[re.Match[bytes]]:
    """The matches of ``_CANDIDATE`` in ``chunk``, in order: the expression is tried at
    the starts of the lines that hold one of ``_NEEDLES`` (found by substring search,
    much faster than the expression over every line)."""
    low = chunk.lower()
    starts: set[int] = set()
    for needle in _NEEDLES:
        at = low.find(needle)
        while at >= 0:
            starts.add(low.rfind(b"\n", 0, at) + 1)
            end = low.find(b"\n", at)
            at = -1 if end < 0 else low.find(needle, end)
    out = []
    for start in sorted(starts):
        m = _CANDIDATE.match(chunk, start)
        if m is not None:
            out.append(m)
    return out


def _first_command(chunk: bytes, base: int) -> tuple[int, str] | None:
    """The first line of ``chunk`` that holds a command, with its number."""
    start, k = 0, base + 1
    while start < len(chunk):
        end = chunk.find(b"\n", start)
        end = len(chunk) if end < 0 else end
        s = chunk[start:end].strip()
        if s and not s.startswith(b";"):
            return k, _text(chunk[start:end])
        start, k = end + 1, k + 1
    return None
