"""The kinematics modules: geometry, ranges, caps, homing and config errors.

Known answers: the zones real Klipper logs when it loads a delta ("Delta max build
height ... (radius tapered above ...)", "Delta max build radius ... (moves slowed past
... and ...)", klippy 84104bb on the oracle configs of ``tests/data/kinematics``), and
plain geometry (arms at their lengths, distances to a segment).
"""

from __future__ import annotations

import math
import pkgutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import flowtwin.planner.kinematics as kinematics_pkg
from flowtwin.errors import GcodeError, ProfileError
from flowtwin.gcode.reader import read_gcode
from flowtwin.planner.kinematics import names
from flowtwin.planner.kinematics.base import MoveGeometry, trilaterate
from flowtwin.planner.kinematics.polar import distance_to_centre
from flowtwin.planner.kinematics.rotary_delta import arm_angle
from flowtwin.planner.klipper import plan_klipper
from flowtwin.planner.klipper_config import (
    KlipperSettings,
    klipper_read_options,
    load_printer_cfg,
)

DATA = Path(__file__).resolve().parents[1] / "data" / "kinematics" / "configs"

#: What Klipper 84104bb logs on loading each config: max Z, cone start, max radius, slow
#: radius, very-slow radius (mm, 2 decimals).
KLIPPER_LOG = {
    "kossel_plus.cfg": (295.60, 259.62, 133.68, 120.80, 130.95),
    "mini_delta.cfg": (125.00, 107.27, 57.39, 51.61, 56.17),
    "flsun_q5.cfg": (220.00, 191.20, 100.00, 96.47, 104.58),
    "calibrated.cfg": (296.71, 247.10, 156.70, 140.79, 153.33),
}


def test_every_module_is_a_kinematics():
    modules = {m.name for m in pkgutil.iter_modules(kinematics_pkg.__path__)}
    assert set(names()) == modules - {"base"}
    assert set(names()) >= {"cartesian", "corexy", "corexz", "hybrid_corexy",
                            "hybrid_corexz", "generic_cartesian", "delta", "deltesian",
                            "polar", "rotary_delta", "winch", "none"}


@pytest.mark.parametrize("cfg", sorted(KLIPPER_LOG))
def test_delta_zones_match_klippers_log(cfg):
    kin = load_printer_cfg(DATA / cfg).kinematics_model
    got = (kin.max_z, kin.limit_z, math.sqrt(kin.max_xy2), math.sqrt(kin.slow_xy2),
           math.sqrt(kin.very_slow_xy2))
    assert got == pytest.approx(KLIPPER_LOG[cfg], abs=0.005)


def test_delta_home_is_where_the_arms_meet():
    kin = load_printer_cfg(DATA / "kossel_plus.cfg").kinematics_model
    assert kin.home_position == pytest.approx((0.0, 0.0, 295.6), abs=1e-9)
    cal = load_printer_cfg(DATA / "calibrated.cfg").kinematics_model
    home = np.array(cal.home_position)
    for angle, arm, endstop in zip(cal.angles, cal.arm_lengths, cal.endstops, strict=True):
        a = math.radians(angle)
        carriage = np.array([math.cos(a) * cal.radius, math.sin(a) * cal.radius,
                             endstop + math.sqrt(arm**2 - cal.radius**2)])
        assert np.linalg.norm(carriage - home) == pytest.approx(arm, abs=1e-9)
    assert cal.homed_axes(1) == 7                 # G28 X homes the three towers


def test_trilateration_known_point():
    p = np.array([3.0, -4.0, 10.0])
    centres = [(50.0, 0.0, 200.0), (-20.0, 40.0, 190.0), (-25.0, -45.0, 210.0)]
    r2 = [float(np.sum((np.array(c) - p) ** 2)) for c in centres]
    assert trilaterate(centres, r2) == pytest.approx(tuple(p), abs=1e-9)


