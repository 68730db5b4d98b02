"""The advance-factor line patterns people print, with their published geometry.

Every layout is a stack of straight test lines, each printed ``slow / fast / slow`` with one
advance factor, front to back in rising ``K``, plus the marks its tool adds (prime lines,
reference marks at the speed changes, printed numbers, anchor lines). The test lines are
what is measured; the marks only tell which way the photo is turned.

==============  =========================================================================
name            geometry and defaults (source)
==============  =========================================================================
``kline``       flowtwin's K-line pattern (:mod:`flowtwin.calibration.patterns.kline`): 20/40/20 mm
                at 20/70 mm/s, 5 mm pitch, 0.48 mm lines, K 0–0.2 s by 0.01 s [001 Table
                I]; prime line in front, a tick beyond the end of every 5th line.
``marlin``      Marlin's K-factor calibration pattern generator ("standard" pattern;
                MarlinDocumentation ``_tools/lin_advance/k-factor.html``/``.js``, read at
                commit 9ceeb6e4): 20/40/20 mm at 20/70 mm/s, 5 mm spacing, line width
                1.2 × nozzle, 0.2 mm layer, acceleration 500 mm/s², K 0–2 by 0.2 (the
                page's LIN_ADVANCE 1.5 defaults); two prime lines along Y 10 mm left of the
                lines, two 20 mm reference marks at the speed changes 5 mm behind the last
                line, the K printed (2 mm segments) 2 mm right of every second line;
                options ``frame`` (the generator's anchor frame: two lines along each
                end of the test lines, 3 mm beyond the first and last line) and
                ``prime`` (on by default). Andrew Ellis' deprecated "lines method" tool
                is this generator with the frame on, no prime lines, 5/120 mm/s,
                2000 mm/s² and K 0–0.1 by 0.005 by default.
``prusa``       Prusa's linear-advance calibration lines (Prusa Knowledge Base, "Linear
                Advance", article 2252): the first and last 25 mm slow, 100 mm fast.
                The article states no speeds, spacing or K range: the defaults here are
                Marlin's generator's (20/70 mm/s, 5 mm) with K 0–0.1 by 0.01 — give them
                as printed.
``orca``        OrcaSlicer's PA line (``CalibPressureAdvanceLine``, src/libslic3r/calib.cpp,
                2.x): 20/40/20 mm at 20/100 mm/s (``set_speed`` defaults), 3.5 mm pitch,
                0.6 mm lines, 0.2 mm layer, K from 0 by 0.002, 50 lines (``generate_test``
                defaults); prime line along the line starts, anchor line along the line
                ends (printed after line 0), a filled box right of the lines with the K of
                every second line.
``orca-legacy`` The same test lines as laid out by OrcaSlicer 1.x / Bambu Studio
                (``calib_pressure_advance``): a prime line 2 mm left of the lines from
                line 3 to line n−4, two 5 mm speed-change indicators 2 mm behind the last
                line, the K of every second line 3 mm right of the lines (the layout of
                the photo in the OrcaSlicer wiki's pressure-advance page).
``pa-camera``   The pattern of Marius Wachtler's PressureAdvanceCamera (Klipper
                extension ``DRAW_PRESSURE_ADVANCE_PATTERN``, github.com/undingen/
                PressureAdvanceCamera, read at commit 862aacf): a frame drawn twice
                (40 mm wide, ``(n + 3)·pitch`` deep, the second one line width
                inside), lines from the inner frame on the left, 10 % at 10 mm/s, 60 %
                at 100 mm/s, 30 % at 10 mm/s of ``40 − 3·w`` mm, 3 mm pitch, K 0–0.1 by
                0.005, line width 1.2 × nozzle, no numbers. (Its first published
                version, which took the real photos in tests/data/kphoto, used 0.4 mm
                nominal lines and extruded 2.4 times too much: give ``--line-width
                1.0 --slow-length 3.88 --fast-length 23.28 --end-length 11.64``.)
==============  =========================================================================

Flowtwin's ``chevron`` pattern is not a line layout (2-D corners): it is read by
:mod:`.chevron_read`.

The digits are drawn as seven-segment glyphs of the tool's segment length; their exact
strokes differ from the tools' own fonts (they serve as marks, never as measurements).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

from flowtwin.calibration.patterns.pattern import (
    Pattern,
    PatternWriter,
    PrintSettings,
    check_param,
    value_steps,
)
from flowtwin.errors import CalibrationError

__all__ = ["LAYOUTS", "LayoutInfo", "LineLayoutParams", "layout_params", "line_layout_pattern"]


@dataclass(frozen=True, slots=True)
class LineLayoutParams:
    """User parameters of a line layout (speeds mm/s, lengths mm, K in s).

    Attributes
    ----------
    k_start, k_end, k_step
        Advance factors, one per line, front to back.
    slow_speed_mm_s, fast_speed_mm_s
        Speeds of the slow and fast segments.
    slow_length_mm, fast_length_mm
        Lengths of each slow segment and of the fast one.
    end_length_mm
        Length of the last (slow) segment when it differs from the first (``None``: as
        ``slow_length_mm``).
    line_pitch_mm
        Distance between neighbouring lines.
    numbers
        Print the K beside every second line (the tools' option).
    frame
        ``marlin``/``prusa``: the generator's anchor frame (two lines along each end of
        the test lines, from 3 mm before the first line to 3 mm beyond the last).
    prime
        ``marlin``/``prusa``: the generator's two prime lines left of the pattern.
    """

    k_start: float = 0.0
    k_end: float = 0.2
    k_step: float = 0.01
    slow_speed_mm_s: float = 20.0
    fast_speed_mm_s: float = 70.0
    slow_length_mm: float = 20.0
    fast_length_mm: float = 40.0
    line_pitch_mm: float = 5.0
    numbers: bool = True
    end_length_mm: float | None = None
    frame: bool = False
    prime: bool = True

    def __post_init__(self) -> None:
        check_param("k_start", self.k_start, 0.0 <= self.k_start <= 10.0, "0 .. 10 s")
        check_param("slow_speed_mm_s", self.slow_speed_mm_s,
                    0.0 < self.slow_speed_mm_s < self.fast_speed_mm_s,
                    f"0 < slow < fast ({self.fast_speed_mm_s:g} mm/s)")
        check_param("fast_speed_mm_s", self.fast_speed_mm_s, self.fast_speed_mm_s <= 2000.0,
                    "<= 2000 mm/s")
        check_param("slow_length_mm", self.slow_length_mm, self.slow_length_mm >= 1.0,
                    ">= 1 mm")
        check_param("fast_length_mm", self.fast_length_mm, self.fast_length_mm >= 1.0,
                    ">= 1 mm")
        check_param("line_pitch_mm", self.line_pitch_mm, self.line_pitch_mm >= 1.0, ">= 1 mm")
        if self.end_length_mm is not None:
            check_param("end_length_mm", self.end_length_mm, self.end_length_mm >= 1.0,
                        ">= 1 mm")

    @property
    def k_values(self) -> tuple[float, ...]:
        """The advance factors, one per line, front to back."""
        return value_steps(self.k_start, self.k_end, self.k_step, name="k")

    @property
    def last_length_mm(self) -> float:
        """Length of the last slow segment."""
        return self.slow_length_mm if self.end_length_mm is None else self.end_length_mm

    @property
    def length_mm(self) -> float:
        """Length of one test line."""
        return self.slow_length_mm + self.fast_length_mm + self.last_length_mm


@dataclass(frozen=True, slots=True)
class LayoutInfo:
    """A named layout: its defaults, the print settings it implies, and its source.

    Attributes
    ----------
    name
        ``--pattern`` name.
    defaults
        Default :class:`LineLayoutParams` (the tool's defaults).
    line_width_nozzle_ratio
        Line width as a multiple of the nozzle diameter (``None``: the given settings').
    line_width_mm
        Fixed line width of the tool (``None``: from the ratio or the settings).
    accel_mm_s2
        Acceleration the tool's G-code sets (``None``: the printer's).
    source
        Where the geometry and the defaults come from.
    """

    name: str
    defaults: LineLayoutParams
    line_width_nozzle_ratio: float | None
    line_width_mm: float | None
    accel_mm_s2: float | None
    source: str


#: Every line layout by ``--pattern`` name.
LAYOUTS: Mapping[str, LayoutInfo] = {i.name: i for i in (
    LayoutInfo("kline", LineLayoutParams(numbers=False), None, None, None,
               "flowtwin calibrate pattern kline [001 Fig. 10, Table I]"),
    LayoutInfo("marlin", LineLayoutParams(k_start=0.0, k_end=2.0, k_step=0.2), 1.2, None,
               500.0, "Marlin K-factor calibration pattern generator "
               "(MarlinDocumentation _tools/lin_advance/k-factor.js, standard pattern)"),
    LayoutInfo("prusa", LineLayoutParams(k_start=0.0, k_end=0.1, k_step=0.01,
                                         slow_length_mm=25.0, fast_length_mm=100.0),
               None, None, None,
               "Prusa Knowledge Base 'Linear Advance' (25 mm slow, 100 mm fast, 25 mm "
               "slow); speeds, spacing and K range not published there"),
    LayoutInfo("orca", LineLayoutParams(k_start=0.0, k_end=0.098, k_step=0.002,
                                        fast_speed_mm_s=100.0, line_pitch_mm=3.5),
               None, 0.6, None, "OrcaSlicer PA line (CalibPressureAdvanceLine, calib.cpp)"),
    LayoutInfo("orca-legacy", LineLayoutParams(k_start=0.0, k_end=0.098, k_step=0.002,
                                               fast_speed_mm_s=100.0, line_pitch_mm=3.5),
               None, 0.6, None,
               "OrcaSlicer 1.x / Bambu Studio PA line (calib_pressure_advance, Calib.cpp)"),
    LayoutInfo("pa-camera", LineLayoutParams(
        k_start=0.0, k_end=0.1, k_step=0.005, slow_speed_mm_s=10.0, fast_speed_mm_s=100.0,
        slow_length_mm=3.856, fast_length_mm=23.136, end_length_mm=11.568,
        line_pitch_mm=3.0, numbers=False), 1.2, None, None,
        "PressureAdvanceCamera DRAW_PRESSURE_ADVANCE_PATTERN (github.com/undingen/"
        "PressureAdvanceCamera, pressure_advance_camera.py at 862aacf)"),
)}


def layout_params(name: str, values: Mapping[str, Any] | None = None) -> LineLayoutParams:
    """The layout's default parameters with ``values`` (``None`` entries ignored) replacing them.

    Raises
    ------
    CalibrationError
        Unknown layout or parameter, or an invalid value.
    """
    info = _info(name)
    given = {k: v for k, v in (values or {}).items() if v is not None}
    fields = {f.name for f in dataclasses.fields(LineLayoutParams)}
    for key in given:
        if key not in fields:
            raise CalibrationError(f"the {name} layout has no parameter {key!r}", field=key,
                                   allowed=", ".join(sorted(fields)))
    return replace(info.defaults, **given)


def layout_settings(name: str, settings: PrintSettings, *, line_width_given: bool = False,
                    accel_given: bool = False) -> PrintSettings:
    """``settings`` with the layout's line width and acceleration unless given by the user."""
    info = _info(name)
    out = settings
    if not line_width_given:
        if info.line_width_mm is not None:
            out = replace(out, line_width_mm=info.line_width_mm)
        elif info.line_width_nozzle_ratio is not None:
            out = replace(out, line_width_mm=round(info.line_width_nozzle_ratio
                                                   * out.nozzle_diameter_mm, 4))
    if not accel_given and info.accel_mm_s2 is not None:
        out = replace(out, accel_mm_s2=info.accel_mm_s2)
    return out


def _info(name: str) -> LayoutInfo:
    info = LAYOUTS.get(name)
    if info is None:
        raise CalibrationError("unknown line pattern", field="pattern", value=name,
                               allowed=", ".join(LAYOUTS))
    return info


# --- G-code --------------------------------------------------------------------------------

#: Seven-segment strokes of each character on a 1 × 2 cell (x right, y up), pen-up between
#: strokes; the glyph's lower-left corner at (0, 0).
_GLYPHS: Mapping[str, tuple[tuple[tuple[float, float], ...], ...]] = {
    "0": (((0, 0), (1, 0), (1, 2), (0, 2), (0, 0)),),
    "1": (((0.5, 0), (0.5, 2)),),
    "2": (((0, 2), (1, 2), (1, 1), (0, 1), (0, 0), (1, 0)),),
    "3": (((0, 2), (1, 2), (1, 0), (0, 0)), ((0, 1), (1, 1))),
    "4": (((0, 2), (0, 1), (1, 1)), ((1, 2), (1, 0))),
    "5": (((1, 2), (0, 2), (0, 1), (1, 1), (1, 0), (0, 0)),),
    "6": (((1, 2), (0, 2), (0, 0), (1, 0), (1, 1), (0, 1)),),
    "7": (((0, 2), (1, 2), (1, 0)),),
    "8": (((0, 0), (1, 0), (1, 2), (0, 2), (0, 0)), ((0, 1), (1, 1))),
    "9": (((0, 0), (1, 0), (1, 2), (0, 2), (0, 1), (1, 1)),),
    ".": (((0.4, 0), (0.4, 0.25)),),
}


def _number_text(k: float) -> str:
    return f"{k:.3f}".rstrip("0").rstrip(".") or "0"


def _digits(w: PatternWriter, x: float, y: float, text: str, seg_mm: float,
            speed_mm_s: float) -> None:
    """Write ``text`` with its lower-left corner at ``(x, y)``, segments ``seg_mm`` long."""
    for ch in text:
        for stroke in _GLYPHS.get(ch, ()):
            pts = [(x + px * seg_mm, y + py * seg_mm) for px, py in stroke]
            w.travel(*pts[0])
            for px, py in pts[1:]:
                w.extrude_to(px, py, speed_mm_s)
        x += (0.6 if ch in ".1" else 1.5) * seg_mm


def _test_line(w: PatternWriter, p: LineLayoutParams, x0: float, y: float, i: int,
               k: float) -> None:
    w.comment(f" test line {i}: K = {k:g} s")
    w.feature(f"K-line {i}")
    w.travel(x0, y)
    w.set_pa(k, i)
    w.extrude_to(x0 + p.slow_length_mm, y, p.slow_speed_mm_s, role="slow", group=i)
    w.extrude_to(x0 + p.slow_length_mm + p.fast_length_mm, y, p.fast_speed_mm_s,
                 role="fast", group=i)
    w.extrude_to(x0 + p.length_mm, y, p.slow_speed_mm_s, role="slow", group=i)


def _pa_camera(w: PatternWriter, p: LineLayoutParams, ks: tuple[float, ...], x0: float,
               y0: float) -> None:
    """PressureAdvanceCamera's frame (drawn twice, at 20 mm/s) and lines."""
    lw = w.settings.line_width_mm
    n = len(ks)
    xs, ys = x0 - lw, y0 - 2.0 * p.line_pitch_mm          # the frame's outer corner
    width = p.length_mm + 3.0 * lw
    height = (n + 3) * p.line_pitch_mm
    _first_layer(w, xs, ys)
    w.set_pa(0.0, -1)
    w.feature("Skirt/Brim")
    for off in (0.0, lw):
        w.travel(xs + off, ys + off)
        for cx, cy in ((xs + width - off, ys + off), (xs + width - off, ys + height - off),
                       (xs + off, ys + height - off), (xs + off, ys + off)):
            w.extrude_to(cx, cy, 20.0)
    for i, k in enumerate(ks):
        _test_line(w, p, x0, y0 + i * p.line_pitch_mm, i, k)


def _first_layer(w: PatternWriter, x: float, y: float) -> None:
    s = w.settings
    w.move_z(s.layer_height_mm + 2.0)
    w.travel(x, y, retract=False)
    w.layer(0, s.layer_height_mm)


def line_layout_pattern(name: str, settings: PrintSettings,
                        params: LineLayoutParams | None = None) -> Pattern:
    """G-code of the line layout ``name`` (``kind`` of the result: ``name``).

    Parameters
    ----------
    name
        A key of :data:`LAYOUTS` other than ``kline`` (use
        :func:`flowtwin.calibration.patterns.kline.kline_pattern` for that one).
    settings
        Print settings as used (firmware, bead, placement); see :func:`layout_settings`.
    params
        Layout parameters; default the layout's.

    Returns
    -------
    Pattern
        Test segments ``slow``/``fast``/``slow`` per line, group = line index; one advance
        setting per line; marks are untested extrusions.
    """
    info = _info(name)
    if name == "kline":
        raise CalibrationError("the kline layout is written by kline_pattern", field="pattern",
                               value=name, allowed=", ".join(n for n in LAYOUTS if n != name))
    p = params or info.defaults
    ks = p.k_values
    s = settings
    n = len(ks)
    cx, cy = s.center_xy_mm
    x0 = cx - p.length_mm / 2.0
    y0 = cy - (n - 1) * p.line_pitch_mm / 2.0
    y_last = y0 + (n - 1) * p.line_pitch_mm
    x_end = x0 + p.length_mm
    w = PatternWriter(s)
    w.start(f"{name} advance-factor lines (layout: {info.source})", [
        f"K from {ks[0]:g} to {ks[-1]:g} s in steps of {p.k_step:g} s, front to back",
        f"each line: {p.slow_length_mm:g} mm at {p.slow_speed_mm_s:g} mm/s, "
        f"{p.fast_length_mm:g} mm at {p.fast_speed_mm_s:g} mm/s, {p.last_length_mm:g} mm "
        f"at {p.slow_speed_mm_s:g} mm/s; pitch {p.line_pitch_mm:g} mm"])
    lw = s.line_width_mm
    if name == "pa-camera":
        _pa_camera(w, p, ks, x0, y0)
    elif name in ("marlin", "prusa"):
        # two prime lines along Y, 10 mm left of the lines, over the pattern's depth
        depth = (n - 1) * p.line_pitch_mm + 25.0
        xp = x0 - 10.0
        _first_layer(w, xp if p.prime else x0, y0 if p.prime else y0 - 3.0)
        w.feature("Skirt/Brim")
        if p.prime:
            w.extrude_to(xp, y0 + depth, s.prime_speed_mm_s)
            w.travel(xp + 1.5 * lw, y0 + depth, retract=False)
            w.extrude_to(xp + 1.5 * lw, y0, s.prime_speed_mm_s)
        if p.frame:
            # k-factor.js "Print Frame": at each end of the lines, up and back one line
            # width inside, from 3 mm before the first line to 3 mm beyond the last
            for xf, inward in ((x0, lw), (x_end, -lw)):
                w.travel(xf, y0 - 3.0)
                w.extrude_to(xf, y_last + 3.0, p.slow_speed_mm_s, multiplier=1.1)
                w.travel(xf + inward, y_last + 3.0, retract=False)
                w.extrude_to(xf + inward, y0 - 3.0, p.slow_speed_mm_s, multiplier=1.1)
        for i, k in enumerate(ks):
            _test_line(w, p, x0, y0 + i * p.line_pitch_mm, i, k)
        w.set_pa(0.0, -1)
        for xr in (x0 + p.slow_length_mm, x0 + p.slow_length_mm + p.fast_length_mm):
            w.travel(xr, y_last + 5.0)
            w.extrude_to(xr, y_last + 25.0, p.slow_speed_mm_s)
        if p.numbers:
            for i in range(0, n, 2):
                _digits(w, x_end + 2.0, y0 + i * p.line_pitch_mm - 2.0, _number_text(ks[i]),
                        2.0, p.slow_speed_mm_s)
    elif name == "orca":
        _first_layer(w, x0, y0 + n * p.line_pitch_mm)
        w.set_pa(0.0, -1)
        w.feature("Skirt/Brim")
        # Orca's prime ends where line 0 starts; flowtwin stops it 0.02 mm short so that
        # line 0 is a run of its own for the twin
        w.extrude_to(x0, y0 + 0.02, p.slow_speed_mm_s, multiplier=1.2)
        for i, k in enumerate(ks):
            _test_line(w, p, x0, y0 + i * p.line_pitch_mm, i, k)
            if i == 0:
                # Orca extrudes the anchor on from line 0's end; a 0.02 mm hop keeps the
                # test line a run of its own for the twin
                w.set_pa(0.0, -1)
                w.travel(x_end + 0.02, y0, retract=False)
                w.extrude_to(x_end + 0.02, y0 + n * p.line_pitch_mm, p.slow_speed_mm_s,
                             multiplier=1.2)
        w.set_pa(0.0, -1)
        if p.numbers:
            bx = x_end + 0.6
            box_w = 8 * 3.0 * 0.8
            yb0, yb1 = y0 - p.line_pitch_mm, y0 + n * p.line_pitch_mm
            w.travel(bx, yb0)
            x = bx
            while x + lw <= bx + box_w:     # the filled tab, back and forth along Y
                w.extrude_to(x, yb1, p.fast_speed_mm_s)
                x += lw
                w.travel(x, yb1, retract=False)
                w.extrude_to(x, yb0, p.fast_speed_mm_s)
                x += lw
                w.travel(x, yb0, retract=False)
            w.move_z(2.0 * s.layer_height_mm)
            for i in range(0, n, 2):
                _digits(w, bx + 3.0 + lw, y0 + (i - 0.5) * p.line_pitch_mm,
                        _number_text(ks[i]), 1.0, 60.0)
    else:   # orca-legacy
        _first_layer(w, x0 - 2.0, y0 + max(n - 4, 4) * p.line_pitch_mm)
        w.feature("Skirt/Brim")
        w.extrude_to(x0 - 2.0, y0 + 3 * p.line_pitch_mm, p.slow_speed_mm_s, multiplier=1.1)
        for i, k in enumerate(ks):
            _test_line(w, p, x0, y0 + i * p.line_pitch_mm, i, k)
        w.set_pa(0.0, -1)
        if p.numbers:
            xa, xb = x0 + p.slow_length_mm, x0 + p.slow_length_mm + p.fast_length_mm
            w.travel(xa, y_last + 2.0)
            w.extrude_to(xa, y_last + 7.0, p.fast_speed_mm_s)
            w.travel(xb, y_last + 7.0)
            w.extrude_to(xb, y_last + 2.0, p.fast_speed_mm_s)
            for i in range(0, n, 2):
                _digits(w, x_end + 3.0, y0 + i * p.line_pitch_mm - 2.25,
                        _number_text(ks[i]), 2.0, 60.0)
    w.end()
    notes = (f"{n} lines, K = {ks[0]:g} (front) to {ks[-1]:g} s (back)",
             f"layout: {info.source}",
             "pick the line whose width stays even across both speed steps")
    return w.finish(name, "k_s", ks, notes)
