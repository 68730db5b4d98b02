"""Printer profile: firmware kind and the motion/extrusion limits the firmware applies.

Two styles of limits, chosen by the firmware:

* ``firmware = "klipper"`` needs a ``[limits]`` table (Klipper's ``[printer]`` and
  ``[extruder]`` options, same defaults as Klipper: ``square_corner_velocity`` 5 mm/s,
  ``minimum_cruise_ratio`` 0.5, ``instantaneous_corner_velocity`` 1 mm/s,
  ``max_extrude_only_distance`` 50 mm, the rest derived as Klipper derives it —
  see :meth:`PrinterProfile.resolved_klipper_limits`);
* ``marlin``, ``prusa``, ``reprapfirmware`` and ``repetier`` need a ``[marlin]`` table of
  per-axis limits (M203 max feedrate, M201 max acceleration, M204 P/R/T, classic jerk
  M205 X/Y/Z/E *or* junction deviation M205 J, M205 B/S/T); a Marlin delta adds
  ``[marlin.delta]`` (its geometry and ``DEFAULT_SEGMENTS_PER_SECOND``; the per-axis
  limits X, Y, Z then apply to the towers A, B, C).

Common to all: ``[extruder]`` (nozzle and filament diameters as the firmware knows them),
``[pressure_advance]``, ``[retraction]`` (firmware retraction, G10/G11 as M207/M208 set it),
``[arcs]`` (G2/G3 segmentation) and ``[home_position_mm]`` (where G28 leaves the axes).
"""

from __future__ import annotations

import math

from pydantic import Field, model_validator

from flowtwin.errors import ProfileError
from flowtwin.firmware import DEFAULT_SMOOTH_TIME_S, Firmware, PlannerFamily
from flowtwin.profiles.base import NamedProfile, ProfileModel

__all__ = [
    "KLIPPER_DEFAULT_SMOOTH_TIME_S",
    "ArcSettings",
    "AxisAccelerations",
    "AxisFeedrates",
    "AxisJerks",
    "FirmwareExtruder",
    "FirmwareRetraction",
    "KlipperLimits",
    "MarlinDeltaGeometry",
    "MarlinLimits",
    "Position",
    "PressureAdvance",
    "PrinterProfile",
]

#: Klipper's default ``pressure_advance_smooth_time`` (klippy/kinematics/extruder.py).
KLIPPER_DEFAULT_SMOOTH_TIME_S = DEFAULT_SMOOTH_TIME_S

_MAX_SPEED = 10000.0   # mm/s, far above any FFF printer
_MAX_ACCEL = 1e6       # mm/s²


class AxisFeedrates(ProfileModel):
    """Per-axis maximum feedrate (Marlin M203), mm/s."""

    x: float = Field(gt=0.0, le=_MAX_SPEED, description="X, mm/s.")
    y: float = Field(gt=0.0, le=_MAX_SPEED, description="Y, mm/s.")
    z: float = Field(gt=0.0, le=_MAX_SPEED, description="Z, mm/s.")
    e: float = Field(gt=0.0, le=_MAX_SPEED, description="E (filament), mm/s.")


class AxisAccelerations(ProfileModel):
    """Per-axis maximum acceleration (Marlin M201), mm/s²."""

    x: float = Field(gt=0.0, le=_MAX_ACCEL, description="X, mm/s².")
    y: float = Field(gt=0.0, le=_MAX_ACCEL, description="Y, mm/s².")
    z: float = Field(gt=0.0, le=_MAX_ACCEL, description="Z, mm/s².")
    e: float = Field(gt=0.0, le=_MAX_ACCEL, description="E (filament), mm/s².")


class AxisJerks(ProfileModel):
    """Classic jerk: per-axis instantaneous speed change (Marlin M205 X/Y/Z/E), mm/s."""

    x: float = Field(ge=0.0, le=1000.0, description="X, mm/s.")
    y: float = Field(ge=0.0, le=1000.0, description="Y, mm/s.")
    z: float = Field(ge=0.0, le=1000.0, description="Z, mm/s.")
    e: float = Field(ge=0.0, le=1000.0, description="E (filament), mm/s.")


