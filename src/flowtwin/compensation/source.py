"""The source G-code as text: its lines and the G-code state at every motion line.

Compensation rewrites motion lines, so it must know what the reader knew when it read
each one: absolute or relative XYZ (``G90``/``G91``) and E (``M82``/``M83``; ``G91``
makes E relative too), the ``G92`` offsets, the E coordinate before the line and the
modal feed rate. :func:`scan_source` replays exactly the reader's rules
(:mod:`flowtwin.gcode.reader`, :mod:`flowtwin.gcode._kernel`) on the raw lines, and
resynchronises the toolhead position with the reader's own move rows after every line
that moved, so the two can never drift apart.

E amounts are handled as **integers on a decimal grid** of ``10**-e_decimals`` G-code
units (``e_decimals`` = the most decimals any E word of the file has, at least 5): every
E word of the file is exactly representable on it, so sums of rewritten pieces can be made
to equal the original sums exactly, in decimal, as the firmware will add them.
"""

from __future__ import annotations

import gzip
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flowtwin.errors import GcodeError
from flowtwin.gcode.moves import MoveTable

__all__ = ["MotionLine", "ScannedSource", "SourceText", "format_grid", "read_source", "row_e_grid",
           "scan_source"]

_WORD = re.compile(r"([A-Z])\s*([^A-Z\s]*)")
_CODE = re.compile(r"\s*(?:N\s*\d+\s*)?([GMT])\s*(\d+(?:\.\d+)?)", re.IGNORECASE)
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)")
#: Fewest decimals of the E grid (PrusaSlicer writes 5).
MIN_E_DECIMALS = 5
#: Most decimals accepted (beyond that a float cannot carry the grid exactly).
MAX_E_DECIMALS = 9


@dataclass(frozen=True, slots=True)
class SourceText:
    """A G-code file's bytes, split into lines.

    Attributes
    ----------
    source
        File name (for messages).
    lines
        Each line's bytes *without* its line ending; ``lines[0]`` is line 1.
    gzip
        The file was gzip-compressed.
    """

    source: str
    lines: list[bytes]
    gzip: bool

    def text(self, line: int) -> str:
        """Line ``line`` (1-based) as text, without its ending (invalid UTF-8 replaced)."""
        return self.lines[line - 1].decode("utf-8", "replace").rstrip("\r")


@dataclass(slots=True)
class MotionLine:
    """One ``G0``–``G3`` line and the state it was read in.

    Attributes
    ----------
    line
        1-based line number.
    code
        ``"G0"``, ``"G1"``, ``"G2"`` or ``"G3"``.
    words
        Parameter letter → its number exactly as written (``{"X": "85.225", "E": ".5"}``).
    comment
        Everything from the first ``;`` (kept on the first rewritten piece), or ``""``.
    abs_xyz, abs_e
        Absolute XYZ (``G90``) / absolute E (``M82`` and ``G90``) in force.
    offset_xyz
        ``G92`` offsets in force: toolhead = G-code coordinate + offset, mm.
    e_before
        G-code E coordinate before the line, in grid units.
    e_after
        G-code E coordinate after the line, in grid units.
    feed_mm_min
        Modal ``F`` in force *before* the line (G-code units, mm/min).
    speed_factor
        ``M220`` factor in force (1.0 = 100 %).
    checksum
        The line carries an ``N`` number or ``*`` checksum (it cannot be rewritten).
    """

    line: int
    code: str
    words: dict[str, str]
    comment: str
    abs_xyz: bool
    abs_e: bool
    offset_xyz: tuple[float, float, float]
    e_before: int
    e_after: int
    feed_mm_min: float
    speed_factor: float
    checksum: bool

    @property
    def de_grid(self) -> int:
        """E change of the line in grid units."""
        return self.e_after - self.e_before


@dataclass(slots=True)
class ScannedSource:
    """Motion lines of a file with their states (see :func:`scan_source`).

    Attributes
    ----------
    text
        The file's lines.
    motion
        Line number → :class:`MotionLine`.
    e_decimals
        Decimals of the E grid.
    e_resets
        Lines that set the E coordinate (``G92`` with ``E`` or without parameters).
    """

    text: SourceText
    motion: dict[int, MotionLine]
    e_decimals: int
    e_resets: list[int] = field(default_factory=list)

    @property
    def e_unit(self) -> float:
        """Size of one grid unit, G-code E units (mm of filament)."""
        return 10.0 ** -self.e_decimals


