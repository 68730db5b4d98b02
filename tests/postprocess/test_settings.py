"""Where the printer of a post-processing run comes from: the slicer's environment, the
configuration embedded in the G-code, a printer.cfg, the profile."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from flowtwin.errors import DataError, ProfileError
from flowtwin.firmware import Firmware
from flowtwin.postprocess import PostprocessOptions, SlicerContext
from flowtwin.postprocess.printer import firmware_of_flavor, resolve_printer

pytestmark = [pytest.mark.corpus]

CLI = [sys.executable, "-c", "from flowtwin.cli.main import main; main()"]

#: What Debian's PrusaSlicer 2.5 sets for a Marlin 2 printer (measured on Debian bookworm,
#: docs/postprocess.md), trimmed.
PRUSA_ENV = {
    "SLIC3R_PP_HOST": "File", "SLIC3R_PP_OUTPUT_NAME": "/tmp/out.gcode",
    "SLIC3R_GCODE_FLAVOR": "marlin2", "SLIC3R_PRINTER_MODEL": "MK3S",
    "SLIC3R_MACHINE_MAX_ACCELERATION_X": "9000,1000",
    "SLIC3R_MACHINE_MAX_ACCELERATION_Y": "9000,1000",
    "SLIC3R_MACHINE_MAX_ACCELERATION_Z": "500,200",
    "SLIC3R_MACHINE_MAX_ACCELERATION_E": "10000,5000",
    "SLIC3R_MACHINE_MAX_ACCELERATION_EXTRUDING": "1500,1250",
    "SLIC3R_MACHINE_MAX_ACCELERATION_RETRACTING": "1500,1250",
    "SLIC3R_MACHINE_MAX_ACCELERATION_TRAVEL": "1500,1250",
    "SLIC3R_MACHINE_MAX_FEEDRATE_X": "500,200", "SLIC3R_MACHINE_MAX_FEEDRATE_Y": "500,200",
    "SLIC3R_MACHINE_MAX_FEEDRATE_Z": "12,12", "SLIC3R_MACHINE_MAX_FEEDRATE_E": "120,120",
    "SLIC3R_MACHINE_MAX_JERK_X": "10,10", "SLIC3R_MACHINE_MAX_JERK_Y": "10,10",
    "SLIC3R_MACHINE_MAX_JERK_Z": "0.2,0.2", "SLIC3R_MACHINE_MAX_JERK_E": "2.5,2.5",
    "SLIC3R_NOZZLE_DIAMETER": "0.4", "SLIC3R_FILAMENT_DIAMETER": "1.75",
    "SLIC3R_TEMPERATURE": "205", "PATH": "/usr/bin",
}


def test_the_environment_is_read_as_the_slicers_options() -> None:
    ctx = SlicerContext.from_environment(PRUSA_ENV)
    assert ctx.in_slicer and ctx.host == "File" and ctx.output_name == "/tmp/out.gcode"
    assert ctx.environment["machine_max_feedrate_x"] == "500,200"
    assert "pp_host" not in ctx.environment and "path" not in ctx.environment
    s = ctx.settings({"gcode_flavor": "klipper"})
    assert s is not None and s.source == "environment" and s.flavor == "marlin2"
    assert (s.nozzle_diameter_mm, s.filament_diameter_mm, s.temperature_c) == (0.4, 1.75, 205)
    assert s.mode(1)["machine_max_feedrate_x"] == "200" and s.has_silent_mode()
    assert not SlicerContext.from_environment({"HOME": "/root"}).in_slicer


def test_without_printer_options_in_the_environment_the_embedded_block_counts() -> None:
    ctx = SlicerContext.from_environment({"SLIC3R_PP_HOST": "File"})
    s = ctx.settings({"gcode_flavor": "klipper", "nozzle_temperature": "220,220",
                      "enable_pressure_advance": "1", "pressure_advance": "0.035"})
    assert s is not None and s.source == "embedded" and s.flavor == "klipper"
    assert s.temperature_c == 220 and s.pressure_advance_s == 0.035
    assert ctx.settings({"layer_height": "0.2"}) is None and ctx.settings(None) is None


def test_the_final_output_name_decides_where_the_sidecar_goes(tmp_path: Path) -> None:
    pp = tmp_path / "tmp" / ".123.gcode.pp"
    out = tmp_path / "part.gcode"
    assert SlicerContext(host="File", output_name=str(out)).final_path(pp) == out
    assert SlicerContext(host="OctoPrint", output_name="part.gcode").final_path(pp) == pp
    assert SlicerContext(host="File", output_name="part.gcode").final_path(pp) == pp
    gone = tmp_path / "no-such-folder" / "part.gcode"
    assert SlicerContext(host="File", output_name=str(gone)).final_path(pp) == pp
    assert SlicerContext().final_path(pp) == pp


@pytest.mark.parametrize(("flavor", "model", "firmware", "noted"), [
    ("klipper", None, Firmware.KLIPPER, False),
    ("marlin2", "MK3S", Firmware.MARLIN, False),
    ("marlin2", "MK4S", Firmware.PRUSA, False),
    ("marlin2", "COREONE", Firmware.PRUSA, False),
    ("reprapfirmware", None, Firmware.REPRAPFIRMWARE, False),
    ("repetier", None, Firmware.REPETIER, False),
    ("smoothie", None, Firmware.MARLIN, True),
    (None, None, None, False),
])
def test_gcode_flavors(flavor: str | None, model: str | None, firmware: Firmware | None,
                       noted: bool) -> None:
    fw, note = firmware_of_flavor(flavor, model)
    assert fw is firmware and (note is not None) == noted


def test_slicer_limits_replace_the_profiles_and_give_a_silent_mode() -> None:
    s = SlicerContext.from_environment(PRUSA_ENV).settings(None)
    c = resolve_printer(setup="tronvoll2019", settings=s)
    assert c.source == "slicer settings (environment)" and c.firmware is Firmware.MARLIN
    m = c.machine.printer.marlin
    assert m is not None and m.max_feedrate_mm_s.x == 500 and m.max_acceleration_mm_s2.x == 9000
    assert m.print_accel_mm_s2 == 1500 and m.jerk_mm_s is not None and m.jerk_mm_s.e == 2.5
    assert c.machine.temperature_c == 205
    # the set-up's measured 1.752 mm filament stays; the firmware's nominal is the slicer's
    assert c.machine.filament.diameter_mm == 1.752
    assert c.machine.printer.extruder.filament_diameter_mm == 1.75
    assert c.silent is not None and c.silent.marlin is not None
    assert c.silent.marlin.max_feedrate_mm_s.x == 200
    assert c.silent.marlin.max_acceleration_mm_s2.x == 1000


def test_a_klipper_flavor_without_printer_cfg_takes_the_slicers_xy_limits() -> None:
    env = {"SLIC3R_GCODE_FLAVOR": "klipper", "SLIC3R_MACHINE_MAX_SPEED_X": "800",
           "SLIC3R_MACHINE_MAX_SPEED_Y": "600", "SLIC3R_MACHINE_MAX_ACCELERATION_X": "20000",
           "SLIC3R_MACHINE_MAX_ACCELERATION_Y": "12000"}
    c = resolve_printer(setup=None, settings=SlicerContext.from_environment(env).settings(None))
    lim = c.machine.printer.limits
    assert c.firmware is Firmware.KLIPPER and lim is not None
    assert (lim.max_velocity_mm_s, lim.max_accel_mm_s2) == (600, 12000)
    assert any("--klipper-config" in n for n in c.notes)


def test_another_nozzle_and_an_impossible_filament(tmp_path: Path) -> None:
    env = {**PRUSA_ENV, "SLIC3R_NOZZLE_DIAMETER": "0.6"}
    c = resolve_printer(setup=None, settings=SlicerContext.from_environment(env).settings(None))
    assert c.machine.hotend.nozzle_diameter_mm == 0.6
    assert c.machine.printer.extruder.nozzle_diameter_mm == 0.6
    assert any("0.6 mm nozzle" in n for n in c.notes)
    env = {**PRUSA_ENV, "SLIC3R_FILAMENT_DIAMETER": "2.85"}
    with pytest.raises(ProfileError, match="does not fit"):
        resolve_printer(setup=None, settings=SlicerContext.from_environment(env).settings(None))


def test_a_printer_cfg_decides_the_motion(klipper_dir: Path) -> None:
    s = SlicerContext.from_environment(PRUSA_ENV).settings(None)
    c = resolve_printer(setup=None, klipper_config=klipper_dir / "B.cfg", settings=s)
    assert c.firmware is Firmware.KLIPPER and c.klipper_config == klipper_dir / "B.cfg"
    assert c.source == "klipper-config" and c.silent is None


def test_bad_options_are_clear_errors(tmp_path: Path, pph: Any) -> None:
    with pytest.raises(DataError, match="fail-on"):
        PostprocessOptions(fail_on=frozenset({"warping"}))
    with pytest.raises(DataError, match="give the printer once"):
        PostprocessOptions(klipper_config="a.cfg", moonraker="http://printer")
    gcode = pph.corpus_copy("kisslicer_1.1.0.5_thinbox_small", tmp_path / "k.gcode")
    before = gcode.read_bytes()
    for args, words in ((["--fail-on", "warping"], "warping"),
                        (["--moonraker", "printer:7125"], "not an HTTP URL"),
                        (["--klipper-config", str(tmp_path / "none.cfg")], "none.cfg")):
        proc = subprocess.run([*CLI, "postprocess", *args, str(gcode)], capture_output=True,
                              text=True, timeout=600, check=False)
        assert proc.returncode == 2 and words in proc.stderr, proc.stderr
        assert "Traceback" not in proc.stderr
    proc = subprocess.run([*CLI, "postprocess", str(tmp_path / "missing.gcode")],
                          capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 2 and "missing.gcode" in proc.stderr
    assert gcode.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k.gcode"]
