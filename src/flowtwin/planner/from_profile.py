"""Firmware planner settings and reader options from a :class:`PrinterProfile`."""

from __future__ import annotations

import math

from flowtwin.firmware import Firmware
from flowtwin.gcode.reader import FirmwareRetraction, ReadOptions
from flowtwin.planner.klipper_config import KlipperExtruder, KlipperSettings
from flowtwin.planner.marlin import MarlinSettings
from flowtwin.planner.marlin_delta import MarlinDelta
from flowtwin.profiles.printer import PrinterProfile

__all__ = ["klipper_settings", "marlin_settings", "read_options"]


def _nan(value: float | None) -> float:
    return math.nan if value is None else float(value)


def klipper_settings(profile: PrinterProfile) -> KlipperSettings:
    """The Klipper settings a ``firmware = "klipper"`` profile describes."""
    lim = profile.resolved_klipper_limits()
    ex = KlipperExtruder(
        nozzle_diameter=profile.extruder.nozzle_diameter_mm,
        filament_diameter=profile.extruder.filament_diameter_mm,
        max_extrude_only_velocity=_nan(lim.max_extrude_only_velocity_mm_s),
        max_extrude_only_accel=_nan(lim.max_extrude_only_accel_mm_s2),
        max_extrude_only_distance=lim.max_extrude_only_distance_mm,
        max_extrude_cross_section=_nan(lim.max_extrude_cross_section_mm2),
        instantaneous_corner_velocity=lim.instantaneous_corner_velocity_mm_s,
        pressure_advance=profile.pressure_advance.k_s,
        pressure_advance_smooth_time=profile.pa_smooth_time_s,
    )
    home = profile.home_position_mm
    return KlipperSettings(
        max_velocity=lim.max_velocity_mm_s, max_accel=lim.max_accel_mm_s2,
        square_corner_velocity=lim.square_corner_velocity_mm_s,
        minimum_cruise_ratio=lim.minimum_cruise_ratio,
        max_z_velocity=_nan(lim.max_z_velocity_mm_s), max_z_accel=_nan(lim.max_z_accel_mm_s2),
        position_endstop=(home.x, home.y, home.z), extruders=(ex,),
        firmware_retraction=_retraction(profile),
        arc_resolution=profile.arcs.segment_mm if profile.arcs.enabled else None,
        source=f"printer profile {profile.name}")


def marlin_settings(profile: PrinterProfile) -> MarlinSettings:
    """The Marlin-style settings of a Marlin, Prusa or RepRapFirmware profile."""
    m = profile.marlin
    if m is None:
        return MarlinSettings()
    jerk = m.jerk_mm_s
    return MarlinSettings(
        max_feedrate_mm_s=(m.max_feedrate_mm_s.x, m.max_feedrate_mm_s.y, m.max_feedrate_mm_s.z,
                           m.max_feedrate_mm_s.e),
        max_acceleration_mm_s2=(m.max_acceleration_mm_s2.x, m.max_acceleration_mm_s2.y,
                                m.max_acceleration_mm_s2.z, m.max_acceleration_mm_s2.e),
        print_accel_mm_s2=m.print_accel_mm_s2, retract_accel_mm_s2=m.retract_accel_mm_s2,
        travel_accel_mm_s2=m.travel_accel_mm_s2,
        jerk_mm_s=(jerk.x, jerk.y, jerk.z, jerk.e) if jerk is not None
        else (10.0, 10.0, 0.3, m.e_jerk_mm_s if m.e_jerk_mm_s is not None else 5.0),
        junction_deviation_mm=m.junction_deviation_mm,
        min_feedrate_mm_s=m.min_feedrate_mm_s, min_travel_feedrate_mm_s=m.min_travel_feedrate_mm_s,
        min_segment_time_s=m.minimum_segment_time_s,
        lin_advance=profile.pressure_advance.k_s > 0,
        linear_advance_k=profile.pressure_advance.k_s,
        delta=_delta(profile))


def _delta(profile: PrinterProfile) -> MarlinDelta | None:
    g = profile.marlin.delta if profile.marlin is not None else None
    if g is None:
        return None
    a, r, d = g.tower_angle_trim_deg, g.radius_trim_mm, g.diagonal_rod_trim_mm
    return MarlinDelta(radius_mm=g.radius_mm, diagonal_rod_mm=g.diagonal_rod_mm,
                       segments_per_second=g.segments_per_second,
                       printable_radius_mm=g.printable_radius_mm, height_mm=g.height_mm,
                       tower_angle_trim_deg=(a[0], a[1], a[2]),
                       radius_trim_mm=(r[0], r[1], r[2]),
                       diagonal_rod_trim_mm=(d[0], d[1], d[2]))


def _retraction(profile: PrinterProfile) -> FirmwareRetraction | None:
    r = profile.retraction
    if not r.enabled:
        return None
    return FirmwareRetraction(length_mm=r.length_mm, speed_mm_s=r.speed_mm_s,
                              z_hop_mm=r.z_hop_mm, extra_unretract_mm=r.unretract_extra_length_mm,
                              unretract_speed_mm_s=r.unretract_speed_mm_s)


def read_options(profile: PrinterProfile, **overrides: object) -> ReadOptions:
    """Reader options matching the firmware of ``profile`` (arcs, homing, retraction)."""
    home = profile.home_position_mm
    if profile.firmware is Firmware.KLIPPER:
        arc_segment: float | None = profile.arcs.segment_mm
    else:
        arc_segment = profile.arcs.segment_mm if profile.arcs.enabled else None
    opts = ReadOptions(arc_segment_mm=arc_segment, home_xyz=(home.x, home.y, home.z),
                       firmware_retraction=_retraction(profile),
                       filament_diameter_mm=profile.extruder.filament_diameter_mm)
    from dataclasses import replace

    return replace(opts, **overrides)  # type: ignore[arg-type]
