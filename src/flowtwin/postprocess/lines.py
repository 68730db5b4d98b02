"""Where a line of the simulated file is after lines were inserted or deleted.

The verdict names G-code lines of the file that was simulated; the file written adds a few
lines (``M73`` progress lines). :class:`LineMap` translates a line number of the simulated
file into the written one, and :func:`remap_lines` applies it to a verdict's JSON and text.
"""

from __future__ import annotations

import re
from collections.abc import Mapping

import numpy as np

from flowtwin.gcode.writer import Edit

__all__ = ["LINE_KEYS", "LineMap", "remap_lines"]

#: Keys of a verdict's dictionary whose values are line numbers.
LINE_KEYS = frozenset({"line", "line_first", "line_last", "ooze_line"})
_LINE_TEXT = re.compile(r"\b(lines?) (\d+)(?:–(\d+))?")


class LineMap:
    """Line numbers before → after a set of edits.

    Parameters
    ----------
    edits
        The edits (line → replacement) given to the writer.
    original_index
        Edited line → position of the original text within its replacement list (lines
        inserted before it); lines not listed keep the original first.
    """

    def __init__(self, edits: Mapping[int, Edit], original_index: Mapping[int, int]) -> None:
        lines = np.array(sorted(edits), dtype=np.int64)
        delta = np.array([(-1 if edits[k] is None else 0 if isinstance(edits[k], str)
                           else len(edits[k]) - 1)  # type: ignore[arg-type]
                          for k in lines.tolist()], dtype=np.int64)
        self._lines = lines
        self._before = np.concatenate(([0], np.cumsum(delta)))
        self._own = dict(original_index)

    @property
    def identity(self) -> bool:
        """True when no line moves."""
        return not np.any(self._before)

    def __call__(self, line: int) -> int:
        """The new number of original line ``line`` (``line`` itself when ≤ 0)."""
        if line <= 0 or self.identity:
            return line
        k = int(np.searchsorted(self._lines, line, side="left"))
        return int(line + self._before[k] + self._own.get(line, 0))


def remap_lines(value: object, lines: LineMap) -> object:
    """``value`` (a verdict's dictionary, a list, or a sentence) with its line numbers
    translated."""
    if lines.identity:
        return value
    if isinstance(value, dict):
        return {k: (lines(v) if k in LINE_KEYS and isinstance(v, int) else
                    remap_lines(v, lines)) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [remap_lines(v, lines) for v in value]
    if isinstance(value, str):
        def sub(m: re.Match[str]) -> str:
            first = lines(int(m.group(2)))
            if m.group(3) is None:
                return f"{m.group(1)} {first}"
            return f"{m.group(1)} {first}–{lines(int(m.group(3)))}"
        return _LINE_TEXT.sub(sub, value)
    return value
