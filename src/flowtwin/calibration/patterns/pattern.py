"""What every calibration pattern shares: print settings, the G-code writer, the result.

Every extrusion's filament length comes from the slicer bead model
``E = A·L/A_fil`` with ``A = w·h − (1 − π/4)·h²`` [001 Eq. 7]
(:func:`flowtwin.physics.deposition.bead_area_mm2`), times an extrusion multiplier where a
pattern varies it; so the pattern's volumetric flow at print speed ``v`` is
``Q = m·A·v``. Extrusion is relative (``M83``); travels longer than
:attr:`PrintSettings.retract_min_travel_mm` retract and unretract by the same length, so
the net filament of the file is the sum of the bead volumes over ``A_fil``.

The writer records, for each move a pattern means to *test*, its source line, target
speed and flow (:class:`TestSegment`), and every advance command it writes
(:class:`PaSetting`), so :func:`flowtwin.calibration.patterns.verify.verify_pattern` can read the
file back, plan it and check that the printer really reaches those speeds.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Any

from flowtwin.atomic import atomic_open
from flowtwin.errors import CalibrationError
from flowtwin.firmware import (
    ACCEL_MAX_MM_S2,
    MAX_SMOOTH_TIME_S,
    Firmware,
    accel_command,
    pa_command,
)
from flowtwin.gcode.emitter import GcodeEmitter, NumberFormat, Retraction, WordFormats

__all__ = [
    "PATTERN_FORMATS",
    "PaSetting",
    "Pattern",
    "PatternWriter",
    "PrintSettings",
    "TestSegment",
    "check_param",
    "value_steps",
    "write_pattern",
]


def check_param(name: str, value: float, ok: bool, allowed: str) -> None:
    """Raise :class:`CalibrationError` naming ``name`` unless ``ok``."""
    if not ok or (isinstance(value, float) and not math.isfinite(value)):
        raise CalibrationError("invalid pattern parameter", field=name, value=value,
                               allowed=allowed)


def value_steps(start: float, end: float, step: float, *, name: str,
                max_count: int = 200) -> tuple[float, ...]:
    """``start, start + step, …`` up to ``end`` inclusive (to 1e-9 of a step).

    Raises
    ------
    CalibrationError
        ``step <= 0``, ``end < start`` or more than ``max_count`` values.
    """
    check_param(f"{name}_step", step, step > 0.0, "> 0")
    check_param(f"{name}_end", end, end >= start, f">= {name}_start ({start:g})")
    count = int(math.floor((end - start) / step + 1e-9)) + 1
    check_param(f"{name}_step", step, count <= max_count,
                f"at most {max_count} values between {name}_start and {name}_end")
    return tuple(round(start + i * step, 10) for i in range(count))


@dataclass(frozen=True, slots=True)
class PrintSettings:
    """Settings every pattern shares (lengths mm, speeds mm/s, temperatures °C).

    Defaults: a 0.4 mm nozzle, 1.75 mm filament, 0.48 mm lines on 0.2 mm layers (the
    set-up of [001 Table I]), PLA at 215 °C, on a 220 × 220 mm bed.

    Attributes
    ----------
    firmware
        Target firmware (advance and acceleration syntax).
    accel_mm_s2
        Printing and travel acceleration to set at the start, or ``None`` to keep the
        printer's.
    pa_smooth_time_s
        Advance smoothing window to set with every advance command (Klipper, Prusa only).
    center_xy_mm
        Where the pattern's centre goes.
    bed_size_mm
        Printable area from (0, 0); the pattern and its prime line must fit.
    """

    firmware: Firmware = Firmware.KLIPPER
    nozzle_diameter_mm: float = 0.4
    filament_diameter_mm: float = 1.75
    layer_height_mm: float = 0.2
    line_width_mm: float = 0.48
    nozzle_temp_c: float = 215.0
    bed_temp_c: float = 60.0
    fan_percent: float = 0.0
    accel_mm_s2: float | None = None
    pa_smooth_time_s: float | None = None
    center_xy_mm: tuple[float, float] = (110.0, 110.0)
    bed_size_mm: tuple[float, float] = (220.0, 220.0)
    travel_speed_mm_s: float = 150.0
    z_speed_mm_s: float = 10.0
    prime_speed_mm_s: float = 20.0
    retract_mm: float = 0.8
    retract_speed_mm_s: float = 35.0
    retract_min_travel_mm: float = 2.0
    z_hop_mm: float = 0.0

    def __post_init__(self) -> None:
        # a firmware name ("marlin", "rrf") is accepted too and turned into the enum
        object.__setattr__(self, "firmware", Firmware.parse(self.firmware))
        n = self.nozzle_diameter_mm
        check_param("nozzle_diameter_mm", n, 0.05 <= n <= 3.0, "0.05 .. 3 mm")
        check_param("filament_diameter_mm", self.filament_diameter_mm,
                    n < self.filament_diameter_mm <= 5.0, f"{n:g} < d <= 5 mm")
        check_param("layer_height_mm", self.layer_height_mm,
                    0.0 < self.layer_height_mm <= n, f"0 < h <= nozzle ({n:g} mm)")
        # the bead model is ill-defined for w < h [001 Fig. 12]
        check_param("line_width_mm", self.line_width_mm,
                    self.layer_height_mm <= self.line_width_mm <= 3.0 * n,
                    f"layer height ({self.layer_height_mm:g}) <= w <= 3·nozzle")
        check_param("nozzle_temp_c", self.nozzle_temp_c, 0.0 <= self.nozzle_temp_c <= 500.0,
                    "0 .. 500 °C")
        check_param("bed_temp_c", self.bed_temp_c, 0.0 <= self.bed_temp_c <= 200.0,
                    "0 .. 200 °C")
        check_param("fan_percent", self.fan_percent, 0.0 <= self.fan_percent <= 100.0,
                    "0 .. 100 %")
        for name in ("travel_speed_mm_s", "z_speed_mm_s", "prime_speed_mm_s",
                     "retract_speed_mm_s"):
            v = getattr(self, name)
            check_param(name, v, 0.0 < v <= 2000.0, "0 < v <= 2000 mm/s")
        check_param("retract_mm", self.retract_mm, 0.0 <= self.retract_mm <= 20.0, "0 .. 20 mm")
        check_param("retract_min_travel_mm", self.retract_min_travel_mm,
                    self.retract_min_travel_mm >= 0.0, ">= 0 mm")
        check_param("z_hop_mm", self.z_hop_mm, 0.0 <= self.z_hop_mm <= 5.0, "0 .. 5 mm")
        if self.accel_mm_s2 is not None:
            a = self.accel_mm_s2
            check_param("accel_mm_s2", a, 0.0 < a <= ACCEL_MAX_MM_S2,
                        f"0 < a <= {ACCEL_MAX_MM_S2:g} mm/s²")
        if self.pa_smooth_time_s is not None:
            t = self.pa_smooth_time_s
            check_param("pa_smooth_time_s", t, self.firmware.smooths_advance,
                        f"leave it out: {self.firmware.value} has no advance smoothing window")
            check_param("pa_smooth_time_s", t, 0.0 < t <= MAX_SMOOTH_TIME_S,
                        f"0 < t <= {MAX_SMOOTH_TIME_S:g} s")
        for i, size in enumerate(self.bed_size_mm):
            check_param("bed_size_mm", size, 10.0 <= size <= 2000.0, "10 .. 2000 mm")
            c = self.center_xy_mm[i]
            check_param("center_xy_mm", c, 0.0 < c < size, "inside the bed")

    @property
    def filament_area_mm2(self) -> float:
        """``π·d²/4`` of the filament, mm²."""
        return math.pi * self.filament_diameter_mm ** 2 / 4.0

    def bead_area_mm2(self, width_mm: float | None = None,
                      height_mm: float | None = None) -> float:
        """Bead cross-section [001 Eq. 7] of these lines (or of the given ``w``, ``h``), mm²."""
        w = self.line_width_mm if width_mm is None else width_mm
        h = self.layer_height_mm if height_mm is None else height_mm
        from flowtwin.physics.deposition import bead_area_mm2  # numpy: loaded when used

        return float(bead_area_mm2(w, h))

    @property
    def line_spacing_mm(self) -> float:
        """Centre distance of touching lines, ``A/h = w − (1 − π/4)·h`` (Slic3r flow math)."""
        return self.bead_area_mm2() / self.layer_height_mm


@dataclass(frozen=True, slots=True)
class TestSegment:
    """One move whose speed (and flow) the pattern means to test.

    Attributes
    ----------
    line
        1-based line of the move in the G-code.
    role
        What the move is (``"slow"``, ``"fast"``, ``"arm"``, ``"wall"``, ``"step"``, …).
    group
        Index of the tested value (K line, chevron, block, flow step) it belongs to.
    speed_mm_s
        Commanded speed.
    flow_mm3_s
        Volumetric flow at that speed, ``m·A·v``.
    length_mm
        Path length.
    must_cruise
        The pattern is only valid if the printer reaches ``speed_mm_s`` on this move.
    """

    line: int
    role: str
    group: int
    speed_mm_s: float
    flow_mm3_s: float
    length_mm: float
    must_cruise: bool = True


@dataclass(frozen=True, slots=True)
class PaSetting:
    """One advance command the pattern wrote.

    Attributes
    ----------
    line
        1-based line of the command.
    k_s
        The factor set, s.
    group
        The tested group (K line, chevron, tower layer) it applies to.
    z_mm
        Layer height (nozzle Z) at which it applies.
    """

    line: int
    k_s: float
    group: int
    z_mm: float


@dataclass(frozen=True)
class Pattern:
    """A generated calibration pattern and what it means to test.

    Attributes
    ----------
    kind
        Pattern name (``"kline"``, ``"chevron"``, …).
    settings
        The shared print settings.
    lines
        G-code lines, without line breaks.
    filament_mm
        Net filament of the file: the beads' ``bead_filament_mm`` less the final
        retraction (retract/unretract pairs cancel), before rounding E to 5 decimals.
    bead_filament_mm
        Filament of all beads, ``Σ m·A·L/A_fil`` [001 Eq. 7].
    e_words
        Number of E words written (each rounded to 5e-6 mm at most).
    value_name
        What the groups vary (``"k_s"``, ``"extrusion_multiplier"``, ``"flow_mm3_s"``).
    values
        The value of each group, in order.
    segments
        The moves whose speed the pattern tests.
    pa_settings
        Every advance command written, in file order.
    bounds_xy_mm
        ``(x_min, y_min, x_max, y_max)`` of everything extruded.
    notes
        Human-readable facts about the pattern (how to read it).
    """

    kind: str
    settings: PrintSettings
    lines: tuple[str, ...]
    filament_mm: float
    bead_filament_mm: float
    e_words: int
    value_name: str
    values: tuple[float, ...]
    segments: tuple[TestSegment, ...]
    pa_settings: tuple[PaSetting, ...]
    bounds_xy_mm: tuple[float, float, float, float]
    notes: tuple[str, ...] = ()

    def text(self) -> str:
        """The whole file, one line break after each line."""
        return "\n".join(self.lines) + "\n"

    def summary(self) -> dict[str, Any]:
        """Plain JSON-able description (no G-code text)."""
        return {
            "kind": self.kind,
            "firmware": self.settings.firmware.value,
            "lines": len(self.lines),
            "filament_mm": self.filament_mm,
            "bead_filament_mm": self.bead_filament_mm,
            "value_name": self.value_name,
            "values": list(self.values),
            "test_segments": len(self.segments),
            "pa_commands": len(self.pa_settings),
            "bounds_xy_mm": list(self.bounds_xy_mm),
            "bead_area_mm2": self.settings.bead_area_mm2(),
            "notes": list(self.notes),
        }


def write_pattern(path: str | os.PathLike[str], pattern: Pattern) -> int:
    """Write ``pattern`` to ``path`` atomically; return the number of lines."""
    with atomic_open(path, "w") as fh:
        fh.write(pattern.text())
    return len(pattern.lines)


#: Number formats of pattern files: positions to 1 µm, E to 10 nm and F to 0.001 mm/min,
#: trailing zeros of E and F removed.
PATTERN_FORMATS = WordFormats(xyz=NumberFormat(3), e=NumberFormat(5, trim=True),
                              f=NumberFormat(3, trim=True))


class PatternWriter:
    """Builds a pattern's G-code line by line (:class:`~flowtwin.gcode.emitter.GcodeEmitter`),
    tracking position and filament.

    Lines are numbered from 1 as the reader numbers them, so the recorded
    :class:`TestSegment` and :class:`PaSetting` lines point at the written commands.
    Travel, Z and retraction feed rates are written in whole mm/min.
    """

    def __init__(self, settings: PrintSettings) -> None:
        self.settings = settings
        self.out = GcodeEmitter(PATTERN_FORMATS)
        self.segments: list[TestSegment] = []
        self.pa_settings: list[PaSetting] = []
        self.bead_filament_mm = 0.0
        self._bounds = [math.inf, math.inf, -math.inf, -math.inf]

    @property
    def lines(self) -> list[str]:
        """The lines written so far."""
        return self.out.lines

    @property
    def x(self) -> float:
        """Nozzle X after the last line, mm."""
        return self.out.x

    @property
    def y(self) -> float:
        """Nozzle Y after the last line, mm."""
        return self.out.y

    @property
    def z(self) -> float:
        """Nozzle Z of the current layer, mm."""
        return self.out.z

    @property
    def filament_mm(self) -> float:
        """Net filament of the E words so far, mm."""
        return self.out.filament_mm

    @property
    def e_words(self) -> int:
        """E words written so far."""
        return self.out.e_words

    # -- raw lines -------------------------------------------------------------------
    def emit(self, line: str) -> int:
        """Append a line; return its 1-based number."""
        return self.out.line(line)

    def comment(self, text: str) -> None:
        """Append ``;text`` (``" text"`` gives ``; text``)."""
        if text.startswith(" "):
            self.out.comment(text[1:])
        else:
            self.out.marker(text)

    def feature(self, name: str) -> None:
        """Mark a feature type the reader picks up (``;TYPE:name``)."""
        self.out.marker("TYPE", name)

    def _retraction(self) -> Retraction:
        s = self.settings
        return Retraction(s.retract_mm, round(s.retract_speed_mm_s * 60), s.z_hop_mm,
                          round(s.z_speed_mm_s * 60))

    # -- start and end -----------------------------------------------------------------
    def start(self, title: str, description: list[str]) -> None:
        """Header comments, units and modes, heating, homing, acceleration."""
        s = self.settings
        out = self.out
        from flowtwin import __version__

        out.comment(f"{title} -- generated by flowtwin {__version__}")
        for text in description:
            out.comment(text)
        out.comment(f"firmware = {s.firmware.value}")
        out.comment(f"nozzle_diameter = {s.nozzle_diameter_mm:g}")
        out.comment(f"filament_diameter = {s.filament_diameter_mm:g}")
        out.comment(f"layer_height = {s.layer_height_mm:g}")
        out.comment(f"extrusion_width = {s.line_width_mm:g}")
        out.comment(f"bead_area_mm2 = {s.bead_area_mm2():.6f} (A = w*h - (1 - pi/4)*h^2)")
        out.begin(relative_e=True)
        out.heat_bed(round(s.bed_temp_c))
        out.heat_nozzle(round(s.nozzle_temp_c))
        out.home()
        out.heat_bed(round(s.bed_temp_c), wait=True)
        out.heat_nozzle(round(s.nozzle_temp_c), wait=True)
        if s.accel_mm_s2 is not None:
            out.line(accel_command(s.firmware, s.accel_mm_s2))
        out.fan(s.fan_percent)
        out.reset_e()

    def prime(self, x0: float, x1: float, y: float) -> None:
        """Start the first layer with a prime line from ``(x0, y)`` to ``(x1, y)``."""
        s = self.settings
        self.move_z(s.layer_height_mm + 2.0)
        self.travel(x0, y, retract=False)
        self.layer(0, s.layer_height_mm)
        self.feature("Skirt/Brim")
        self.extrude_to(x1, y, s.prime_speed_mm_s)

    def end(self) -> None:
        """Retract, lift, heaters and fan off, motors off."""
        s = self.settings
        out = self.out
        if s.retract_mm > 0:
            out.move(e_mm=-s.retract_mm, f_mm_min=round(s.retract_speed_mm_s * 60))
        self.move_z(self.z + 10.0)
        out.heat_nozzle(0)
        out.heat_bed(0)
        out.fan(0.0)
        out.line("M84")

    # -- motion ----------------------------------------------------------------------------
    def move_z(self, z: float) -> None:
        """Move Z only, at :attr:`PrintSettings.z_speed_mm_s` (nothing if already there)."""
        if abs(z - self.z) < 5e-4:
            return
        self.out.move(z=z, f_mm_min=round(self.settings.z_speed_mm_s * 60))

    def layer(self, index: int, z: float) -> None:
        """Start layer ``index`` at nozzle height ``z`` (PrusaSlicer-style markers)."""
        self.out.marker("LAYER_CHANGE")
        self.out.marker("Z", f"{z:.3f}")
        self.out.marker("HEIGHT", f"{self.settings.layer_height_mm:.3f}")
        self.move_z(z)

    def travel(self, x: float, y: float, *, retract: bool | None = None) -> None:
        """Travel to ``(x, y)``; retract when the travel is long (or when told to)."""
        s = self.settings
        x, y = round(x, 3), round(y, 3)     # as written: the next bead starts exactly here
        dist = math.hypot(x - self.x, y - self.y)
        if dist < 1e-9:
            return
        if retract is None:
            retract = dist >= s.retract_min_travel_mm
        retract = retract and s.retract_mm > 0
        self.out.travel(x, y, round(s.travel_speed_mm_s * 60),
                        self._retraction() if retract else None)

    def extrude_to(self, x: float, y: float, speed_mm_s: float, *, multiplier: float = 1.0,
                   role: str | None = None, group: int = -1, must_cruise: bool = True) -> int:
        """Extrude a bead [001 Eq. 7] to ``(x, y)``; record a test segment if ``role``.

        Returns the line number of the move.
        """
        s = self.settings
        # coordinates are written with 3 decimals: measure the length actually commanded
        x, y = round(x, 3), round(y, 3)
        x0, y0 = self.x, self.y
        length = math.hypot(x - x0, y - y0)
        if length < 1e-9:
            raise CalibrationError("zero-length extrusion in a pattern (internal geometry)",
                                   field=role or "extrude", value=(x, y))
        area = s.bead_area_mm2()
        e = multiplier * area * length / s.filament_area_mm2
        feed_mm_min = round(speed_mm_s * 60.0, 3)
        speed_mm_s = feed_mm_min / 60.0       # the speed actually written
        line = self.out.move(x=x, y=y, e_mm=e, f_mm_min=feed_mm_min)
        self.bead_filament_mm += e
        b = self._bounds
        b[0], b[1] = min(b[0], x0, x), min(b[1], y0, y)
        b[2], b[3] = max(b[2], x0, x), max(b[3], y0, y)
        if role is not None:
            self.segments.append(TestSegment(line, role, group, speed_mm_s,
                                             multiplier * area * speed_mm_s, length,
                                             must_cruise))
        return line

    def set_pa(self, k_s: float, group: int) -> int:
        """Write the advance command for ``k_s`` and record it."""
        s = self.settings
        line = self.out.line(pa_command(s.firmware, k_s, smooth_time_s=s.pa_smooth_time_s))
        self.pa_settings.append(PaSetting(line, k_s, group, self.z))
        return line

    # -- result ------------------------------------------------------------------------------
    def finish(self, kind: str, value_name: str, values: tuple[float, ...],
               notes: tuple[str, ...] = ()) -> Pattern:
        """Check the bed bounds and return the :class:`Pattern`."""
        s = self.settings
        b = tuple(self._bounds)
        if b[0] < 0.0 or b[1] < 0.0 or b[2] > s.bed_size_mm[0] or b[3] > s.bed_size_mm[1]:
            raise CalibrationError(
                f"the {kind} pattern does not fit on the bed", field="bed_size_mm",
                value=f"x {b[0]:.1f}..{b[2]:.1f}, y {b[1]:.1f}..{b[3]:.1f} mm",
                allowed=f"0..{s.bed_size_mm[0]:g} x 0..{s.bed_size_mm[1]:g} mm (move "
                        "center_xy_mm, or test fewer values)")
        return Pattern(kind, s, tuple(self.lines), self.filament_mm, self.bead_filament_mm,
                       self.e_words, value_name,
                       values, tuple(self.segments), tuple(self.pa_settings),
                       (b[0], b[1], b[2], b[3]), notes)