def _geom(start, end, speed=100.0):
    start, end = np.atleast_2d(np.asarray(start, float)), np.atleast_2d(np.asarray(end, float))
    length = np.linalg.norm(end - start, axis=1)
    return MoveGeometry(start=start, end=end, kinematic=length >= 1e-9, length=length,
                        speed=np.full(len(length), speed))


def test_delta_slow_zones_cap_speed_and_accel():
    kin = load_printer_cfg(DATA / "kossel_plus.cfg").kinematics_model   # 500 mm/s, 3000
    r_slow, r_vslow = math.sqrt(kin.slow_xy2), math.sqrt(kin.very_slow_xy2)
    starts = [(0.0, 0.0, 5.0), (0.0, 0.0, 5.0), (r_slow + 1, 0.0, 5.0), (0.0, 0.0, 5.0)]
    ends = [(r_slow - 1, 0.0, 5.0), (0.0, r_slow + 1, 5.0), (0.0, 0.0, 5.0),
            (-(r_vslow + 1), 0.0, 5.0)]
    lim = kin.limit_moves(_geom(starts, ends))
    assert lim.refused is None
    assert lim.speed.tolist() == [math.inf, 250.0, 250.0, 125.0]   # start or end counts
    assert lim.accel.tolist() == [math.inf, 1500.0, 1500.0, 750.0]


def test_delta_range_radius_cone_and_z():
    kin = load_printer_cfg(DATA / "kossel_plus.cfg").kinematics_model
    reach = math.sqrt(kin.max_xy2)
    ok = kin.limit_moves(_geom([(0, 0, 5)], [(reach - 0.01, 0, 5)]))
    assert ok.refused is None
    for end in [(reach + 0.01, 0, 5), (0, 0, -0.1), (0, 0, kin.max_z + 0.1),
                (100.0, 0, kin.limit_z + 30)]:               # under the towers' tops
        assert kin.limit_moves(_geom([(0, 0, 5)], [end])).refused is not None, end
    z = kin.limit_z + 30
    cone = kin.radius - math.sqrt(269.0**2 - (269.0 - 30) ** 2)
    assert kin.limit_moves(_geom([(0, 0, 5)], [(cone - 0.01, 0, z)])).refused is None
    assert kin.limit_moves(_geom([(0, 0, 5)], [(cone + 0.01, 0, z)])).refused is not None


def test_delta_way_back_from_home_is_allowed():
    cal = load_printer_cfg(DATA / "calibrated.cfg").kinematics_model
    hx, hy, hz = cal.home_position
    assert hz > cal.max_z                          # the towers disagree: home is above max_z
    lim = cal.limit_moves(_geom([(hx, hy, hz)], [(hx, hy, (hz + cal.max_z) / 2)]))
    assert lim.refused is None
    lim = cal.limit_moves(_geom([(hx, hy, hz)], [(hx + 1, hy, (hz + cal.max_z) / 2)]))
    assert lim.refused is not None


def test_delta_refusal_names_the_line(tmp_path):
    settings = load_printer_cfg(DATA / "mini_delta.cfg")
    gcode = tmp_path / "far.gcode"
    gcode.write_text("G28\nG1 Z5 F3000\nG1 X20 Y0\nG1 X70 Y0\n")
    table = read_gcode(gcode, options=klipper_read_options(settings))
    with pytest.raises(GcodeError, match="delta's reach") as info:
        plan_klipper(table, settings)
    assert info.value.line == 4


def test_g28_naming_an_axis_on_a_delta_is_flagged(tmp_path):
    settings = load_printer_cfg(DATA / "mini_delta.cfg")
    gcode = tmp_path / "g28x.gcode"
    gcode.write_text("G28\nG1 Z5 F3000\nG28 X\nG1 Z10\n")
    timeline = plan_klipper(read_gcode(gcode, options=klipper_read_options(settings)),
                            settings)
    assert any("G28 naming some axes" in w for w in timeline.warnings)


