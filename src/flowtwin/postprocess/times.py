"""Firmware-exact times written over the slicer's: progress commands and time comments.

Every figure comes from flowtwin's planner (:class:`PlanTimes`): the total print time, the
first layer's time, the time before the first layer, and the print time elapsed at any line
(the start of the first move at or after it, dwells included). The slicers' own lines keep
their form and only their numbers change (a second run replaces the first run's numbers):

==============================  =================================================  =========
slicer                          line                                               figure
==============================  =================================================  =========
PrusaSlicer, SuperSlicer,       ``; estimated printing time (normal mode) = 1h 2m  total
OrcaSlicer, Creality Print      3s``, ``(silent mode)``
same                            ``; estimated first layer printing time (… mode)   layer 0
                                = …``
Bambu Studio                    ``; model printing time: …; total estimated time:  total − time
                                …``                                                 before layer 0,
                                                                                    total
Creality Print                  ``; total estimated time: …``                      total
all Prusa-style firmwares       ``M73 P<%> R<min>``, ``Q<%> S<min>`` (silent),      elapsed at
                                ``C``/``D`` (min to the next ``M600``/``M601``)    the line
Cura                            ``;TIME:<s>``, ``;PRINT.TIME:<s>``,                 total,
                                ``;TIME_ELAPSED:<s>``                               elapsed
ideaMaker                       ``;Print Time: <s>``, ``;PRINTING_TIME: <s>``,      total,
                                ``;REMAINING_TIME: <s>``                            elapsed,
                                                                                    remaining
KISSlicer                       ``; Estimated Build Time:   2.50 minutes``          total
Simplify3D                      ``;   Build time: 0 hours 39 minutes``              total
==============================  =================================================  =========

``M73`` follows PrusaSlicer's ``GCodeProcessor``: percent ``⌊100·t/T⌋`` (100 at the end), minutes
``⌊(T − t + 0.5)/60⌋``. A file without ``M73 P`` gets ``M73 P R`` lines (and ``Q S`` for a
printer with a silent mode) before the first move, at the first move of every layer and
after the last move when its firmware shows them (Marlin-family firmwares; Klipper's front
ends read the time comments instead).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from flowtwin.gcode.moves import MoveTable
from flowtwin.gcode.writer import Edit
from flowtwin.planner.timeline import Timeline, time_by_layer
from flowtwin.postprocess.scan import FLOWTWIN_MARK, ScanResult

__all__ = ["PlanTimes", "TimeEdits", "format_dhms", "progress_lines", "time_edits"]


def format_dhms(seconds: float) -> str:
    """PrusaSlicer's duration format (``1d 2h 3m 4s``, ``5m 6s``, ``7s``), to the second."""
    s = max(0, int(round(seconds)))
    d, s = divmod(s, 86400)
    h, s = divmod(s, 3600)
    m, s = divmod(s, 60)
    if d:
        return f"{d}d {h}h {m}m {s}s"
    if h:
        return f"{h}h {m}m {s}s"
    if m:
        return f"{m}m {s}s"
    return f"{s}s"


#: Added before rounding a percentage down, so that 100·t/T at t = T (99.99999999999999 in
#: floating point) gives 100, and no exact value falls below its integer.
_PCT_EPS = 1e-9


def _percent(elapsed_s: float, total_s: float, decimals: int = 0) -> str:
    """``⌊100·t/T⌋`` (at ``decimals`` places), 100 at or after the end."""
    if total_s <= 0 or elapsed_s >= total_s:
        return f"{100:.{decimals}f}"
    scale = 10 ** decimals
    return f"{math.floor(100.0 * elapsed_s / total_s * scale + _PCT_EPS) / scale:.{decimals}f}"


def _minutes(seconds: float) -> int:
    """Whole minutes as PrusaSlicer's ``M73 R`` writes them."""
    return int((max(seconds, 0.0) + 0.5) / 60.0)