def read_source(source: str | os.PathLike[str]) -> SourceText:
    """Read a G-code file (plain, gzip or ``.bgcode``) into lines.

    Raises
    ------
    GcodeError
        The file cannot be read.
    """
    path = Path(source)
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise GcodeError(f"cannot open G-code file: {exc.strerror}", source=path) from exc
    if raw[:4] == b"GCDE":  # Prusa binary G-code: its text (the reader's line numbers)
        from flowtwin.gcode.inputs import open_source

        stream, _ = open_source(path)
        with stream:
            raw = stream.read()
    compressed = raw[:2] == b"\x1f\x8b"
    if compressed:
        try:
            raw = gzip.decompress(raw)
        except (OSError, EOFError) as exc:
            raise GcodeError(f"cannot read G-code: {exc}", source=path) from exc
    lines = raw.split(b"\n")
    if lines and lines[-1] == b"":
        lines.pop()
    return SourceText(str(path), lines, compressed)


def _decimals(raw: str) -> int:
    dot = raw.find(".")
    return 0 if dot < 0 else len(raw) - dot - 1


def _to_grid(raw: str, decimals: int) -> int:
    """Exact grid integer of a decimal literal (``"-1.2"`` with 5 decimals → -120000)."""
    text = raw.strip()
    sign = -1 if text.startswith("-") else 1
    text = text.lstrip("+-")
    whole, _, frac = text.partition(".")
    frac = (frac + "0" * decimals)[:decimals]
    return sign * int((whole or "0") + frac)


def format_grid(value: int, decimals: int) -> str:
    """Decimal text of a grid integer, trailing zeros dropped (``120000, 5`` → ``"1.2"``)."""
    sign = "-" if value < 0 else ""
    q, r = divmod(abs(value), 10 ** decimals)
    if r == 0:
        return f"{sign}{q}"
    frac = f"{r:0{decimals}d}".rstrip("0")
    return f"{sign}{q}.{frac}"


