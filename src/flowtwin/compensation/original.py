"""The original file as compensation rewrites it: its text and the modes of every row.

Compensation writes some motion lines anew, each in the modes it was read in: absolute or
relative XYZ (``G90``/``G91``) and E (``M82``/``M83``; ``G91`` makes E relative too), the
``G92`` offsets (toolhead = G-code coordinate + offset), the ``M220`` speed factor and the
G-code E coordinate before it. All of that is the reader's: its move table (toolhead
positions, E per row) and its events (the modal commands in file order,
:mod:`flowtwin.gcode.reader`); nothing here reads G-code words.

E amounts are handled as **integers on a decimal grid** of ``10**-e_decimals`` mm
(``e_decimals``: the fewest decimals, at least 5, on which every E amount of the file and
every ``G92 E`` is a whole number): every E word of the file is exactly representable on
it, so sums of rewritten pieces can equal the original sums exactly, in decimal, as the
firmware adds the words.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit
from flowtwin.compensation._grid_kernel import split_lines
from flowtwin.errors import GcodeError
from flowtwin.gcode._columns import fill_columns
from flowtwin.gcode.inputs import open_source
from flowtwin.gcode.moves import MoveKind, MoveTable

__all__ = ["MAX_E_DECIMALS", "MIN_E_DECIMALS", "OriginalFile", "read_original", "split_line"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

#: Fewest decimals of the E grid (PrusaSlicer writes 5).
MIN_E_DECIMALS = 5
#: Most decimals accepted (beyond that a float cannot carry the grid exactly).
MAX_E_DECIMALS = 9
#: An amount is on the grid when it is this close to a whole number of grid units.
_GRID_TOLERANCE = 1e-2


@dataclass(frozen=True, slots=True)
class OriginalFile:
    """The original file's text and the modes of every row of its move table.

    Attributes
    ----------
    source
        File name (for messages).
    text
        The file's bytes (decompressed), ``uint8``.
    line_start
        Byte offset of the start of every line, with ``len(text)`` appended (line ``k``,
        1-based, is ``text[line_start[k - 1]:line_start[k]]``, line break included),
        shape ``(n_lines + 1,)``.
    gzip
        The file was gzip-compressed (the output is too).
    bgcode
        The file is a Prusa binary G-code (the output is stored the same way).
    e_decimals
        Decimals of the E grid.
    abs_xyz, abs_e
        Absolute XYZ / absolute E in force on every row, shape ``(n,)``.
    offset_xyz
        ``G92`` offsets in force on every row, mm, shape ``(n, 3)``.
    speed_factor
        ``M220`` factor in force on every row, shape ``(n,)``.
    row_e
        E of every row, grid units (0 for firmware retractions, which the G-code does not
        write), shape ``(n,)``.
    e_before
        G-code E coordinate before every row, grid units, shape ``(n,)``.
    e_reset
        A ``G92`` sets the E coordinate just before the row, shape ``(n,)``.
    line_inert
        Line neither moves nor can set the E coordinate: empty, a comment, or a command the
        reader kept as an event other than ``G92``/``M82``/``G90`` (a rewritten stretch of
        lines continues across such lines), shape ``(n_lines,)``.
    layers_by_z
        The reader found no layer markers: its layers start at each extrusion above the
        last (:func:`flowtwin.gcode._columns.fill_columns`).
    """

    source: str
    text: npt.NDArray[np.uint8]
    line_start: IntArray
    gzip: bool
    bgcode: bool
    e_decimals: int
    abs_xyz: BoolArray
    abs_e: BoolArray
    offset_xyz: FloatArray
    speed_factor: FloatArray
    row_e: IntArray
    e_before: IntArray
    e_reset: BoolArray
    line_inert: BoolArray
    layers_by_z: bool

    @property
    def e_unit(self) -> float:
        """Size of one grid unit, mm of filament."""
        return 10.0 ** -self.e_decimals

    def line_bytes(self, line: int) -> bytes:
        """Line ``line`` (1-based) without its line break."""
        raw = self.text[self.line_start[line - 1]:self.line_start[line]].tobytes()
        return raw.rstrip(b"\n").rstrip(b"\r")


def read_original(source: str | os.PathLike[str], table: MoveTable, *,
                  home_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> OriginalFile:
    """The text of ``source`` and the modes of the rows of ``table`` (its move table).

    Parameters
    ----------
    source
        The G-code file (plain or gzip).
    table
        The reader's move table of the same file.
    home_xyz
        Where ``G28`` leaves the axes (the reader's ``ReadOptions.home_xyz``), mm.

    Returns
    -------
    OriginalFile

    Raises
    ------
    GcodeError
        The file cannot be read; inch units (``G20``) or volumetric E (``M200``):
        compensation rewrites E in mm of filament only; E amounts with more than
        :data:`MAX_E_DECIMALS` decimals.
    """
    name = str(Path(source))
    try:
        with open(name, "rb") as probe:
            head = probe.read(4)
    except OSError as exc:
        raise GcodeError(f"cannot open G-code file: {exc.strerror}", source=name) from exc
    stream, _ = open_source(source)
    try:
        data = stream.read()
    except (OSError, EOFError) as exc:
        raise GcodeError(f"cannot read G-code: {exc}", source=name) from exc
    finally:
        stream.close()
    text = np.frombuffer(data, dtype=np.uint8)
    breaks = np.flatnonzero(text == 10) + 1
    line_start = np.concatenate(([0], breaks)).astype(np.int64)
    if line_start[-1] != text.size:
        line_start = np.append(line_start, text.size)
    modes = _modes(table, name, home_xyz)
    decimals, row_e = _e_grid(table, modes[4], name)
    e_before = _e_coordinates(table, row_e, modes[4], decimals)
    e_reset = np.zeros(len(table), dtype=bool)
    for at, _value in modes[4]:
        if at < len(table):
            e_reset[at] = True
    return OriginalFile(name, text, line_start, head[:2] == b"\x1f\x8b", head == b"GCDE",
                        decimals, modes[0], modes[1],
                        modes[2], modes[3], row_e, e_before, e_reset,
                        _inert_lines(text, line_start, table), _layers_by_z(table))


def _steps(n: int, default: npt.ArrayLike, points: list[tuple[int, object]]
           ) -> npt.NDArray[np.generic]:
    """A per-row value that changes at the given rows (in order; the last wins)."""
    base = np.asarray(default)
    out = np.broadcast_to(base, (n, *base.shape)).copy()
    if not points or n == 0:
        return out
    at = np.array([p[0] for p in points], dtype=np.int64)
    vals = np.array([p[1] for p in points])
    k = np.searchsorted(at, np.arange(n), side="right") - 1
    set_ = k >= 0
    out[set_] = vals[k[set_]]
    return out


def _modes(table: MoveTable, name: str, home_xyz: tuple[float, float, float]
           ) -> tuple[BoolArray, BoolArray, FloatArray, FloatArray,
                      list[tuple[int, float]]]:
    """Per row: absolute XYZ, absolute E, G92 offsets, M220 factor; and the ``G92 E``
    settings ``(row index, value)`` in order. Replays the reader's modal events."""
    mv = table.moves
    n = len(table)
    xyz_points: list[tuple[int, object]] = []
    e_points: list[tuple[int, object]] = []
    off_points: list[tuple[int, object]] = []
    factor_points: list[tuple[int, object]] = []
    e_sets: list[tuple[int, float]] = []
    start = np.asarray(table.start_xyze[:3], dtype=np.float64)
    pos_key = -1
    pos = start.copy()
    off = np.zeros(3)
    flavor = table.metadata.get("volumetric_e")
    if flavor:
        raise GcodeError("volumetric E (a CuraEngine volumetric flavor): compensation rewrites "
                         "E in mm of filament only", source=name, line=1,
                         value=f";FLAVOR:{flavor}", allowed="a flavor with linear E")
    for ev in table.events:
        code = ev.code
        at = ev.move_index
        if code in ("G90", "G91"):
            xyz_points.append((at, code == "G90"))
        elif code in ("M82", "M83"):
            e_points.append((at, code == "M82"))
        elif code == "M220" and isinstance(s_value := ev.params.get("S"), float):
            factor_points.append((at, s_value / 100.0))
        elif code in ("G28", "G92"):
            if pos_key != at:  # the toolhead where the event happens: after row at − 1
                pos = (np.array([mv["x"][at - 1], mv["y"][at - 1], mv["z"][at - 1]],
                                dtype=np.float64) if at > 0 else start.copy())
                pos_key = at
            if code == "G28":
                named = [i for i, a in enumerate("XYZ") if a in ev.params]
                for i in named or [0, 1, 2]:
                    pos[i] = home_xyz[i]
                continue
            given = [a for a in "XYZE" if a in ev.params]
            moved = False
            for i, axis in enumerate("XYZ"):
                if axis in ev.params or not given:
                    value = ev.params.get(axis, 0.0)
                    off[i] = pos[i] - (value if isinstance(value, float) else 0.0)
                    moved = True
            if moved:
                off_points.append((at, off.copy()))
            if "E" in ev.params or not given:
                value = ev.params.get("E", 0.0)
                e_sets.append((at, value if isinstance(value, float) else 0.0))
        elif code == "G20":
            raise GcodeError("inch units (G20): compensation rewrites millimetre G-code only",
                             source=name, line=ev.line, value="G20", allowed="G21 (mm)")
        elif code == "M200":
            d = ev.params.get("D")
            if d is None or not isinstance(d, float) or d > 0:
                raise GcodeError("volumetric E (M200): compensation rewrites E in mm of "
                                 "filament only", source=name, line=ev.line, value="M200",
                                 allowed="linear E (no M200, or M200 D0)")
    abs_xyz = _steps(n, True, xyz_points).astype(bool)
    abs_e = _steps(n, True, e_points).astype(bool) & abs_xyz
    offset = _steps(n, np.zeros(3), off_points).astype(np.float64)
    factor = _steps(n, 1.0, factor_points).astype(np.float64)
    return abs_xyz, abs_e, offset, factor, e_sets


def _e_grid(table: MoveTable, e_sets: list[tuple[int, float]], name: str
            ) -> tuple[int, IntArray]:
    """The E grid's decimals and every row's E on it (each line's E exactly, split over its
    rows in proportion to the reader's E per row)."""
    mv = table.moves
    n = len(table)
    written = (mv["kind"] & MoveKind.FW_RETRACT) == 0
    de = np.where(written, np.asarray(mv["de"], dtype=np.float64), 0.0)
    lines = np.asarray(mv["line"], dtype=np.int64)
    first = np.flatnonzero(np.concatenate(([True], lines[1:] != lines[:-1]))) if n else \
        np.zeros(0, dtype=np.int64)
    line_de = np.add.reduceat(de, first) if n else np.zeros(0)
    values = np.concatenate((line_de, np.array([v for _i, v in e_sets], dtype=np.float64)))
    decimals = MIN_E_DECIMALS
    while decimals <= MAX_E_DECIMALS:
        scaled = values * 10.0 ** decimals
        if (np.all(np.abs(scaled) < 1e13)
                and np.all(np.abs(scaled - np.rint(scaled)) <= _GRID_TOLERANCE)):
            break
        decimals += 1
    if decimals > MAX_E_DECIMALS:
        worst = int(np.argmax(np.abs(values * 1e9 - np.rint(values * 1e9))))
        line = int(lines[first[worst]]) if worst < first.size else None
        raise GcodeError(f"E values with more than {MAX_E_DECIMALS} decimals", source=name,
                         line=line, value=float(values[worst]),
                         allowed=f"at most {MAX_E_DECIMALS} decimals")
    unit = 10.0 ** decimals
    line_grid = np.rint(line_de * unit).astype(np.int64)
    out = np.zeros(n, dtype=np.int64)
    if n:
        counts = np.diff(np.append(first, n))
        single = counts == 1
        out[first[single]] = line_grid[single]
        # arcs: split over the chords (the few the kernel leaves, here)
        for k in split_lines(de, first, counts, line_grid, out).tolist():
            a, b = int(first[k]), int(first[k] + counts[k])
            out[a:b] = split_line(de[a:b], int(line_grid[k]))
    return decimals, out


def split_line(de: npt.NDArray[np.float64], total: int) -> IntArray:
    """A line's E on the grid (``total`` steps) split over its rows in proportion to their
    ``de`` (evenly when they sum to zero), each row's share the difference of the rounded
    running totals, so the shares add up to ``total`` exactly; shape ``(rows,)``."""
    s = float(np.sum(de))
    cum = (np.cumsum(de) / s * total if s != 0.0
           else np.linspace(total / de.size, total, de.size))
    pos = np.rint(cum).astype(np.int64)
    pos[-1] = total
    return np.diff(np.concatenate(([0], pos)))


def _e_coordinates(table: MoveTable, row_e: IntArray, e_sets: list[tuple[int, float]],
                   decimals: int) -> IntArray:
    """G-code E coordinate before every row, grid units (``G92 E`` sets it)."""
    cum = np.concatenate(([0], np.cumsum(row_e)))  # E written before every row
    out = cum[:-1].copy()
    unit = 10.0 ** decimals
    for at, value in e_sets:  # from `at` on: value + what is written since
        out[at:] = int(round(value * unit)) + (cum[at:-1] - cum[at])
    return out


def _layers_by_z(table: MoveTable) -> bool:
    """Whether the reader's layers are those of the Z rule (no layer markers)."""
    rows = table.moves.copy()
    _f, _l, _z, rises = fill_columns(rows, [], None, base=0, feature=-1, layer=-1,
                                     max_extrude_z=-np.inf)
    return bool(np.array_equal(rows["layer"], table.moves["layer"])
                and np.array_equal(np.asarray(rises, dtype=np.float64),
                                   np.asarray(table.layer_z, dtype=np.float64),
                                   equal_nan=True))


def _inert_lines(text: npt.NDArray[np.uint8], line_start: IntArray,
                 table: MoveTable) -> BoolArray:
    """Lines that neither move nor can set the E coordinate (see ``line_inert``)."""
    n_lines = line_start.size - 1
    out = np.zeros(n_lines, dtype=bool)
    if n_lines == 0:
        return out
    solid = np.flatnonzero((text != 32) & (text != 9) & (text != 13))
    k = np.searchsorted(solid, line_start[:-1])
    at = solid[np.minimum(k, solid.size - 1)] if solid.size else np.zeros(n_lines, np.int64)
    inside = (k < solid.size) & (at < line_start[1:])
    first = np.where(inside, text[at] if solid.size else 0, 10)
    out[(first == 10) | (first == 59)] = True  # empty, or a comment
    for ev in table.events:
        if ev.code not in ("G92", "M82", "G90", "G91", "M83") and 1 <= ev.line <= n_lines:
            out[ev.line - 1] = True
    if len(table):
        out[np.asarray(table.moves["line"], dtype=np.int64) - 1] = False
    return out


def e_grid_text(value: int, decimals: int) -> str:
    """Decimal text of a grid integer, trailing zeros dropped (``120000, 5`` → ``"1.2"``)."""
    sign = "-" if value < 0 else ""
    q, r = divmod(abs(value), 10 ** decimals)
    if r == 0:
        return f"{sign}{q}"
    return f"{sign}{q}.{f'{r:0{decimals}d}'.rstrip('0')}"


def check_rewritable(original: OriginalFile, lines: IntArray) -> None:
    """Refuse to rewrite a line that carries a line number or a checksum.

    Raises
    ------
    GcodeError
        Naming the first such line.
    """
    lines = np.asarray(lines, dtype=np.int64)
    bad = _numbered_lines(original.text, original.line_start, lines)
    if bad >= 0:
        ln = int(lines[bad])
        raise GcodeError("cannot rewrite a line with a line number or checksum",
                         source=original.source, line=ln,
                         value=original.line_bytes(ln).decode("utf-8", "replace"),
                         allowed="G-code without N/* (as slicers write it)")


@njit(cache=True)
def _numbered_lines(text: npt.NDArray[np.uint8], line_start: IntArray,
                    lines: IntArray) -> int:
    """Index of the first of ``lines`` that starts with ``N`` or has a ``*`` before its
    comment, or −1."""
    for k in range(lines.shape[0]):
        a = line_start[lines[k] - 1]
        b = line_start[lines[k]]
        head = True
        for i in range(a, b):
            c = text[i]
            if c == 59 or c == 10:
                break
            if head and c != 32 and c != 9:
                if c == 78 or c == 110:
                    return k
                head = False
            if c == 42:
                return k
    return -1