class Position(ProfileModel):
    """A toolhead position, mm."""

    x: float = Field(0.0, ge=-1e5, le=1e5, description="X, mm.")
    y: float = Field(0.0, ge=-1e5, le=1e5, description="Y, mm.")
    z: float = Field(0.0, ge=-1e5, le=1e5, description="Z, mm.")


class KlipperLimits(ProfileModel):
    """Klipper toolhead and extruder limits (``[printer]``/``[extruder]`` options).

    Options left out take Klipper's default; the ones Klipper derives are derived by
    :meth:`PrinterProfile.resolved_klipper_limits`.
    """

    max_velocity_mm_s: float = Field(gt=0.0, le=_MAX_SPEED, description="max_velocity, mm/s.")
    max_accel_mm_s2: float = Field(gt=0.0, le=_MAX_ACCEL, description="max_accel, mm/s².")
    square_corner_velocity_mm_s: float = Field(5.0, ge=0.0, le=1000.0,
                                               description="square_corner_velocity, mm/s.")
    minimum_cruise_ratio: float = Field(0.5, ge=0.0, lt=1.0,
                                        description="minimum_cruise_ratio (formerly "
                                                    "max_accel_to_decel), fraction.")
    max_z_velocity_mm_s: float | None = Field(None, gt=0.0, le=_MAX_SPEED,
                                              description="max_z_velocity, mm/s "
                                                          "(default max_velocity).")
    max_z_accel_mm_s2: float | None = Field(None, gt=0.0, le=_MAX_ACCEL,
                                            description="max_z_accel, mm/s² "
                                                        "(default max_accel).")
    instantaneous_corner_velocity_mm_s: float = Field(
        1.0, ge=0.0, le=1000.0, description="Extruder instantaneous_corner_velocity, mm/s.")
    max_extrude_only_velocity_mm_s: float | None = Field(
        None, gt=0.0, le=_MAX_SPEED,
        description="max_extrude_only_velocity, mm/s of filament (default derived).")
    max_extrude_only_accel_mm_s2: float | None = Field(
        None, gt=0.0, le=_MAX_ACCEL,
        description="max_extrude_only_accel, mm/s² of filament (default derived).")
    max_extrude_only_distance_mm: float = Field(50.0, ge=0.0, le=1e6,
                                                description="max_extrude_only_distance, mm.")
    max_extrude_cross_section_mm2: float | None = Field(
        None, gt=0.0, le=1e4, description="max_extrude_cross_section, mm² "
                                          "(default 4·nozzle_diameter²).")

    @model_validator(mode="after")
    def _z_within_xy(self) -> KlipperLimits:
        # Klipper's cartesian kinematics: maxval=max_velocity / max_accel.
        if self.max_z_velocity_mm_s is not None and \
                self.max_z_velocity_mm_s > self.max_velocity_mm_s:
            raise ValueError(f"max_z_velocity_mm_s ({self.max_z_velocity_mm_s:g}) must not "
                             f"exceed max_velocity_mm_s ({self.max_velocity_mm_s:g})")
        if self.max_z_accel_mm_s2 is not None and self.max_z_accel_mm_s2 > self.max_accel_mm_s2:
            raise ValueError(f"max_z_accel_mm_s2 ({self.max_z_accel_mm_s2:g}) must not exceed "
                             f"max_accel_mm_s2 ({self.max_accel_mm_s2:g})")
        return self


def _trim() -> list[float]:
    return [0.0, 0.0, 0.0]