@dataclass(frozen=True, slots=True)
class PlanTimes:
    """The planner's times of one file.

    Attributes
    ----------
    total_s, first_layer_s, before_first_layer_s
        Whole print, layer 0, and everything before layer 0 (start G-code), s.
    move_lines
        Source line of every move (non-decreasing), shape ``(n,)``.
    t_start
        Start of every move on the printer's clock (dwells included), s, ``(n,)``.
    """

    total_s: float
    first_layer_s: float
    before_first_layer_s: float
    move_lines: npt.NDArray[np.int64]
    t_start: npt.NDArray[np.float64]
    dwell_move: npt.NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    dwell_line: npt.NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, np.int64))
    dwell_s: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def of(cls, table: MoveTable, timeline: Timeline) -> PlanTimes:
        """The times of a planned move table."""
        layers = time_by_layer(timeline, table)
        n = len(table)
        lines = [_reason_line(reason) for _, _, reason in timeline.dwell_s]
        return cls(total_s=float(timeline.total_time_s), first_layer_s=layers.get(0, 0.0),
                   before_first_layer_s=layers.get(-1, 0.0),
                   move_lines=np.asarray(table.moves["line"], dtype=np.int64),
                   t_start=np.asarray(timeline.phases["t_start"], dtype=np.float64),
                   dwell_move=np.minimum(np.array([d[0] for d in timeline.dwell_s],
                                                  dtype=np.int64), n),
                   dwell_line=np.array(lines, dtype=np.int64),
                   dwell_s=np.array([d[1] for d in timeline.dwell_s], dtype=np.float64))

    def elapsed_at(self, line: int) -> float:
        """Print time when the printer reaches ``line``, s: the start of the first move at or
        after it, less the dwells between the line and that move (the total after the last
        move, less the dwells after the line)."""
        k = int(np.searchsorted(self.move_lines, line, side="left"))
        t = float(self.t_start[k]) if k < self.t_start.shape[0] else self.total_s
        if self.dwell_s.size:
            later = (self.dwell_move == k) & (self.dwell_line >= line)
            if np.any(later):
                t -= float(np.sum(self.dwell_s[later]))
        return t


def _reason_line(reason: str) -> int:
    """The G-code line a planner's dwell came from (its reason ends in ``line N``)."""
    m = re.search(r"line (\d+)\s*$", reason)
    return int(m.group(1)) if m else -1


@dataclass(slots=True)
class TimeEdits:
    """The line edits and what they changed.

    Attributes
    ----------
    edits
        Line number → replacement, for :func:`flowtwin.gcode.writer.rewrite_gcode`.
    rewritten
        Kind of line → how many were rewritten (``"M73"``, ``"prusa total"``, ``"cura
        elapsed"``, …).
    progress_added
        ``M73`` lines added (a file without any).
    original_index
        Edited line → position of its original text among its replacement lines (for
        :class:`~flowtwin.postprocess.lines.LineMap`).
    """

    edits: dict[int, Edit] = field(default_factory=dict)
    rewritten: dict[str, int] = field(default_factory=dict)
    progress_added: int = 0
    original_index: dict[int, int] = field(default_factory=dict)


#: comment patterns: (kind, expression with the number(s) as groups, formatter)
_Fmt = Callable[[re.Match[str], int, PlanTimes, PlanTimes], str]


def _sub(m: re.Match[str], values: dict[int, str]) -> str:
    """``m``'s string with group ``g`` replaced by ``values[g]``."""
    s = m.string
    out, pos = [], 0
    for g in sorted(values):
        out.append(s[pos:m.start(g)])
        out.append(values[g])
        pos = m.end(g)
    out.append(s[pos:])
    return "".join(out)


def _decimals(token: str) -> int:
    return len(token.split(".", 1)[1]) if "." in token else 0


def _mode(m: re.Match[str], normal: PlanTimes, silent: PlanTimes) -> PlanTimes:
    return silent if m.group("mode") == "silent" else normal