def test_polar_distance_to_centre():
    start = np.array([[10.0, -5.0], [10.0, 5.0], [3.0, 4.0], [-5.0, 0.0]])
    end = np.array([[10.0, 5.0], [10.0, 15.0], [6.0, 8.0], [5.0, 0.0]])
    assert distance_to_centre(start, end) == pytest.approx([10.0, math.hypot(10, 5), 5.0,
                                                            0.0])


def test_polar_reach_homing_and_angular_cap():
    kin = load_printer_cfg(DATA / "polar.cfg").kinematics_model      # arm 300, 5 rad/s
    assert kin.home_position == (300.0, 0.0, 0.5)
    assert kin.homed_axes(1) == 3 and kin.homed_axes(4) == 4
    assert kin.limit_moves(_geom([(0, 10, 1)], [(301, 0, 1)])).refused is not None
    # a chord 20 mm from the centre at 300 mm/s: 15 rad/s > 5 -> scaled to a third
    lim = kin.limit_moves(_geom([(-50, 20, 1)], [(50, 20, 1)], speed=300.0))
    assert lim.speed[0] == pytest.approx(300.0 * 5.0 / 15.0)
    assert lim.accel[0] == pytest.approx(3000.0 * 5.0 / 15.0)


def test_deltesian_limits_and_home():
    kin = load_printer_cfg(DATA / "deltesian.cfg").kinematics_model
    assert kin.limits[0] == (-56.0, 56.0) and kin.limits[1] == (0.0, 200.0)
    assert kin.home_position == pytest.approx((0.0, 0.0, 268.0))
    assert kin.homed_axes(1) == 5 and kin.homed_axes(2) == 2 and kin.homed_axes(0) == 7
    assert kin.limit_moves(_geom([(0, 100, 5)], [(-57, 100, 5)])).refused is not None
    assert kin.limit_moves(_geom([(0, 100, 5)], [(40, 100, 5)])).refused is None


def test_rotary_delta_home_and_arm_geometry():
    kin = load_printer_cfg(DATA / "rotary_delta.cfg").kinematics_model
    assert kin.home_position == pytest.approx((0.0, 0.0, 252.0), abs=1e-9)
    p = (12.0, -30.0, 100.0)
    for a in (30.0, 150.0, 270.0):
        theta = arm_angle(p, shoulder_radius=33.9, shoulder_height=412.9, angle_deg=a,
                          upper_arm=170.0, lower_arm=320.0)
        radial = 33.9 + 170.0 * math.cos(theta)
        elbow = np.array([radial * math.cos(math.radians(a)),
                          radial * math.sin(math.radians(a)),
                          412.9 + 170.0 * math.sin(theta)])
        assert np.linalg.norm(elbow - np.array(p)) == pytest.approx(320.0, abs=1e-9)
    lim = kin.limit_moves(_geom([(0, 0, 10)], [(0, 0, 20)]))
    assert lim.speed[0] == 50.0 and lim.accel is None     # max_z_velocity, flat


def test_winch_and_none_limit_nothing(tmp_path):
    for cfg in ("winch.cfg",):
        settings = load_printer_cfg(DATA / cfg)
        gcode = tmp_path / "far.gcode"
        gcode.write_text("G28\nG1 X1500 Y-1500 Z400 F30000\n")
        timeline = plan_klipper(read_gcode(gcode, options=klipper_read_options(settings)),
                                settings)
        d = math.sqrt(1500**2 * 2 + 400**2)
        assert timeline.total_time_s == pytest.approx(d / 300 + 300 / 3000, rel=1e-9)


def test_generic_cartesian_box_from_the_carriages():
    s = load_printer_cfg(DATA / "generic_cartesian.cfg")
    assert s.position_min == (0.0, 0.0, 0.0) and s.position_max == (300.0, 200.0, 100.0)
    assert s.position_endstop == (0.0, 0.0, 0.5)