class MarlinDeltaGeometry(ProfileModel):
    """A Marlin linear delta (``Configuration.h`` ``DELTA_*``, ``M665``), mm."""

    radius_mm: float = Field(gt=0.0, le=1000.0, description="DELTA_RADIUS (M665 R), mm.")
    diagonal_rod_mm: float = Field(gt=0.0, le=2000.0,
                                   description="DELTA_DIAGONAL_ROD (M665 L), mm.")
    segments_per_second: float = Field(gt=0.0, le=10000.0,
                                       description="DEFAULT_SEGMENTS_PER_SECOND (M665 S).")
    printable_radius_mm: float = Field(gt=0.0, le=1000.0,
                                       description="PRINTABLE_RADIUS "
                                                   "(DELTA_PRINTABLE_RADIUS), mm.")
    height_mm: float = Field(gt=0.0, le=5000.0, description="DELTA_HEIGHT (M665 H), mm.")
    tower_angle_trim_deg: list[float] = Field(default_factory=_trim, min_length=3,
                                              max_length=3,
                                              description="DELTA_TOWER_ANGLE_TRIM, deg.")
    radius_trim_mm: list[float] = Field(default_factory=_trim, min_length=3, max_length=3,
                                        description="DELTA_RADIUS_TRIM_TOWER, mm.")
    diagonal_rod_trim_mm: list[float] = Field(default_factory=_trim, min_length=3,
                                              max_length=3,
                                              description="DELTA_DIAGONAL_ROD_TRIM_TOWER, "
                                                          "mm.")

    @model_validator(mode="after")
    def _rods_reach(self) -> MarlinDeltaGeometry:
        rod = self.diagonal_rod_mm + min(self.diagonal_rod_trim_mm)
        span = self.radius_mm + max(self.radius_trim_mm) + self.printable_radius_mm
        if rod <= span:
            raise ValueError(f"diagonal_rod_mm ({rod:g} with trim) must exceed radius_mm + "
                             f"printable_radius_mm ({span:g}): the rods cannot reach the edge")
        return self


class MarlinLimits(ProfileModel):
    """Per-axis limits of Marlin-style planners (Marlin, Prusa-Firmware, RRF, Repetier)."""

    max_feedrate_mm_s: AxisFeedrates = Field(description="M203, mm/s.")
    max_acceleration_mm_s2: AxisAccelerations = Field(description="M201, mm/s².")
    print_accel_mm_s2: float = Field(gt=0.0, le=_MAX_ACCEL,
                                     description="M204 P: acceleration of printing moves.")
    retract_accel_mm_s2: float = Field(gt=0.0, le=_MAX_ACCEL,
                                       description="M204 R: acceleration of E-only moves.")
    travel_accel_mm_s2: float = Field(gt=0.0, le=_MAX_ACCEL,
                                      description="M204 T: acceleration of travel moves.")
    jerk_mm_s: AxisJerks | None = Field(None, description="Classic jerk (M205 X/Y/Z/E); "
                                                          "give this or junction deviation.")
    junction_deviation_mm: float | None = Field(None, gt=0.0, le=10.0,
                                                description="Junction deviation (M205 J), mm.")
    e_jerk_mm_s: float | None = Field(None, ge=0.0, le=1000.0,
                                      description="E jerk used with junction deviation "
                                                  "(Marlin DEFAULT_EJERK, linear advance).")
    minimum_segment_time_s: float = Field(0.02, ge=0.0, le=10.0,
                                          description="M205 B (µs in G-code), s.")
    min_feedrate_mm_s: float = Field(0.0, ge=0.0, le=_MAX_SPEED,
                                     description="M205 S: minimum print feedrate, mm/s.")
    min_travel_feedrate_mm_s: float = Field(0.0, ge=0.0, le=_MAX_SPEED,
                                            description="M205 T: minimum travel feedrate, "
                                                        "mm/s.")
    delta: MarlinDeltaGeometry | None = Field(None, description="A linear delta: moves are "
                                                                "cut into segments; the "
                                                                "X/Y/Z limits apply to "
                                                                "the towers.")

    @model_validator(mode="after")
    def _jerk_or_jd(self) -> MarlinLimits:
        if (self.jerk_mm_s is None) == (self.junction_deviation_mm is None):
            raise ValueError("give exactly one of [marlin.jerk_mm_s] (classic jerk) or "
                             "junction_deviation_mm")
        if self.jerk_mm_s is not None and self.e_jerk_mm_s is not None:
            raise ValueError("e_jerk_mm_s belongs to junction deviation; with classic jerk "
                             "use jerk_mm_s.e")
        return self