def scan_source(text: SourceText, table: MoveTable, *,
                home_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> ScannedSource:
    """Replay the reader's modal state over every line.

    Parameters
    ----------
    text
        The file's lines (:func:`read_source`).
    table
        The reader's move table of the same file (positions are resynchronised with it).
    home_xyz
        Where ``G28`` leaves the axes (the reader's ``ReadOptions.home_xyz``), mm.

    Returns
    -------
    ScannedSource

    Raises
    ------
    GcodeError
        Inch units (``G20``) or volumetric E (``M200``): compensation rewrites E in mm of
        filament only (the message names the line).
    """
    src = text.source
    raw_motion: list[tuple[int, str, dict[str, str], str, bool]] = []
    decimals = MIN_E_DECIMALS
    plain: list[tuple[int, str, dict[str, str]]] = []  # (line, code, words) of state lines
    for number, raw in enumerate(text.lines, start=1):
        head = raw.lstrip()[:1]
        if head not in (b"G", b"g", b"M", b"m", b"N", b"n"):
            continue
        line = raw.decode("utf-8", "replace").rstrip("\r")
        body, sep, comment = line.partition(";")
        m = _CODE.match(body)
        if m is None:
            continue
        checksum = "*" in body or body.lstrip()[:1] in ("N", "n")
        star = body.find("*")
        if star >= 0:
            body = body[:star]
        code = m.group(1).upper() + m.group(2)
        rest = body[m.end():].upper()
        words = {k: v for k, v in _WORD.findall(rest)}
        if code in ("G0", "G1", "G2", "G3", "G00", "G01", "G02", "G03"):
            code = "G" + str(int(code[1:]))
            if "E" in words:
                decimals = max(decimals, _decimals(words["E"]))
            raw_motion.append((number, code, words, sep + comment, checksum))
            plain.append((number, code, words))
        elif code in ("G90", "G91", "G92", "M82", "M83", "G20", "G21", "G28", "M200", "M220"):
            if code == "G92" and "E" in words:
                decimals = max(decimals, _decimals(words["E"]))
            plain.append((number, code, words))
    if decimals > MAX_E_DECIMALS:
        raise GcodeError(f"E values with more than {MAX_E_DECIMALS} decimals", source=src,
                         value=decimals, allowed=f"at most {MAX_E_DECIMALS} decimals")
    # toolhead position after each line that produced rows (resynchronisation)
    mv = table.moves
    row_lines = np.asarray(mv["line"], dtype=np.int64)
    last_row: dict[int, int] = {}
    if row_lines.size:
        ends = np.flatnonzero(np.diff(np.concatenate((row_lines, [-1]))) != 0)
        last_row = dict(zip(row_lines[ends].tolist(), ends.tolist(), strict=True))
    pos = [float(v) for v in table.start_xyze[:3]]
    offset = [0.0, 0.0, 0.0]
    abs_xyz, abs_e_flag = True, True
    e_coord = 0
    feed = 1500.0
    speed_factor = 1.0
    motion: dict[int, MotionLine] = {}
    resets: list[int] = []
    motion_info = {n: (c, s) for n, _code, _w, c, s in raw_motion}
    for number, code, words in plain:
        if code in ("G0", "G1", "G2", "G3"):
            abs_e = abs_e_flag and abs_xyz
            before = e_coord
            if "E" in words:
                value = _grid_word(words, "E", decimals, src, number)
                e_coord = value if abs_e else e_coord + value
            comment, checksum = motion_info[number]
            motion[number] = MotionLine(number, code, words, comment, abs_xyz, abs_e,
                                        (offset[0], offset[1], offset[2]), before, e_coord,
                                        feed, speed_factor, checksum)
            if "F" in words:
                feed = _float_word(words, "F", src, number)
            for i, axis in enumerate("XYZ"):
                if axis in words:
                    v = _float_word(words, axis, src, number)
                    pos[i] = v + offset[i] if abs_xyz else pos[i] + v
        elif code == "G90":
            abs_xyz = True
        elif code == "G91":
            abs_xyz = False
        elif code == "M82":
            abs_e_flag = True
        elif code == "M83":
            abs_e_flag = False
        elif code == "G92":
            given = [a for a in "XYZE" if a in words]
            for i, axis in enumerate("XYZ"):
                if axis in words or not given:
                    v = _float_word(words, axis, src, number) if axis in words else 0.0
                    offset[i] = pos[i] - v
            if "E" in words or not given:
                e_coord = _grid_word(words, "E", decimals, src, number) if "E" in words else 0
                resets.append(number)
        elif code == "G20":
            raise GcodeError("inch units (G20): compensation rewrites millimetre G-code only",
                             source=src, line=number, value="G20", allowed="G21 (mm)")
        elif code == "M200":
            d = words.get("D")
            if d is None or _float_word(words, "D", src, number) > 0:
                raise GcodeError("volumetric E (M200): compensation rewrites E in mm of "
                                 "filament only", source=src, line=number, value="M200",
                                 allowed="linear E (no M200, or M200 D0)")
        elif code == "M220" and "S" in words:
            speed_factor = _float_word(words, "S", src, number) / 100.0
        elif code == "G28":
            named = [i for i, a in enumerate("XYZ") if a in words]
            for i in named or [0, 1, 2]:
                pos[i] = home_xyz[i]
        row = last_row.get(number)
        if row is not None:
            pos = [float(mv["x"][row]), float(mv["y"][row]), float(mv["z"][row])]
    return ScannedSource(text, motion, decimals, resets)


def _float_word(words: dict[str, str], key: str, src: str, line: int) -> float:
    raw = words[key]
    if _NUMBER.fullmatch(raw) is None:
        raise GcodeError(f"parameter {key} is not a number", source=src, line=line, field=key,
                         value=raw, allowed="a decimal number")
    return float(raw)


def _grid_word(words: dict[str, str], key: str, decimals: int, src: str, line: int) -> int:
    _float_word(words, key, src, line)
    return _to_grid(words[key], decimals)


def row_e_grid(scanned: ScannedSource, table: MoveTable) -> np.ndarray:
    """E of every row in grid units, exact: each line's E split over its rows.

    A ``G1`` line is one row and gets the line's E exactly; an arc's E is split over its
    chords in proportion to the reader's per-row E, with the rounding residue carried so
    the chords add up to the line's E. Firmware-retraction rows (``G10``/``G11``) are not
    E the G-code writes and get 0.

    Returns
    -------
    ndarray of int64
        Shape ``(n_rows,)``.
    """
    from flowtwin.gcode.moves import MoveKind

    mv = table.moves
    n = len(table)
    out = np.zeros(n, dtype=np.int64)
    lines = np.asarray(mv["line"], dtype=np.int64)
    written = (mv["kind"] & MoveKind.FW_RETRACT) == 0
    de = np.asarray(mv["de"], dtype=np.float64)
    i = 0
    while i < n:
        j = i
        while j + 1 < n and lines[j + 1] == lines[i]:
            j += 1
        ml = scanned.motion.get(int(lines[i]))
        sel = [k for k in range(i, j + 1) if written[k]]
        if ml is not None and sel:
            total = ml.de_grid
            if len(sel) == 1:
                out[sel[0]] = total
            else:
                w = de[sel]
                s = float(np.sum(w))
                cum = np.cumsum(w) / s * total if s != 0 else np.linspace(
                    total / len(sel), total, len(sel))
                pos = np.rint(cum).astype(np.int64)
                pos[-1] = total
                out[sel] = np.diff(np.concatenate(([0], pos)))
        i = j + 1
    return out
