"""Klipper printer settings and the ``printer.cfg`` reader.

:class:`KlipperSettings` holds what Klipper's motion planner reads from a printer's
``printer.cfg`` (``[printer]``, the kinematics' sections — ``[stepper_x/y/z]``,
``[stepper_a/b/c]``, ``[carriage *]`` ... —, ``[extruder]`` .. ``[extruderN]``,
``[extruder_stepper]``, ``[firmware_retraction]``, ``[gcode_arcs]``), with Klipper's own
defaults and bounds (Klipper ``docs/Config_Reference.md``). :func:`load_printer_cfg`
parses a real ``printer.cfg`` (:mod:`flowtwin.planner.klipper_cfg`: includes, macros,
SAVE_CONFIG) and builds its kinematics (:mod:`flowtwin.planner.kinematics`). Unknown
sections and options are ignored; a value outside Klipper's range raises
:class:`~flowtwin.errors.ProfileError` naming the file, line, option, value and the
allowed range.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace

from flowtwin.errors import ProfileError
from flowtwin.gcode.reader import FirmwareRetraction, ReadOptions
from flowtwin.planner.kinematics import box_kinematics, load_kinematics, names
from flowtwin.planner.kinematics.base import Kinematics, PrinterLimits
from flowtwin.planner.klipper_cfg import check_value as _check
from flowtwin.planner.klipper_cfg import read_cfg

__all__ = [
    "KINEMATICS",
    "KlipperExtruder",
    "KlipperSettings",
    "klipper_read_options",
    "load_printer_cfg",
]

#: Largest nozzle or filament diameter the twin accepts from a printer.cfg, mm.
MAX_DIAMETER_MM = 10.0
#: Smallest, mm (Klipper takes any positive value; squares of denormal diameters such as
#: 1e-320 underflow to zero and no nozzle is finer than 10 µm).
MIN_DIAMETER_MM = 0.01

#: Every kinematics the planner models (Klipper's names; one module each in
#: :mod:`flowtwin.planner.kinematics`).
KINEMATICS = names()

#: Klipper's ``SDS_CHECK_TIME``: minimum step-generation scan window, s.
SDS_CHECK_TIME_S = 0.001


def _derived(value: float) -> bool:
    return isinstance(value, float) and math.isnan(value)


@dataclass(frozen=True, slots=True)
class KlipperExtruder:
    """One ``[extruder]`` / ``[extruderN]`` section (lengths mm, speeds mm/s, s).

    Fields left at ``nan`` take Klipper's derived default when the extruder is placed in
    :class:`KlipperSettings`: ``max_extrude_only_velocity`` = ``max_velocity`` · r,
    ``max_extrude_only_accel`` = ``max_accel`` · r with r = 4·nozzle²/filament area, and
    ``max_extrude_cross_section`` = 4·nozzle² (Klipper ``kinematics/extruder.py``).
    """

    name: str = "extruder"
    nozzle_diameter: float = 0.4
    filament_diameter: float = 1.75
    max_extrude_only_velocity: float = math.nan
    max_extrude_only_accel: float = math.nan
    max_extrude_only_distance: float = 50.0
    max_extrude_cross_section: float = math.nan
    instantaneous_corner_velocity: float = 1.0
    pressure_advance: float = 0.0
    pressure_advance_smooth_time: float = 0.040

    @property
    def filament_area_mm2(self) -> float:
        """Cross-section of the filament, mm²."""
        return math.pi * (self.filament_diameter * 0.5) ** 2

    @property
    def max_extrude_ratio(self) -> float:
        """Largest E distance per XYZ distance before Klipper refuses a move."""
        return self.max_extrude_cross_section / self.filament_area_mm2


@dataclass(frozen=True, slots=True)
class KlipperSettings:
    """Motion settings of a Klipper printer (mm, s; ``nan`` = Klipper's derived default).

    Attributes
    ----------
    max_velocity, max_accel
        ``[printer]`` limits, mm/s and mm/s².
    square_corner_velocity
        mm/s; sets the junction deviation ``scv²·(√2 − 1)/max_accel``.
    minimum_cruise_ratio
        Fraction of a move that must cruise (``max_accel_to_decel`` = accel·(1 − ratio)).
    max_z_velocity, max_z_accel
        Z limits (default: ``max_velocity`` / ``max_accel``).
    kinematics
        One of :data:`KINEMATICS`.
    position_endstop, position_min, position_max
        Per axis X, Y, Z, mm. ``G28`` leaves an axis at ``position_endstop``. Without
        ``kin`` they are the range box of a cartesian-like kinematics; with ``kin`` they
        are set from it (its home position and reported axis range).
    extruders
        ``[extruder]``, ``[extruder1]`` ... in tool order (``T<n>`` is ``extruders[n]``).
    extra_smooth_times
        Pressure-advance smooth times of ``[extruder_stepper]`` sections with PA, s.
    firmware_retraction
        ``[firmware_retraction]`` settings, or ``None`` (then ``G10``/``G11`` are unknown).
    arc_resolution
        ``[gcode_arcs] resolution``, mm, or ``None`` (no ``[gcode_arcs]``: G2/G3 unknown).
    source
        Where the settings came from (for messages).
    kin
        The kinematics (range, per-move limits, homing). ``None``: built from
        ``kinematics``, the position box and the Z limits, which works for the
        cartesian-like kinematics (cartesian, corexy, corexz, hybrids, generic
        cartesian); a delta, polar ... needs its geometry (:func:`load_printer_cfg`).
    """

    max_velocity: float
    max_accel: float
    square_corner_velocity: float = 5.0
    minimum_cruise_ratio: float = 0.5
    max_z_velocity: float = math.nan
    max_z_accel: float = math.nan
    kinematics: str = "cartesian"
    position_endstop: tuple[float, float, float] = (0.0, 0.0, 0.0)
    position_min: tuple[float, float, float] = (-math.inf, -math.inf, -math.inf)
    position_max: tuple[float, float, float] = (math.inf, math.inf, math.inf)
    extruders: tuple[KlipperExtruder, ...] = (KlipperExtruder(),)
    extra_smooth_times: tuple[float, ...] = ()
    firmware_retraction: FirmwareRetraction | None = None
    arc_resolution: float | None = 1.0
    source: str = "<settings>"
    kin: Kinematics | None = None

    def __post_init__(self) -> None:
        src = self.source
        _check(src, "max_velocity", self.max_velocity, above=0.0)
        _check(src, "max_accel", self.max_accel, above=0.0)
        _check(src, "square_corner_velocity", self.square_corner_velocity, minval=0.0)
        _check(src, "minimum_cruise_ratio", self.minimum_cruise_ratio, minval=0.0, below=1.0)
        if self.kinematics not in KINEMATICS:
            raise ProfileError("kinematics not supported by the Klipper planner", source=src,
                               field="kinematics", value=self.kinematics,
                               allowed=", ".join(KINEMATICS))
        if self.kin is not None and self.kin.name != self.kinematics:
            raise ProfileError("kinematics name and kinematics object disagree", source=src,
                               field="kinematics", value=(self.kinematics, self.kin.name),
                               allowed="the same kinematics")
        zv = self.max_velocity if _derived(self.max_z_velocity) else self.max_z_velocity
        za = self.max_accel if _derived(self.max_z_accel) else self.max_z_accel
        _check(src, "max_z_velocity", zv, above=0.0, maxval=self.max_velocity)
        _check(src, "max_z_accel", za, above=0.0, maxval=self.max_accel)
        object.__setattr__(self, "max_z_velocity", float(zv))
        object.__setattr__(self, "max_z_accel", float(za))
        if self.kin is None:
            for axis in range(3):
                lo, hi = self.position_min[axis], self.position_max[axis]
                if not lo < hi or not lo <= self.position_endstop[axis] <= hi:
                    raise ProfileError("position_endstop must lie between position_min and "
                                       "position_max", source=src,
                                       field=f"stepper_{'xyz'[axis]}",
                                       value=(lo, self.position_endstop[axis], hi),
                                       allowed="position_min <= position_endstop <= "
                                       "position_max")
            object.__setattr__(self, "kin", box_kinematics(
                self.kinematics, home=self.position_endstop, lo=self.position_min,
                hi=self.position_max, max_z_velocity=float(zv), max_z_accel=float(za),
                source=src))
        else:
            object.__setattr__(self, "position_endstop", self.kin.home_position)
            object.__setattr__(self, "position_min", self.kin.axes_min)
            object.__setattr__(self, "position_max", self.kin.axes_max)
        object.__setattr__(self, "extruders",
                           tuple(self._resolve(ex) for ex in self.extruders))
        for t in self.extra_smooth_times:
            _check(src, "pressure_advance_smooth_time", t, above=0.0, maxval=0.2)
        if self.arc_resolution is not None:
            _check(src, "resolution", self.arc_resolution, above=0.0)

    def _resolve(self, ex: KlipperExtruder) -> KlipperExtruder:
        src = f"{self.source} [{ex.name}]"
        _check(src, "nozzle_diameter", ex.nozzle_diameter, above=0.0)
        _check(src, "filament_diameter", ex.filament_diameter, minval=ex.nozzle_diameter)
        def_cross = 4.0 * ex.nozzle_diameter ** 2
        def_ratio = def_cross / (math.pi * (ex.filament_diameter * 0.5) ** 2)
        vel = ex.max_extrude_only_velocity
        acc = ex.max_extrude_only_accel
        cross = ex.max_extrude_cross_section
        ex = replace(ex,
                     max_extrude_only_velocity=self.max_velocity * def_ratio if _derived(vel)
                     else vel,
                     max_extrude_only_accel=self.max_accel * def_ratio if _derived(acc)
                     else acc,
                     max_extrude_cross_section=def_cross if _derived(cross) else cross)
        _check(src, "max_extrude_only_velocity", ex.max_extrude_only_velocity, above=0.0)
        _check(src, "max_extrude_only_accel", ex.max_extrude_only_accel, above=0.0)
        _check(src, "max_extrude_cross_section", ex.max_extrude_cross_section, above=0.0)
        _check(src, "max_extrude_only_distance", ex.max_extrude_only_distance, minval=0.0)
        _check(src, "instantaneous_corner_velocity", ex.instantaneous_corner_velocity,
               minval=0.0)
        _check(src, "pressure_advance", ex.pressure_advance, minval=0.0)
        _check(src, "pressure_advance_smooth_time", ex.pressure_advance_smooth_time,
               above=0.0, maxval=0.2)
        return ex

    @property
    def kinematics_model(self) -> Kinematics:
        """The kinematics (always set after construction)."""
        assert self.kin is not None
        return self.kin

    # -- convenience views (first extruder) ----------------------------------------------
    @property
    def extruder_names(self) -> tuple[str, ...]:
        """Section names of the extruders, tool order."""
        return tuple(ex.name for ex in self.extruders)

    @property
    def extruder_count(self) -> int:
        """Number of real extruders (tools ``T0`` .. ``T<count-1>``)."""
        return len(self.extruders)

    def _first(self) -> KlipperExtruder:
        if not self.extruders:
            raise ProfileError("the printer has no [extruder] section", source=self.source,
                               field="extruder")
        return self.extruders[0]

    @property
    def instantaneous_corner_velocity(self) -> float:
        """``[extruder] instantaneous_corner_velocity``, mm/s."""
        return self._first().instantaneous_corner_velocity

    @property
    def max_extrude_only_velocity(self) -> float:
        """``[extruder]`` extrude-only speed limit, mm/s of filament."""
        return self._first().max_extrude_only_velocity

    @property
    def max_extrude_only_accel(self) -> float:
        """``[extruder]`` extrude-only acceleration limit, mm/s² of filament."""
        return self._first().max_extrude_only_accel

    @property
    def max_extrude_only_distance(self) -> float:
        """``[extruder]`` longest extrude-only move, mm of filament."""
        return self._first().max_extrude_only_distance

    @property
    def nozzle_diameter(self) -> float:
        """``[extruder] nozzle_diameter``, mm."""
        return self._first().nozzle_diameter

    @property
    def filament_diameter(self) -> float:
        """``[extruder] filament_diameter``, mm."""
        return self._first().filament_diameter

    @property
    def pressure_advance(self) -> float:
        """``[extruder] pressure_advance``, s."""
        return self._first().pressure_advance

    @property
    def smooth_time(self) -> float:
        """``[extruder] pressure_advance_smooth_time``, s."""
        return self._first().pressure_advance_smooth_time

    @property
    def junction_deviation(self) -> float:
        """Klipper's junction deviation ``scv²·(√2 − 1)/max_accel``, mm."""
        return self.square_corner_velocity ** 2 * (math.sqrt(2.0) - 1.0) / self.max_accel

    @property
    def kin_flush_delay(self) -> float:
        """Step-generation scan window, s: half the largest active PA smooth time, ≥ 1 ms."""
        times = [ex.pressure_advance_smooth_time * 0.5 for ex in self.extruders
                 if ex.pressure_advance]
        times += [t * 0.5 for t in self.extra_smooth_times]
        return max([SDS_CHECK_TIME_S, *times])


def load_printer_cfg(path: str | os.PathLike[str]) -> KlipperSettings:
    """Read the motion settings of a Klipper ``printer.cfg``.

    Parameters
    ----------
    path
        The printer.cfg file; ``[include]`` paths are relative to the including file.

    Returns
    -------
    KlipperSettings
        Limits, homing positions, extruders, firmware retraction and arc resolution.

    Raises
    ------
    ProfileError
        The file cannot be read or parsed, a required section or option is missing, or a
        value is out of Klipper's range (the message names file, line, option, value and
        the allowed range).
    """
    source = str(path)
    cfg = read_cfg(path)
    pr = cfg.require("printer", "a Klipper printer.cfg with [printer]")
    kin_name = pr.get("kinematics").strip()
    max_v = pr.getfloat("max_velocity", above=0.0)
    max_a = pr.getfloat("max_accel", above=0.0)
    mcr_default = 0.5
    if not pr.has("minimum_cruise_ratio") and pr.has("max_accel_to_decel"):
        atd = pr.getfloat("max_accel_to_decel", above=0.0)
        mcr_default = 1.0 - min(1.0, atd / max_a)
    mcr = pr.getfloat("minimum_cruise_ratio", mcr_default, minval=0.0, below=1.0)
    scv = pr.getfloat("square_corner_velocity", 5.0, minval=0.0)
    kin = load_kinematics(kin_name, cfg, PrinterLimits(max_v, max_a, pr))

    extruders = []
    for i in range(100):
        name = "extruder" + (str(i) if i else "")
        if not cfg.has_section(name):
            break
        ex = cfg.section(name)
        # no firmware bound; the twin needs diameters a hot end can have (mm)
        nozzle = ex.getfloat("nozzle_diameter", minval=MIN_DIAMETER_MM,
                             maxval=MAX_DIAMETER_MM)
        filament = ex.getfloat("filament_diameter", minval=nozzle, maxval=MAX_DIAMETER_MM)
        def_cross = 4.0 * nozzle ** 2
        def_ratio = def_cross / (math.pi * (filament * 0.5) ** 2)
        extruders.append(KlipperExtruder(
            name=name, nozzle_diameter=nozzle, filament_diameter=filament,
            max_extrude_cross_section=ex.getfloat("max_extrude_cross_section", def_cross,
                                                  above=0.0),
            max_extrude_only_velocity=ex.getfloat("max_extrude_only_velocity",
                                                  max_v * def_ratio, above=0.0),
            max_extrude_only_accel=ex.getfloat("max_extrude_only_accel", max_a * def_ratio,
                                               above=0.0),
            max_extrude_only_distance=ex.getfloat("max_extrude_only_distance", 50.0,
                                                  minval=0.0),
            instantaneous_corner_velocity=ex.getfloat("instantaneous_corner_velocity", 1.0,
                                                      minval=0.0),
            pressure_advance=ex.getfloat("pressure_advance", 0.0, minval=0.0),
            pressure_advance_smooth_time=ex.getfloat("pressure_advance_smooth_time", 0.040,
                                                     above=0.0, maxval=0.2)))
    extra = []
    for es in cfg.prefix_sections("extruder_stepper "):
        pa = es.getfloat("pressure_advance", 0.0, minval=0.0)
        st_ = es.getfloat("pressure_advance_smooth_time", 0.040, above=0.0, maxval=0.2)
        if pa:
            extra.append(st_)

    retraction = None
    if cfg.has_section("firmware_retraction"):
        fr = cfg.section("firmware_retraction")
        # Klipper sends "G1 E-%.5f F%d": the length is rounded, the feed truncated to mm/min
        speed = fr.getfloat("retract_speed", 20.0, minval=1.0)
        unspeed = fr.getfloat("unretract_speed", 10.0, minval=1.0)
        retraction = FirmwareRetraction(
            length_mm=round(fr.getfloat("retract_length", 0.0, minval=0.0), 5),
            speed_mm_s=math.floor(speed * 60.0) / 60.0,
            z_hop_mm=0.0,
            extra_unretract_mm=fr.getfloat("unretract_extra_length", 0.0, minval=0.0),
            unretract_speed_mm_s=math.floor(unspeed * 60.0) / 60.0)
    arc = None
    if cfg.has_section("gcode_arcs"):
        arc = cfg.section("gcode_arcs").getfloat("resolution", 1.0, above=0.0)

    return KlipperSettings(
        max_velocity=max_v, max_accel=max_a, square_corner_velocity=scv,
        minimum_cruise_ratio=mcr,
        max_z_velocity=kin.max_z_velocity if math.isfinite(kin.max_z_velocity) else math.nan,
        max_z_accel=kin.max_z_accel if math.isfinite(kin.max_z_accel) else math.nan,
        kinematics=kin.name, extruders=tuple(extruders), extra_smooth_times=tuple(extra),
        firmware_retraction=retraction, arc_resolution=arc, source=source, kin=kin)


def klipper_read_options(settings: KlipperSettings, **overrides: object) -> ReadOptions:
    """G-code reading options that match a Klipper printer.

    Arcs are split at ``[gcode_arcs] resolution`` (1 mm when the section is absent, see
    the planner's warning), ``G28`` leaves axes at ``position_endstop``, ``G10``/``G11``
    follow ``[firmware_retraction]`` (ignored without it), the head starts at X0 Y0 Z0.

    Parameters
    ----------
    settings
        The printer.
    **overrides
        Other :class:`~flowtwin.gcode.reader.ReadOptions` fields (e.g. ``strict=True``).
    """
    opts = ReadOptions(arc_segment_mm=settings.arc_resolution or 1.0,
                       home_xyz=settings.position_endstop,
                       firmware_retraction=settings.firmware_retraction,
                       filament_diameter_mm=(settings.extruders[0].filament_diameter
                                             if settings.extruders else 1.75))
    return replace(opts, **overrides)  # type: ignore[arg-type]