class FirmwareExtruder(ProfileModel):
    """Nozzle and filament diameters as configured in the firmware (may differ from the
    real hot end and filament, e.g. 1.75 mm configured for a 1.752 mm filament)."""

    nozzle_diameter_mm: float = Field(gt=0.0, le=3.0, description="nozzle_diameter, mm.")
    filament_diameter_mm: float = Field(gt=0.0, le=5.0, description="filament_diameter, mm.")

    @model_validator(mode="after")
    def _filament_not_thinner(self) -> FirmwareExtruder:
        # Klipper: filament_diameter minval=nozzle_diameter.
        if self.filament_diameter_mm < self.nozzle_diameter_mm:
            raise ValueError(f"filament_diameter_mm ({self.filament_diameter_mm:g}) must not "
                             f"be smaller than nozzle_diameter_mm "
                             f"({self.nozzle_diameter_mm:g})")
        return self

    @property
    def filament_area_mm2(self) -> float:
        """``π·d²/4`` of the configured filament diameter, mm² (E mm → mm³ factor)."""
        return math.pi * self.filament_diameter_mm ** 2 / 4.0


class PressureAdvance(ProfileModel):
    """Pressure / linear advance as set in the firmware.

    ``k_s``: Klipper ``pressure_advance``, Marlin ``M900 K`` (linear advance 1.5), RRF
    ``M572 S`` — seconds of filament lead per mm/s of filament speed [001 Eq. 11].
    ``smooth_time_s``: Klipper only (``pressure_advance_smooth_time``, default 0.040 s);
    other firmwares do not smooth and must leave it out.
    """

    k_s: float = Field(0.0, ge=0.0, le=10.0, description="Advance factor K, s.")
    smooth_time_s: float | None = Field(None, gt=0.0, le=0.2,
                                        description="Klipper smoothing window, s "
                                                    "(default 0.040).")


class FirmwareRetraction(ProfileModel):
    """Firmware retraction (G10/G11) settings as ``M207``/``M208`` (Klipper
    ``SET_RETRACTION``) would set them. Defaults are Klipper's ``[firmware_retraction]``."""

    enabled: bool = Field(False, description="G10/G11 are understood.")
    length_mm: float = Field(0.0, ge=0.0, le=1000.0, description="retract_length, mm.")
    speed_mm_s: float = Field(20.0, gt=0.0, le=_MAX_SPEED, description="retract_speed, mm/s.")
    unretract_extra_length_mm: float = Field(0.0, ge=-100.0, le=1000.0,
                                             description="unretract_extra_length, mm.")
    unretract_speed_mm_s: float = Field(10.0, gt=0.0, le=_MAX_SPEED,
                                        description="unretract_speed, mm/s.")
    z_hop_mm: float = Field(0.0, ge=0.0, le=100.0, description="Z lift on retract, mm.")


class ArcSettings(ProfileModel):
    """How G2/G3 arcs are cut into straight segments.

    ``segment_mm``: Klipper ``[gcode_arcs] resolution`` (default 1.0 mm); Marlin
    ``MAX_ARC_SEGMENT_MM`` (``MM_PER_ARC_SEGMENT`` in Marlin 1.x and Prusa-Firmware).
    ``min_segment_mm`` and ``min_circle_segments``: Marlin ``MIN_ARC_SEGMENT_MM`` and
    ``MIN_CIRCLE_SEGMENTS`` (Prusa: ``MIN_MM_PER_ARC_SEGMENT``, ``MIN_ARC_SEGMENTS``).
    """

    enabled: bool = Field(True, description="G2/G3 are understood (Klipper: a "
                                            "[gcode_arcs] section exists).")
    segment_mm: float = Field(1.0, gt=0.0, le=100.0, description="Segment length, mm.")
    min_segment_mm: float | None = Field(None, gt=0.0, le=100.0,
                                         description="Shortest segment (Marlin), mm.")
    min_circle_segments: int | None = Field(None, ge=0, le=10000,
                                            description="Fewest segments of a full circle "
                                                        "(Marlin).")

    @model_validator(mode="after")
    def _order(self) -> ArcSettings:
        if self.min_segment_mm is not None and self.min_segment_mm > self.segment_mm:
            raise ValueError(f"min_segment_mm ({self.min_segment_mm:g}) must not exceed "
                             f"segment_mm ({self.segment_mm:g})")
        return self


