"""Check a pattern with flowtwin's own reader and planner.

A calibration pattern is only worth printing if the printer really runs the speeds it
means to test: a 40 mm "fast" segment that never leaves its acceleration ramp tests
nothing. :func:`verify_pattern` reads the generated G-code back with
:func:`flowtwin.gcode.reader.read_gcode`, plans it for a printer profile with the
Klipper or Marlin planner, and compares, for every
:class:`~flowtwin.calibration.patterns.pattern.TestSegment`, the planned cruise speed
(``Timeline.phases["cruise_v"]``) with the target, and the flow it implies
(``cruise_v · ΔE·A_fil/L``, the reader's E) with the target flow. It also reports unknown
commands and compares the file's net filament with the pattern's.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from flowtwin.calibration.patterns.pattern import Pattern, TestSegment
from flowtwin.errors import CalibrationError
from flowtwin.gcode.moves import MoveKind
from flowtwin.planner.plan_file import plan_gcode
from flowtwin.profiles.printer import PrinterProfile

__all__ = ["PatternCheck", "SegmentCheck", "verify_pattern"]

#: Relative tolerance on speeds and flows: the planner stores speeds as float32 (~6e-8)
#: and F is written with 0.1 mm/min, E with 1e-5 mm; 1e-3 is far above both and far
#: below any speed shortfall that matters for a calibration.
DEFAULT_REL_TOL = 1e-3


@dataclass(frozen=True, slots=True)
class SegmentCheck:
    """A test segment against the plan.

    Attributes
    ----------
    segment
        What the pattern intended.
    cruise_v_mm_s
        Highest speed the planner reaches on the move.
    cruise_t_s
        Time spent at that speed.
    flow_mm3_s
        Flow at that speed from the E the reader read, ``v·ΔE·A_fil/L``.
    reached
        ``cruise_v`` equals the target within the tolerance.
    """

    segment: TestSegment
    cruise_v_mm_s: float
    cruise_t_s: float
    flow_mm3_s: float
    reached: bool


@dataclass(frozen=True)
class PatternCheck:
    """Result of :func:`verify_pattern`.

    Attributes
    ----------
    printer
        Profile the pattern was planned for.
    firmware
        Planner used (``"klipper"`` or ``"marlin"``).
    total_time_s
        Planned print time (motion and dwells; no heating).
    net_filament_mm
        Net filament the reader found in the file.
    unknown_commands
        Commands the reader did not interpret, with counts (should be empty).
    segments
        One check per test segment, in file order.
    warnings
        Reader and planner warnings.
    """

    printer: str
    firmware: str
    total_time_s: float
    net_filament_mm: float
    unknown_commands: dict[str, int]
    segments: tuple[SegmentCheck, ...]
    warnings: tuple[str, ...]

    @property
    def shortfalls(self) -> tuple[SegmentCheck, ...]:
        """Segments that must cruise but do not reach their speed."""
        return tuple(c for c in self.segments if c.segment.must_cruise and not c.reached)

    @property
    def ok(self) -> bool:
        """Every must-cruise segment reaches its speed and no command is unknown."""
        return not self.shortfalls and not self.unknown_commands

    def summary(self) -> dict[str, Any]:
        """Plain JSON-able figures (the first ten shortfalls listed)."""
        return {
            "printer": self.printer,
            "planner": self.firmware,
            "ok": self.ok,
            "total_time_s": self.total_time_s,
            "net_filament_mm": self.net_filament_mm,
            "unknown_commands": dict(self.unknown_commands),
            "test_segments": len(self.segments),
            "reached": sum(1 for c in self.segments if c.reached),
            "shortfalls": [
                {"line": c.segment.line, "role": c.segment.role, "group": c.segment.group,
                 "target_mm_s": c.segment.speed_mm_s, "planned_mm_s": c.cruise_v_mm_s}
                for c in self.shortfalls[:10]],
            "warnings": list(self.warnings[:10]),
        }


def verify_pattern(pattern: Pattern, *,
                   printer: PrinterProfile | str | os.PathLike[str] | None = None,
                   rel_tol: float = DEFAULT_REL_TOL) -> PatternCheck:
    """Read and plan ``pattern``; check the speeds and flows of its test segments.

    Parameters
    ----------
    pattern
        A generated pattern.
    printer
        Printer profile (object, built-in name or TOML path); default: the pattern's
        firmware's generic profile (``generic-klipper`` or ``generic-marlin``).
    rel_tol
        Relative tolerance on speeds (see :data:`DEFAULT_REL_TOL`).

    Returns
    -------
    PatternCheck

    Raises
    ------
    CalibrationError
        A test segment's line is not a move in the file (the pattern is inconsistent).
    """
    if printer is None:
        printer = pattern.settings.firmware.default_printer
    result = plan_gcode(pattern.text().encode(), printer=printer)
    table, timeline = result.table, result.timeline
    moves = table.moves
    lines = np.asarray(moves["line"], dtype=np.int64)
    index = {int(line): i for i, line in enumerate(lines.tolist())}
    start = np.vstack([np.concatenate(([table.start_xyze[a]], moves[c][:-1]))
                       for a, c in enumerate("xyz")])
    end = np.vstack([moves[c] for c in "xyz"])
    length = np.sqrt(np.sum((end - start) ** 2, axis=0))
    area_fil = pattern.settings.filament_area_mm2
    checks: list[SegmentCheck] = []
    for seg in pattern.segments:
        i = index.get(seg.line)
        if i is None or not moves["kind"][i] & MoveKind.EXTRUDE:
            raise CalibrationError("a test segment is not an extruding move of the file",
                                   source="<pattern>", line=seg.line, field=seg.role)
        v = float(timeline.phases["cruise_v"][i])
        flow = v * float(moves["de"][i]) * float(moves["flow"][i]) * area_fil / float(length[i])
        checks.append(SegmentCheck(seg, v, float(timeline.phases["cruise_t"][i]), flow,
                                   abs(v - seg.speed_mm_s) <= rel_tol * seg.speed_mm_s))
    net = table.net_filament_mm()
    return PatternCheck(result.printer, timeline.firmware, float(timeline.total_time_s),
                        float(sum(net.values())), dict(table.unknown_commands),
                        tuple(checks), tuple(table.warnings) + tuple(timeline.warnings))