def test_box_kinematics_from_settings_alone():
    s = KlipperSettings(max_velocity=300.0, max_accel=3000.0, kinematics="hybrid_corexy",
                        position_min=(0, 0, 0), position_max=(200, 200, 200))
    assert s.kinematics_model.name == "hybrid_corexy"
    assert s.kinematics_model.box_max == (200, 200, 200)
    with pytest.raises(ProfileError, match="needs its geometry"):
        KlipperSettings(max_velocity=300.0, max_accel=3000.0, kinematics="delta")
    kin = load_printer_cfg(DATA / "mini_delta.cfg").kinematics_model
    with pytest.raises(ProfileError, match="disagree"):
        KlipperSettings(max_velocity=300.0, max_accel=3000.0, kinematics="cartesian",
                        kin=kin)
    s = KlipperSettings(max_velocity=150.0, max_accel=1200.0, kinematics="delta", kin=kin)
    assert s.position_endstop == kin.home_position
    assert replace(s, square_corner_velocity=8.0).kin is kin


DELTA_BASE = (DATA / "mini_delta.cfg").read_text()


@pytest.mark.parametrize(("old", "new", "field", "match"), [
    ("arm_length: 120.8", "arm_length: 60", "[stepper_a] arm_length", "out of range"),
    ("delta_radius: 63.00\n", "", "[printer] delta_radius", "required"),
    ("minimum_z_position: -10.0", "minimum_z_position: 200", "[printer] minimum_z_position",
     "out of range"),
    ("rotation_distance: 56.0", "rotation_distance: -56", "[stepper_a] rotation_distance",
     "out of range"),
    ("microsteps: 16", "microsteps: 16.5", "[stepper_a] microsteps", "parse"),
    ("homing_speed: 50\nposition_endstop: 125.0",
     "homing_speed: 50\nfull_steps_per_rotation: 202\nposition_endstop: 125.0",
     "[stepper_a] full_steps_per_rotation", "invalid"),
    ("kinematics: delta", "kinematics: deltaa", "[printer] kinematics", "not supported"),
    ("rotation_distance: 56.0", "rotation_distance: 56.0\ngear_ratio: 3:x",
     "[stepper_a] gear_ratio", "parse"),
])
def test_delta_config_errors_name_the_line(tmp_path, old, new, field, match):
    assert old in DELTA_BASE
    text = DELTA_BASE.replace(old, new, 1)
    path = tmp_path / "printer.cfg"
    path.write_text(text)
    with pytest.raises(ProfileError, match=match) as info:
        load_printer_cfg(path)
    assert info.value.field == field
    if new and info.value.line is not None:
        bad = new.split("\n")[-1] if "full_steps" not in new else "full_steps_per_rotation"
        assert bad.split(":")[0] in text.split("\n")[info.value.line - 1]


def test_step_distance_with_gear_ratio(tmp_path):
    from flowtwin.planner.kinematics.base import step_distance
    from flowtwin.planner.klipper_cfg import read_cfg

    path = tmp_path / "s.cfg"
    path.write_text("[stepper_a]\nrotation_distance: 40\nmicrosteps: 16\n"
                    "gear_ratio: 80:16, 3:1\n")
    sec = read_cfg(path).section("stepper_a")
    assert step_distance(sec) == pytest.approx(40.0 / (200 * 16 * 5 * 3))
    assert step_distance(sec, radians=True) == pytest.approx(2 * math.pi / (200 * 16 * 15))


def test_a_limit_whose_square_underflows_is_refused(tmp_path):
    """``max_z_velocity: 1e-308`` is a valid number whose square is 0: Klipper would divide
    by zero; flowtwin names the first move it cannot run."""
    path = tmp_path / "printer.cfg"
    path.write_text((DATA / "cartesian.cfg").read_text().replace("max_z_velocity: 25",
                                                                 "max_z_velocity: 1e-308"))
    settings = load_printer_cfg(path)
    gcode = tmp_path / "z.gcode"
    gcode.write_text("G28\nG1 X10 F3000\nG1 Z5\n")
    with pytest.raises(GcodeError, match="too small") as info:
        plan_klipper(read_gcode(gcode, options=klipper_read_options(settings)), settings)
    assert info.value.line == 3
