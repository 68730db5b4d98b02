"""printer.cfg reader: Klipper's defaults, derived limits, bounds and file syntax."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from flowtwin.errors import ProfileError
from flowtwin.planner.klipper_config import (
    KlipperExtruder,
    KlipperSettings,
    klipper_read_options,
    load_printer_cfg,
)

BASE = """\
[mcu]
serial: /dev/null

[printer]
kinematics: cartesian
max_velocity: 300
max_accel: 3000   # inline comment
square_corner_velocity: 5
minimum_cruise_ratio: 0.5

[stepper_x]
step_pin: PF0
position_endstop: 0
position_min: -120
position_max: 400

[stepper_y]
position_endstop = 0
position_min = -120
position_max = 400

[stepper_z]
endstop_pin: ^PD3
position_endstop: 0
position_min: -5
position_max: 300

[extruder]
nozzle_diameter: 0.400
filament_diameter: 1.750
max_extrude_only_distance: 200

[gcode_macro T0]
gcode:
  ACTIVATE_EXTRUDER EXTRUDER=extruder
  ; a comment inside the macro

  M117 max_velocity: 1
"""


def write(tmp_path: Path, text: str, name: str = "printer.cfg") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_basic_file(tmp_path):
    s = load_printer_cfg(write(tmp_path, BASE))
    assert (s.max_velocity, s.max_accel, s.square_corner_velocity) == (300, 3000, 5)
    assert s.minimum_cruise_ratio == 0.5
    assert (s.max_z_velocity, s.max_z_accel) == (300, 3000)        # default: [printer]
    assert s.position_endstop == (0, 0, 0)
    assert s.position_min == (-120, -120, -5) and s.position_max == (400, 400, 300)
    assert s.extruder_names == ("extruder",) and s.extruder_count == 1
    assert s.max_extrude_only_distance == 200
    assert s.instantaneous_corner_velocity == 1.0
    assert s.firmware_retraction is None and s.arc_resolution is None
    assert s.kin_flush_delay == pytest.approx(0.001)
    # Klipper: default cross-section 4·nozzle², extrude-only limits scaled by its ratio
    ratio = 4 * 0.16 / (math.pi * 1.75 ** 2 / 4)
    assert s.max_extrude_only_velocity == pytest.approx(300 * ratio)
    assert s.max_extrude_only_accel == pytest.approx(3000 * ratio)
    assert s.extruders[0].max_extrude_ratio == pytest.approx(ratio)


@pytest.mark.corpus
@pytest.mark.parametrize(("cfg", "vel", "acc", "kfd", "zv", "za"), [
    ("A.cfg", 79.82, 798.2, 0.001, 300, 3000),
    ("B.cfg", 133.04, 2660.8, 0.020, 500, 10000),
    ("C.cfg", 53.21, 399.1, 0.001, 10, 100),
])
def test_reference_configs(klipper_dir, cfg, vel, acc, kfd, zv, za):
    """The README of the Klipper oracle tabulates the derived limits (truncated)."""
    s = load_printer_cfg(klipper_dir / cfg)
    assert s.max_extrude_only_velocity == pytest.approx(vel, abs=0.01)
    assert s.max_extrude_only_accel == pytest.approx(acc, abs=0.1)
    assert s.kin_flush_delay == pytest.approx(kfd)
    assert (s.max_z_velocity, s.max_z_accel) == (zv, za)
    assert s.arc_resolution == 1.0


@pytest.mark.corpus
def test_reference_variant_with_four_extruders(klipper_dir):
    s = load_printer_cfg(klipper_dir / "bambustudio_1.08_eline_multitool__B.cfg")
    assert s.extruder_names == ("extruder", "extruder1", "extruder2", "extruder3")
    assert s.kin_flush_delay == pytest.approx(0.020)


def test_extruders_must_be_contiguous(tmp_path):
    text = BASE + "\n[extruder2]\nnozzle_diameter: 0.6\nfilament_diameter: 1.75\n"
    assert load_printer_cfg(write(tmp_path, text)).extruder_count == 1
    text += "\n[extruder1]\nnozzle_diameter: 0.4\nfilament_diameter: 1.75\n"
    assert load_printer_cfg(write(tmp_path, text)).extruder_names == (
        "extruder", "extruder1", "extruder2")


def test_save_config_block_overrides(tmp_path):
    text = BASE + ("\n#*# <---------------------- SAVE_CONFIG ---------------------->\n"
                   "#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.\n"
                   "#*#\n#*# [printer]\n#*# max_accel = 4500\n#*#\n"
                   "#*# [extruder]\n#*# pressure_advance = 0.05\n")
    s = load_printer_cfg(write(tmp_path, text))
    assert s.max_accel == 4500
    assert s.pressure_advance == 0.05 and s.kin_flush_delay == pytest.approx(0.020)


def test_include_relative_and_glob(tmp_path):
    (tmp_path / "conf").mkdir()
    write(tmp_path, "[printer]\nmax_accel: 7000\n", "conf/a_limits.cfg")
    write(tmp_path, "[extruder]\ninstantaneous_corner_velocity: 2.5\n", "conf/b_ext.cfg")
    main = write(tmp_path, BASE + "\n[include conf/*.cfg]\n")
    s = load_printer_cfg(main)
    assert s.max_accel == 7000 and s.instantaneous_corner_velocity == 2.5
    missing = write(tmp_path, "[include nothere.cfg]\n" + BASE, "m.cfg")
    with pytest.raises(ProfileError, match="does not exist") as info:
        load_printer_cfg(missing)
    assert info.value.line == 1
    loop = write(tmp_path, "[include loop.cfg]\n", "loop.cfg")
    with pytest.raises(ProfileError, match="nested too deeply"):
        load_printer_cfg(loop)


def test_optional_sections(tmp_path):
    text = BASE + ("\n[firmware_retraction]\nretract_length: 0.8\nretract_speed: 35.5\n"
                   "unretract_extra_length: 0.1\nunretract_speed: 20\n"
                   "\n[gcode_arcs]\nresolution: 0.5\n"
                   "\n[extruder_stepper belt]\npressure_advance: 0.1\n"
                   "pressure_advance_smooth_time: 0.06\n"
                   "\n[some_unknown_section]\nwhatever: is ignored\n")
    s = load_printer_cfg(write(tmp_path, text))
    fr = s.firmware_retraction
    assert fr is not None and fr.length_mm == 0.8
    # Klipper sends "G1 E-%.5f F%d": 35.5 mm/s = F2130 exactly, 20 mm/s = F1200
    assert fr.speed_mm_s == pytest.approx(35.5) and fr.unretract_speed_mm_s == 20
    assert fr.extra_unretract_mm == pytest.approx(0.1)
    assert s.arc_resolution == 0.5
    assert s.kin_flush_delay == pytest.approx(0.03)
    opts = klipper_read_options(s, strict=True)
    assert opts.arc_segment_mm == 0.5 and opts.firmware_retraction == fr and opts.strict


def test_max_accel_to_decel_sets_the_cruise_ratio(tmp_path):
    text = BASE.replace("minimum_cruise_ratio: 0.5", "max_accel_to_decel: 1000")
    assert load_printer_cfg(write(tmp_path, text)).minimum_cruise_ratio == pytest.approx(
        1 - 1000 / 3000)
    text = BASE.replace("minimum_cruise_ratio: 0.5\n", "")
    assert load_printer_cfg(write(tmp_path, text)).minimum_cruise_ratio == 0.5


def test_probe_endstop_needs_no_position(tmp_path):
    text = BASE.replace("endstop_pin: ^PD3\nposition_endstop: 0\n",
                        "endstop_pin: probe:z_virtual_endstop\n")
    assert load_printer_cfg(write(tmp_path, text)).position_endstop[2] == 0.0


@pytest.mark.parametrize(("old", "new", "bad", "field", "match"), [
    ("max_velocity: 300", "max_velocity: -300", "-300", "[printer] max_velocity",
     "out of range"),
    ("max_velocity: 300", "max_velocity: fast", "fast", "[printer] max_velocity", "parse"),
    ("minimum_cruise_ratio: 0.5", "minimum_cruise_ratio: 1", "ratio: 1",
     "[printer] minimum_cruise_ratio", "out of range"),
    ("square_corner_velocity: 5", "square_corner_velocity: 5\nmax_z_velocity: 400",
     "max_z_velocity", "[printer] max_z_velocity", "out of range"),
    ("position_endstop: 0\nposition_min: -120", "position_endstop: 500\nposition_min: -120",
     "position_endstop: 500", "[stepper_x] position_endstop", "between"),
    ("filament_diameter: 1.750", "filament_diameter: 0.3", "filament_diameter",
     "[extruder] filament_diameter", "out of range"),
    ("kinematics: cartesian", "kinematics: scara", "scara", "[printer] kinematics",
     "kinematics"),
    ("max_accel: 3000   # inline comment", "max_accel 3000", "max_accel 3000", None,
     "cannot parse"),
])
def test_bad_values_name_line_option_and_range(tmp_path, old, new, bad, field, match):
    text = BASE.replace(old, new, 1)
    line = next(i for i, t in enumerate(text.split("\n"), start=1) if bad in t)
    path = write(tmp_path, text)
    with pytest.raises(ProfileError, match=match) as info:
        load_printer_cfg(path)
    err = info.value
    assert err.source == str(path) and err.line == line
    if field is not None:
        assert err.field == field
    assert f"printer.cfg:{line}" in str(err)


def test_missing_parts(tmp_path):
    with pytest.raises(ProfileError, match=r"no \[printer\]"):
        load_printer_cfg(write(tmp_path, "[extruder]\nnozzle_diameter: 0.4\n"))
    with pytest.raises(ProfileError, match=r"max_accel.*required"):
        load_printer_cfg(write(tmp_path, BASE.replace("max_accel: 3000   # inline comment\n",
                                                      "")))
    with pytest.raises(ProfileError, match=r"no \[stepper_z\]"):
        load_printer_cfg(write(tmp_path, BASE.split("[stepper_z]")[0]))
    with pytest.raises(ProfileError, match="cannot read"):
        load_printer_cfg(tmp_path / "absent.cfg")
    with pytest.raises(ProfileError, match="outside an option"):
        load_printer_cfg(write(tmp_path, "  indented: first\n" + BASE))


def test_settings_validate_when_built_directly():
    with pytest.raises(ProfileError, match="max_accel"):
        KlipperSettings(max_velocity=100.0, max_accel=0.0)
    with pytest.raises(ProfileError, match="pressure_advance_smooth_time"):
        KlipperSettings(max_velocity=100.0, max_accel=1000.0,
                        extruders=(KlipperExtruder(pressure_advance_smooth_time=0.5),))
    s = KlipperSettings(max_velocity=100.0, max_accel=1000.0, max_z_accel=50.0)
    assert (s.max_z_velocity, s.max_z_accel) == (100.0, 50.0)
    assert s.junction_deviation == pytest.approx(25 * (math.sqrt(2) - 1) / 1000)
    with pytest.raises(ProfileError, match="no \\[extruder\\]"):
        _ = KlipperSettings(max_velocity=100.0, max_accel=1000.0, extruders=()).nozzle_diameter
