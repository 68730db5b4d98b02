"""Writing rewritten moves as G-code lines, and keeping the E coordinate consistent.

A rewritten line becomes one ``G1`` per piece (``G0``/``G1`` keep their code; an arc that
must change becomes the ``G1`` chords the reader split it into). Coordinates follow the
line's own modes: absolute (``G90``) piece ends are the G-code coordinates
``(toolhead − G92 offset)``, written with 5 decimals, the last piece repeating the
original word exactly; relative (``G91``) pieces are steps on a 10⁻⁵ mm grid whose sum is
exactly the original step. E is written from whole grid units
(:mod:`flowtwin.compensation.source`), so every sum is exact in decimal.

**Absolute E.** When a rewritten line ends at a different E coordinate than before, the
difference ``δ`` (grid units) is carried: every later line with an E word in absolute
mode is rewritten with ``E + δ`` (only its E word changes; the rest of the line is kept
byte for byte) until a ``G92 E`` sets the coordinate again. The advance keeps ``δ = 0`` at
the end of every run, so in practice only slip feed-forward shifts later lines.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from flowtwin.compensation.source import MotionLine, ScannedSource, format_grid
from flowtwin.errors import GcodeError
from flowtwin.gcode.moves import MoveTable

__all__ = ["EmitResult", "PieceGeometry", "emit_edits"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

_XYZ_DECIMALS = 5
_E_WORD = re.compile(r"(E)(\s*)([-+]?(?:\d+\.?\d*|\.\d+))", re.IGNORECASE)


@dataclass(frozen=True, slots=True)
class PieceGeometry:
    """Where every piece of every row ends and how much E it has.

    Attributes
    ----------
    row
        Row of each piece (non-decreasing), shape ``(n,)``.
    xyz_mm
        Toolhead position at each piece's end, mm, shape ``(n, 3)``.
    e_grid
        E of each piece, grid units, shape ``(n,)``.
    changed_rows
        Rows whose line must be rewritten, shape ``(n_rows,)``.
    feed_mm_min
        Feed of each row's line (``nan``: as written), shape ``(n_rows,)``.
    piece_feed_mm_min
        Feed of each piece (``nan``: its line's), shape ``(n,)``; used for E-only pieces.
    """

    row: IntArray
    xyz_mm: FloatArray
    e_grid: IntArray
    changed_rows: npt.NDArray[np.bool_]
    feed_mm_min: FloatArray
    piece_feed_mm_min: FloatArray


@dataclass(slots=True)
class EmitResult:
    """Edits for :func:`flowtwin.gcode.writer.rewrite_gcode` and how lines map.

    Attributes
    ----------
    edits
        Line number → replacement lines.
    new_line_count
        Output lines per edited input line (1 for lines only re-numbered in E).
    rows_per_row
        Output move rows per input row, shape ``(n_rows,)``.
    lines_rewritten
        Lines replaced by pieces.
    lines_shifted
        Lines whose E word was shifted by the carried ``δ``.
    """

    edits: dict[int, list[str]] = field(default_factory=dict)
    new_line_count: dict[int, int] = field(default_factory=dict)
    rows_per_row: IntArray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    lines_rewritten: int = 0
    lines_shifted: int = 0


def _fmt(value: float) -> str:
    text = f"{value:.{_XYZ_DECIMALS}f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def _grid_xyz(raw: str) -> int:
    whole, _, frac = raw.strip().lstrip("+").partition(".")
    sign = -1 if whole.startswith("-") else 1
    whole = whole.lstrip("-")
    frac = (frac + "0" * _XYZ_DECIMALS)[:_XYZ_DECIMALS]
    return sign * int((whole or "0") + frac)


def emit_edits(scanned: ScannedSource, table: MoveTable, geometry: PieceGeometry) -> EmitResult:
    """G-code text for every changed line, and the ``δ`` shifts of later absolute E words.

    Parameters
    ----------
    scanned
        The source lines and their states.
    table
        The reader's rows of the same file.
    geometry
        The pieces to write.

    Returns
    -------
    EmitResult

    Raises
    ------
    GcodeError
        A line to rewrite carries a checksum, has a relative XYZ step that is not on the
        10⁻⁵ mm grid, or has more decimals in an axis than can be kept.
    """
    mv = table.moves
    n = len(table)
    src = scanned.text.source
    dec = scanned.e_decimals
    counts = np.bincount(geometry.row, minlength=n).astype(np.int64)
    offsets = np.concatenate(([0], np.cumsum(counts)))
    rows_per_row = np.ones(n, dtype=np.int64)
    row_line = np.asarray(mv["line"], dtype=np.int64)
    changed_lines = sorted(set(row_line[geometry.changed_rows].tolist()))
    result = EmitResult()
    start_xyz = np.empty((n, 3))
    if n:
        start_xyz[0] = table.start_xyze[:3]
        start_xyz[1:, 0], start_xyz[1:, 1], start_xyz[1:, 2] = mv["x"][:-1], mv["y"][:-1], \
            mv["z"][:-1]
    orig_end = np.column_stack([mv["x"], mv["y"], mv["z"]]).astype(np.float64)
    # rows of each changed line
    first_row = np.searchsorted(row_line, changed_lines, side="left")
    last_row = np.searchsorted(row_line, changed_lines, side="right")
    changed = dict(zip(changed_lines, zip(first_row.tolist(), last_row.tolist(), strict=True),
                       strict=True))
    # walk every motion line with E (absolute) and every changed line, in order
    events = sorted(set(changed_lines) | set(scanned.e_resets)
                    | {ln for ln, ml in scanned.motion.items() if ml.abs_e and "E" in ml.words})
    resets = set(scanned.e_resets)
    delta = 0
    for ln in events:
        if ln in resets and ln not in scanned.motion:
            delta = 0
            continue
        ml = scanned.motion[ln]
        if ln in changed:
            r0, r1 = changed[ln]
            if ml.checksum:
                raise GcodeError("cannot rewrite a line with a line number or checksum",
                                 source=src, line=ln, value=scanned.text.text(ln),
                                 allowed="G-code without N/* (as slicers write it)")
            lines, e_end = _piece_lines(ml, r0, r1, offsets, geometry, start_xyz, orig_end,
                                        delta, dec, src)
            if ml.abs_e:
                delta = e_end - ml.e_after
            result.edits[ln] = lines
            result.new_line_count[ln] = len(lines)
            rows_per_row[r0:r1] = counts[r0:r1]
            result.lines_rewritten += 1
        elif ml.abs_e and "E" in ml.words and delta != 0:
            result.edits[ln] = [_shift_e(scanned.text.text(ln), ml.e_after + delta, dec,
                                         src, ln)]
            result.new_line_count[ln] = 1
            result.lines_shifted += 1
    result.rows_per_row = rows_per_row
    return result


def _shift_e(text: str, new_e: int, dec: int, src: str, line: int) -> str:
    body, sep, comment = text.partition(";")
    m = _E_WORD.search(body)
    if m is None:
        raise GcodeError("E word not found where the reader saw one", source=src, line=line,
                         value=text)
    body = body[:m.start(3)] + format_grid(new_e, dec) + body[m.end(3):]
    return body + sep + comment


def _piece_lines(ml: MotionLine, r0: int, r1: int, offsets: IntArray, geometry: PieceGeometry,
                 start_xyz: FloatArray, orig_end: FloatArray, delta: int, dec: int,
                 src: str) -> tuple[list[str], int]:
    """Text of the pieces of rows ``r0:r1`` (one line); returns lines and the end E."""
    code = ml.code if ml.code in ("G0", "G1") else "G1"
    p0, p1 = int(offsets[r0]), int(offsets[r1])
    # plain Python values: this runs once per rewritten line (10⁵ on large files)
    ends: list[list[float]] = geometry.xyz_mm[p0:p1].tolist()
    e_pieces: list[int] = geometry.e_grid[p0:p1].tolist()
    line_start: list[float] = (geometry.xyz_mm[p0 - 1] if p0 > 0 else start_xyz[0]).tolist()
    starts = [line_start, *ends[:-1]]
    original_end: list[float] = orig_end[r1 - 1].tolist()
    e_pos = ml.e_before + delta
    out: list[str] = []
    row_feed = float(geometry.feed_mm_min[r0])
    piece_feed: list[float] = geometry.piece_feed_mm_min[p0:p1].tolist()
    line_f_raw = ml.words.get("F")
    line_f = float(line_f_raw) if line_f_raw is not None else ml.feed_mm_min
    default_f = row_feed if math.isfinite(row_feed) else line_f
    state_f = ml.feed_mm_min
    rel_grid: dict[int, int] = {}
    if not ml.abs_xyz:
        for k, axis in enumerate("XYZ"):
            if axis in ml.words:
                total = _grid_xyz(ml.words[axis])
                if abs(total * 10.0 ** -_XYZ_DECIMALS - float(ml.words[axis])) > 1e-12:
                    raise GcodeError("relative step with more than 5 decimals",
                                     source=src, line=ml.line, field=axis,
                                     value=ml.words[axis], allowed="at most 5 decimals")
                rel_grid[k] = total
    written_rel = dict.fromkeys(rel_grid, 0)
    n_p = len(ends)
    for j in range(n_p):
        words: list[str] = [code]
        last = j == n_p - 1
        for k, axis in enumerate("XYZ"):
            moved = abs(ends[j][k] - starts[j][k]) > 1e-9
            if ml.abs_xyz:
                if last and axis in ml.words and abs(ends[j][k] - original_end[k]) < 1e-9:
                    words.append(axis + ml.words[axis])
                elif moved:
                    words.append(axis + _fmt(ends[j][k] - ml.offset_xyz[k]))
            elif k in rel_grid or moved:
                total = rel_grid.get(k, 0)
                frac_pos = ends[j][k] - line_start[k]
                target = total if last else int(round(frac_pos * 10 ** _XYZ_DECIMALS))
                step = target - written_rel.get(k, 0)
                written_rel[k] = target
                if step != 0 or (last and k in rel_grid):
                    words.append(axis + format_grid(step, _XYZ_DECIMALS))
        e = int(e_pieces[j])
        if e != 0:
            e_pos += e
            words.append("E" + format_grid(e_pos if ml.abs_e else e, dec))
        own_feed = math.isfinite(piece_feed[j])
        want = piece_feed[j] if own_feed else default_f
        if j == 0 and line_f_raw is not None and not own_feed \
                and not math.isfinite(row_feed):
            words.append("F" + line_f_raw)
        elif want != state_f:
            words.append("F" + _fmt(want))
        state_f = want
        text = " ".join(words)
        if j == 0 and ml.comment:
            text += " " + ml.comment
        out.append(text)
    if state_f != line_f:
        out.append("G1 F" + (line_f_raw if line_f_raw is not None else _fmt(line_f)))
    return out, e_pos
