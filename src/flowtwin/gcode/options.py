"""How to read a G-code file: the options of :func:`flowtwin.gcode.reader.read_gcode`."""

from __future__ import annotations

from dataclasses import dataclass, field

from flowtwin.errors import GcodeError

__all__ = ["FirmwareRetraction", "ReadOptions"]


@dataclass(frozen=True, slots=True)
class FirmwareRetraction:
    """Settings of ``G10``/``G11`` firmware retraction (``M207``/``M208``).

    Defaults are Marlin's (``RETRACT_LENGTH`` 3 mm at 45 mm/s, recover at 8 mm/s).
    """

    length_mm: float = 3.0
    speed_mm_s: float = 45.0
    z_hop_mm: float = 0.0
    extra_unretract_mm: float = 0.0
    unretract_speed_mm_s: float = 8.0


@dataclass(frozen=True, slots=True)
class ReadOptions:
    """How to read a G-code file.

    Attributes
    ----------
    arc_segment_mm
        Split arcs into ``max(1, floor(L / arc_segment_mm))`` equal-angle segments
        (Klipper's ``[gcode_arcs] resolution``); ``None`` uses ``arc_tolerance_mm``.
    arc_tolerance_mm
        Maximum chord deviation from the true arc, mm.
    home_xyz
        Where ``G28`` leaves each axis (Klipper's ``position_endstop``), mm.
    start_xyz
        Toolhead position before the first line, mm.
    firmware_retraction
        ``G10``/``G11`` settings, or ``None`` when the firmware ignores them.
    strict
        Unknown commands are errors instead of counted.
    filament_diameter_mm
        Used by ``M200`` volumetric E when the command gives no diameter.
    """

    arc_segment_mm: float | None = None
    arc_tolerance_mm: float = 0.002
    home_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    start_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    firmware_retraction: FirmwareRetraction | None = field(default_factory=FirmwareRetraction)
    strict: bool = False
    filament_diameter_mm: float = 1.75

    def __post_init__(self) -> None:
        if self.arc_segment_mm is not None and not self.arc_segment_mm > 0:
            raise GcodeError("arc segment length must be positive", field="arc_segment_mm",
                             value=self.arc_segment_mm, allowed="> 0 mm")
        if not self.arc_tolerance_mm > 0:
            raise GcodeError("arc tolerance must be positive", field="arc_tolerance_mm",
                             value=self.arc_tolerance_mm, allowed="> 0 mm")
