"""Firmware settings from the twin: the best single K and OrcaSlicer's adaptive table."""

from __future__ import annotations

from pathlib import Path

import pytest

from flowtwin.calibration.tuning.adaptive_pa import parse_orca_model
from flowtwin.calibration.tuning.advance_settings import (
    adaptive_pa_table,
    best_pressure_advance,
    pa_test_gcode,
)
from flowtwin.errors import CalibrationError
from flowtwin.firmware import Firmware
from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.gcode.reader import read_gcode
from flowtwin.profiles.machine import load_machine


@pytest.fixture(scope="module")
def example(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The built-in example print (2 layers: small and fast), relative E."""
    path = tmp_path_factory.mktemp("example") / "example.gcode"
    write_print(path, PrintSpec(layers=2))
    return path


def test_best_k_beats_no_advance_and_the_lag_factor(example: Path) -> None:
    fit = best_pressure_advance(example)
    scanned = dict(fit.curve)
    assert fit.rms_at_best <= min(scanned.values()) + 1e-12
    assert fit.rms_at_best < fit.rms_without / 2
    assert fit.rms_at_best <= fit.rms_at_lag + 1e-12
    # the optimum sits near the twin's lag factor (same order), not at an end of the scan
    assert 0.3 * fit.lag_k_s < fit.k_s < 3.0 * fit.lag_k_s
    assert fit.command == f"M900 K{fit.k_s:g}"  # the MK2.5 runs Marlin's linear advance
    assert "lag factor" in fit.explanation and fit.command in fit.explanation


def test_klipper_command(tmp_path: Path, example: Path) -> None:
    cfg = tmp_path / "printer.cfg"
    steppers = "".join(f"[stepper_{a}]\nposition_endstop: 0\nposition_max: 250\n"
                       for a in "xyz")
    cfg.write_text("[printer]\nkinematics: cartesian\nmax_velocity: 300\nmax_accel: 3000\n"
                   + steppers + "[extruder]\nnozzle_diameter: 0.4\nfilament_diameter: 1.75\n"
                   "[gcode_arcs]\nresolution: 1.0\n")
    fit = best_pressure_advance(example, klipper_config=cfg, grid=7)
    assert fit.firmware == "klipper"
    assert fit.command.startswith("SET_PRESSURE_ADVANCE ADVANCE=")
    assert fit.rms_at_best < fit.rms_without


def test_adaptive_table_in_orca_format() -> None:
    table, fits = adaptive_pa_table(flows_mm3_s=[3.0, 9.0], accels_mm_s2=[1000, 4000])
    assert len(table) == 4 and len(fits) == 4
    text = table.to_orca_text()
    back = parse_orca_model(text)
    assert back.k_s.tolist() == pytest.approx(table.k_s.tolist(), abs=5e-5)
    assert sorted(set(back.accel_mm_s2.tolist())) == [1000.0, 4000.0]
    assert all(f.rms_at_best <= f.rms_without for f in fits)
    with pytest.raises(CalibrationError, match="two positive flows"):
        adaptive_pa_table(flows_mm3_s=[3.0], accels_mm_s2=[1000])


def test_test_print_runs_at_the_asked_flow() -> None:
    m = load_machine("tronvoll2019")
    text = pa_test_gcode(m, flow_mm3_s=6.0, accel_mm_s2=2000, firmware=Firmware.MARLIN)
    assert "M204 P2000 T2000" in text
    mv = read_gcode(text.encode()).moves
    printing = mv[mv["de"] > 0.01]
    fast = printing[printing["feed_mm_s"] == printing["feed_mm_s"].max()]
    area_fil = m.filament.area_mm2
    length = 60.0
    flow = float(fast["de"][0]) * area_fil / length * float(fast["feed_mm_s"][0])
    assert flow == pytest.approx(6.0, rel=1e-4)
