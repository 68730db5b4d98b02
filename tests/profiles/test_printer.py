"""Printer profile: Klipper-derived limits and firmware-specific checks."""

from __future__ import annotations

import math
from typing import Any

import pytest

from flowtwin.errors import ProfileError
from flowtwin.profiles import PrinterProfile, load_builtin, profile_from_dict


def klipper(**limits: Any) -> dict[str, Any]:
    return {"name": "k", "firmware": "klipper",
            "limits": {"max_velocity_mm_s": 200.0, "max_accel_mm_s2": 2000.0, **limits},
            "extruder": {"nozzle_diameter_mm": 0.5, "filament_diameter_mm": 2.85}}


def test_klipper_defaults_and_derived_limits() -> None:
    """Klipper: max_z_* default to the XY values (cartesian), cross-section 4·d_nozzle²,
    extrude-only velocity/accel = max_velocity/max_accel · 4·d²/(π/4·D²)."""
    p = profile_from_dict(klipper(), "printer")
    assert isinstance(p, PrinterProfile) and p.limits is not None
    assert p.limits.square_corner_velocity_mm_s == 5.0
    assert p.limits.minimum_cruise_ratio == 0.5
    assert p.limits.instantaneous_corner_velocity_mm_s == 1.0
    assert p.limits.max_extrude_only_distance_mm == 50.0
    assert p.pa_smooth_time_s == 0.040
    r = p.resolved_klipper_limits()
    ratio = 4 * 0.5 ** 2 / (math.pi / 4 * 2.85 ** 2)  # = 0.1567...
    assert r.max_z_velocity_mm_s == 200.0 and r.max_z_accel_mm_s2 == 2000.0
    assert r.max_extrude_cross_section_mm2 == pytest.approx(1.0)
    assert r.max_extrude_only_velocity_mm_s == pytest.approx(200.0 * ratio)
    assert r.max_extrude_only_accel_mm_s2 == pytest.approx(2000.0 * ratio)


def test_klipper_derivation_keeps_configured_values() -> None:
    p = profile_from_dict(klipper(max_z_velocity_mm_s=10.0, max_extrude_cross_section_mm2=5.0,
                                  max_extrude_only_velocity_mm_s=120.0), "printer")
    assert isinstance(p, PrinterProfile)
    r = p.resolved_klipper_limits()
    assert (r.max_z_velocity_mm_s, r.max_extrude_cross_section_mm2,
            r.max_extrude_only_velocity_mm_s) == (10.0, 5.0, 120.0)
    # the extrude-only accel default uses Klipper's *default* ratio, not the configured one
    assert r.max_extrude_only_accel_mm_s2 == pytest.approx(
        2000.0 * 4 * 0.25 / (math.pi / 4 * 2.85 ** 2))


def test_z_limits_may_not_exceed_xy() -> None:
    with pytest.raises(ProfileError, match=r"max_z_velocity_mm_s \(300\) must not exceed "
                                           r"max_velocity_mm_s \(200\)"):
        profile_from_dict(klipper(max_z_velocity_mm_s=300.0), "printer")


def test_minimum_cruise_ratio_below_one() -> None:
    with pytest.raises(ProfileError, match=r"\[limits\.minimum_cruise_ratio\]: must be < 1; "
                                           r"got 1\.0; allowed: >= 0 and < 1"):
        profile_from_dict(klipper(minimum_cruise_ratio=1.0), "printer")


def test_limits_must_match_firmware() -> None:
    data = klipper()
    del data["limits"]
    with pytest.raises(ProfileError, match="firmware 'klipper' needs a \\[limits\\] table"):
        profile_from_dict(data, "printer")
    marlin = load_builtin("generic-marlin").model_dump(mode="json")
    marlin["limits"] = klipper()["limits"]
    with pytest.raises(ProfileError, match="takes \\[marlin\\], not \\[limits\\]"):
        profile_from_dict(marlin, "printer")


def test_marlin_needs_exactly_one_of_jerk_and_junction_deviation() -> None:
    data = load_builtin("generic-marlin").model_dump(mode="json", exclude_none=True)
    data["marlin"]["jerk_mm_s"] = {"x": 10.0, "y": 10.0, "z": 0.3, "e": 5.0}
    with pytest.raises(ProfileError, match=r"exactly one of \[marlin\.jerk_mm_s\]"):
        profile_from_dict(data, "printer")
    del data["marlin"]["junction_deviation_mm"]
    with pytest.raises(ProfileError, match="e_jerk_mm_s belongs to junction deviation"):
        profile_from_dict(data, "printer")
    del data["marlin"]["e_jerk_mm_s"]
    p = profile_from_dict(data, "printer")
    assert isinstance(p, PrinterProfile) and p.marlin is not None
    assert p.marlin.jerk_mm_s is not None and p.marlin.jerk_mm_s.z == 0.3


def test_smooth_time_is_klipper_only() -> None:
    data = load_builtin("generic-marlin").model_dump(mode="json", exclude_none=True)
    data["pressure_advance"]["smooth_time_s"] = 0.04
    with pytest.raises(ProfileError, match="smooth_time_s is a Klipper option"):
        profile_from_dict(data, "printer")


def test_resolved_klipper_limits_refuses_marlin() -> None:
    p = load_builtin("generic-marlin")
    assert isinstance(p, PrinterProfile)
    with pytest.raises(ProfileError, match=r"no Klipper limits.*got 'marlin'"):
        p.resolved_klipper_limits()


def test_filament_not_thinner_than_nozzle() -> None:
    data = klipper()
    data["extruder"]["filament_diameter_mm"] = 0.3
    with pytest.raises(ProfileError, match=r"filament_diameter_mm \(0\.3\) must not be "
                                           r"smaller than nozzle_diameter_mm \(0\.5\)"):
        profile_from_dict(data, "printer")


def test_arc_segment_order() -> None:
    data = klipper()
    data["arcs"] = {"segment_mm": 0.5, "min_segment_mm": 1.0}
    with pytest.raises(ProfileError, match="min_segment_mm \\(1\\) must not exceed"):
        profile_from_dict(data, "printer")