class PrinterProfile(NamedProfile):
    """A printer as its firmware sees it: limits, advance, retraction, arcs, homing."""

    firmware: Firmware = Field(strict=False, description="Firmware family "
                                                         "(flowtwin.firmware).")
    limits: KlipperLimits | None = Field(None, description="Klipper limits (firmware = "
                                                           "'klipper').")
    marlin: MarlinLimits | None = Field(None, description="Per-axis limits (every other "
                                                          "firmware).")
    extruder: FirmwareExtruder = Field(description="Diameters the firmware is configured "
                                                   "with.")
    pressure_advance: PressureAdvance = Field(PressureAdvance.model_validate({}),
                                              description="Pressure/linear advance.")
    retraction: FirmwareRetraction = Field(FirmwareRetraction.model_validate({}),
                                           description="Firmware retraction (G10/G11).")
    arcs: ArcSettings = Field(ArcSettings.model_validate({}), description="G2/G3 handling.")
    home_position_mm: Position = Field(Position.model_validate({}),
                                       description="Where G28 leaves the axes, mm.")

    @model_validator(mode="after")
    def _limits_match_firmware(self) -> PrinterProfile:
        if self.firmware.planner is PlannerFamily.KLIPPER:
            if self.limits is None:
                raise ValueError("firmware 'klipper' needs a [limits] table")
            if self.marlin is not None:
                raise ValueError("firmware 'klipper' takes [limits], not [marlin]")
        else:
            if self.marlin is None:
                raise ValueError(f"firmware {self.firmware!r} needs a [marlin] table of "
                                 "per-axis limits")
            if self.limits is not None:
                raise ValueError(f"firmware {self.firmware!r} takes [marlin], not [limits] "
                                 "(Klipper's)")
            if self.pressure_advance.smooth_time_s is not None:
                raise ValueError("pressure_advance.smooth_time_s is a Klipper option; "
                                 f"firmware {self.firmware!r} does not smooth the advance")
        return self

    @property
    def pa_smooth_time_s(self) -> float:
        """Pressure-advance smoothing window in force, s (0 where the firmware has none)."""
        if self.firmware is not Firmware.KLIPPER:
            return 0.0
        value = self.pressure_advance.smooth_time_s
        return KLIPPER_DEFAULT_SMOOTH_TIME_S if value is None else value

    def resolved_klipper_limits(self) -> KlipperLimits:
        """Klipper limits with every derived option filled in the way Klipper derives it.

        ``max_z_velocity``/``max_z_accel`` default to ``max_velocity``/``max_accel``
        (cartesian kinematics); ``max_extrude_cross_section`` to ``4·d_nozzle²``;
        ``max_extrude_only_velocity``/``accel`` to ``max_velocity``/``max_accel`` times
        ``4·d_nozzle²/A_filament`` (klippy/kinematics/extruder.py).

        Raises
        ------
        ProfileError
            If the firmware is not Klipper (there are no Klipper limits to resolve).
        """
        if self.limits is None:
            raise ProfileError(f"printer {self.name!r} has no Klipper limits", field="firmware",
                               value=self.firmware.value, allowed="'klipper'")
        lim = self.limits
        def_cross_mm2 = 4.0 * self.extruder.nozzle_diameter_mm ** 2
        def_ratio = def_cross_mm2 / self.extruder.filament_area_mm2
        return lim.model_copy(update={
            "max_z_velocity_mm_s": lim.max_z_velocity_mm_s or lim.max_velocity_mm_s,
            "max_z_accel_mm_s2": lim.max_z_accel_mm_s2 or lim.max_accel_mm_s2,
            "max_extrude_cross_section_mm2": lim.max_extrude_cross_section_mm2 or def_cross_mm2,
            "max_extrude_only_velocity_mm_s": (lim.max_extrude_only_velocity_mm_s
                                               or lim.max_velocity_mm_s * def_ratio),
            "max_extrude_only_accel_mm_s2": (lim.max_extrude_only_accel_mm_s2
                                             or lim.max_accel_mm_s2 * def_ratio),
        })