_COMMENTS: list[tuple[str, re.Pattern[str], _Fmt]] = [
    ("prusa total", re.compile(r"^\s*;\s*estimated printing time \((?P<mode>normal|silent) "
                               r"mode\)\s*=\s*(?P<v>.*?)\s*$"),
     lambda m, line, n, s: _sub(m, {2: format_dhms(_mode(m, n, s).total_s)})),
    ("prusa first layer", re.compile(r"^\s*;\s*estimated first layer printing time "
                                     r"\((?P<mode>normal|silent) mode\)\s*=\s*(?P<v>.*?)\s*$"),
     lambda m, line, n, s: _sub(m, {2: format_dhms(_mode(m, n, s).first_layer_s)})),
    ("bambu model and total", re.compile(r"^\s*;\s*model printing time:\s*(.*?)\s*;\s*total "
                                         r"estimated time:\s*(.*?)\s*$"),
     lambda m, line, n, s: _sub(m, {1: format_dhms(n.total_s - n.before_first_layer_s),
                                    2: format_dhms(n.total_s)})),
    ("total estimated", re.compile(r"^\s*;\s*total estimated time:\s*(.*?)\s*$"),
     lambda m, line, n, s: _sub(m, {1: format_dhms(n.total_s)})),
    ("cura total", re.compile(r"^\s*;(?:PRINT\.)?TIME:(\d+(?:\.\d*)?)\s*$"),
     lambda m, line, n, s: _sub(m, {1: f"{n.total_s:.{_decimals(m.group(1))}f}"})),
    ("cura elapsed", re.compile(r"^\s*;TIME_ELAPSED:(\d+(?:\.\d*)?)\s*$"),
     lambda m, line, n, s: _sub(m, {1: f"{n.elapsed_at(line):.{_decimals(m.group(1))}f}"})),
    ("ideamaker total", re.compile(r"^\s*;Print Time:\s*(\d+)\s*$"),
     lambda m, line, n, s: _sub(m, {1: f"{round(n.total_s)}"})),
    ("ideamaker elapsed", re.compile(r"^\s*;PRINTING_TIME:\s*(\d+)\s*$"),
     lambda m, line, n, s: _sub(m, {1: f"{round(n.elapsed_at(line))}"})),
    ("ideamaker remaining", re.compile(r"^\s*;REMAINING_TIME:\s*(\d+)\s*$"),
     lambda m, line, n, s: _sub(m, {1: f"{round(n.total_s - n.elapsed_at(line))}"})),
    ("kisslicer total", re.compile(r"^\s*;\s*Estimated Build Time:\s*(\d+(?:\.\d*)?)"
                                   r"\s*minutes\s*$"),
     lambda m, line, n, s: _sub(m, {1: f"{n.total_s / 60.0:.{_decimals(m.group(1))}f}"})),
    ("simplify3d total", re.compile(r"^\s*;\s*Build time:\s*(\d+)\s*hours?\s*(\d+)\s*"
                                    r"minutes?\s*$"),
     lambda m, line, n, s: _sub(m, {1: str(round(n.total_s / 60.0) // 60),
                                    2: str(round(n.total_s / 60.0) % 60)})),
]

_M73 = re.compile(r"^(?P<lead>\s*M73)(?P<params>(?:\s+[A-Za-z][-+]?[\d.]*)*)(?P<rest>\s*(?:;.*)?)$")
_PARAM = re.compile(r"(\s+)([A-Za-z])([-+]?[\d.]*)")


def _m73(text: str, line: int, normal: PlanTimes, silent: PlanTimes,
         stops: npt.NDArray[np.int64]) -> str | None:
    """The ``M73`` line with flowtwin's figures (``None``: nothing of it is a time)."""
    m = _M73.match(text)
    if m is None:
        return None
    k = int(np.searchsorted(stops, line, side="right"))
    stop_line = int(stops[k]) if k < stops.shape[0] else None
    changed = False

    def value(letter: str, token: str) -> str:
        nonlocal changed
        up = letter.upper()
        times = silent if up in ("Q", "S", "D") else normal
        e = times.elapsed_at(line)
        if up in ("P", "Q"):
            v = _percent(e, times.total_s, _decimals(token))
        elif up in ("R", "S"):
            v = str(_minutes(times.total_s - e))
        elif up in ("C", "D") and stop_line is not None:
            v = str(_minutes(times.elapsed_at(stop_line) - e))
        else:
            return token
        changed = True
        return v

    params = _PARAM.sub(lambda p: p.group(1) + p.group(2) + value(p.group(2), p.group(3)),
                        m.group("params"))
    if not changed:
        return None
    return m.group("lead") + params + m.group("rest")


def progress_lines(times: PlanTimes, line: int, letters: str = "PR") -> str:
    """The ``M73 P R`` line (``letters="QS"``: silent mode's) for the moment the printer
    reaches ``line``."""
    e = times.elapsed_at(line)
    return (f"M73 {letters[0]}{_percent(e, times.total_s)} "
            f"{letters[1]}{_minutes(times.total_s - e)}")


class _Builder:
    """Edits of single lines: a replacement and lines inserted before / after."""

    def __init__(self) -> None:
        self.replace: dict[int, str | None] = {}
        self.before: dict[int, list[str]] = {}
        self.after: dict[int, list[str]] = {}

    def build(self, texts: dict[int, str]) -> tuple[dict[int, Edit], dict[int, int]]:
        edits: dict[int, Edit] = {}
        index: dict[int, int] = {}
        for line in sorted(set(self.replace) | set(self.before) | set(self.after)):
            before, after = self.before.get(line, []), self.after.get(line, [])
            if line in self.replace:
                own = self.replace[line]
            elif line in texts:
                own = texts[line]
            else:
                raise KeyError(f"text of line {line} was not read")
            if not before and not after:
                edits[line] = own
                continue
            mid = [] if own is None else [own]
            edits[line] = [*before, *mid, *after]
            index[line] = len(before)
        return edits, index


def time_edits(scan: ScanResult, normal: PlanTimes, *, silent: PlanTimes | None = None,
               header: list[str] | None = None,
               progress_at: list[int] | None = None) -> TimeEdits:
    """The edits that write ``normal`` (and ``silent``) times over the slicer's.

    Parameters
    ----------
    scan
        The file's time lines (:func:`~flowtwin.postprocess.scan.scan_gcode`); its
        ``wanted`` texts must hold the lines of ``progress_at``.
    normal, silent
        Times of the printer, and of its silent mode (PrusaSlicer's ``Q``/``S`` and
        "silent mode" lines; default: the normal times).
    header
        Comment lines naming flowtwin, the model and the configuration: they replace the
        lines of an earlier run, or are added after the last line (so that no line of the
        file moves).
    progress_at
        Lines before which to add ``M73 P R`` (and ``M73 Q S`` with ``silent``) when the
        file has none (a line after the last one adds them at the end), or ``None``.
    """
    silent_mode = silent is not None
    silent = silent or normal
    out = TimeEdits()
    b = _Builder()
    stops = np.asarray(sorted(scan.stops), dtype=np.int64)
    has_progress = False
    own: list[int] = []

    def count(kind: str) -> None:
        out.rewritten[kind] = out.rewritten.get(kind, 0) + 1

    for line, text in scan.candidates:
        if text.lstrip().startswith(FLOWTWIN_MARK):
            own.append(line)
            continue
        if text.lstrip().startswith("M73"):
            if re.search(r"\s[PQ][\d.]", text):
                has_progress = True
            new = _m73(text, line, normal, silent, stops)
            if new is not None:
                if new != text:
                    b.replace[line] = new
                count("M73")
            continue
        for kind, pattern, fmt in _COMMENTS:
            m = pattern.match(text)
            if m is not None:
                new = fmt(m, line, normal, silent)
                if new != text:
                    b.replace[line] = new
                count(kind)
                break
    texts = dict(scan.wanted)
    if scan.lines:
        texts[scan.lines] = scan.last
    if header:
        if own:
            b.replace[own[0]] = None
            b.after[own[0]] = list(header)
            for line in own[1:]:
                b.replace[line] = None
        elif scan.lines:
            b.after.setdefault(scan.lines, []).extend(header)
    if progress_at and not has_progress:
        for line in progress_at:
            entries = [progress_lines(normal, line)]
            if silent_mode:
                entries.append(progress_lines(silent, line, "QS"))
            if line > scan.lines:
                after = b.after.setdefault(scan.lines, [])
                after[0:0] = entries
            else:
                b.before.setdefault(line, []).extend(entries)
            out.progress_added += len(entries)
    out.edits, out.original_index = b.build(texts)
    return out
