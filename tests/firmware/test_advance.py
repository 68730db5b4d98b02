"""Advance and acceleration commands per firmware, read back by flowtwin's reader."""

from __future__ import annotations

import pytest

from flowtwin.calibration.firmware import (
    Firmware,
    accel_command,
    format_number,
    pa_command,
    parse_firmware,
)
from flowtwin.errors import CalibrationError
from flowtwin.gcode.reader import read_gcode


@pytest.mark.parametrize(("fw", "text", "code", "params"), [
    # Klipper docs: SET_PRESSURE_ADVANCE [ADVANCE=<K>] [SMOOTH_TIME=<t>]
    (Firmware.KLIPPER, "SET_PRESSURE_ADVANCE ADVANCE=0.045 SMOOTH_TIME=0.03",
     "SET_PRESSURE_ADVANCE", {"ADVANCE": 0.045, "SMOOTH_TIME": 0.03}),
    # Marlin LIN_ADVANCE: M900 K<K>
    (Firmware.MARLIN, "M900 K0.045", "M900", {"K": 0.045}),
    # RepRapFirmware: M572 D<extruder> S<K>
    (Firmware.REPRAPFIRMWARE, "M572 D0 S0.045", "M572", {"D": 0.0, "S": 0.045}),
    # Prusa Buddy: M572 S<K> W<smooth time> (no D: "Extruder number is not yet supported")
    (Firmware.PRUSA, "M572 S0.045 W0.03", "M572", {"S": 0.045, "W": 0.03}),
])
def test_pa_command_syntax_and_reader(fw: Firmware, text: str, code: str,
                                      params: dict[str, float]) -> None:
    smooth = 0.03 if fw.smooths_advance else None
    line = pa_command(fw, 0.045, smooth_time_s=smooth)
    assert line == text
    table = read_gcode((line + "\n").encode())
    assert table.unknown_commands == {}
    (event,) = table.events
    assert event.code == code
    assert event.params == params


def test_pa_command_without_smoothing_leaves_it_unchanged() -> None:
    assert pa_command(Firmware.KLIPPER, 0.0) == "SET_PRESSURE_ADVANCE ADVANCE=0"
    assert pa_command(Firmware.PRUSA, 0.1) == "M572 S0.1"


@pytest.mark.parametrize("fw", [Firmware.MARLIN, Firmware.REPRAPFIRMWARE])
def test_smoothing_window_rejected_where_firmware_has_none(fw: Firmware) -> None:
    with pytest.raises(CalibrationError, match=r"pa_smooth_time_s.*no advance smoothing"):
        pa_command(fw, 0.05, smooth_time_s=0.04)


@pytest.mark.parametrize("k", [-0.01, 10.5, float("nan")])
def test_advance_factor_out_of_range(k: float) -> None:
    with pytest.raises(CalibrationError, match=r"\[k_s\].*out of range"):
        pa_command(Firmware.MARLIN, k)


def test_accel_command_klipper_uses_set_velocity_limit() -> None:
    # Klipper ignores M204 with only P or only T (NOTES.md): use SET_VELOCITY_LIMIT
    line = accel_command(Firmware.KLIPPER, 2500.0)
    assert line == "SET_VELOCITY_LIMIT ACCEL=2500"
    (event,) = read_gcode((line + "\n").encode()).events
    assert event.params == {"ACCEL": 2500.0}


@pytest.mark.parametrize("fw", [Firmware.MARLIN, Firmware.REPRAPFIRMWARE, Firmware.PRUSA])
def test_accel_command_marlin_family(fw: Firmware) -> None:
    line = accel_command(fw, 1500.5)
    (event,) = read_gcode((line + "\n").encode()).events
    assert event.code == "M204" and event.params == {"P": 1500.5, "T": 1500.5}


def test_parse_firmware() -> None:
    assert parse_firmware("RRF") is Firmware.REPRAPFIRMWARE
    assert parse_firmware(" Klipper ") is Firmware.KLIPPER
    with pytest.raises(CalibrationError, match="allowed: klipper, marlin, reprapfirmware, "
                                               "prusa"):
        parse_firmware("repetier")


def test_format_number() -> None:
    assert format_number(0.0) == "0"
    assert format_number(-0.0000001) == "0"
    assert format_number(0.05) == "0.05"
    assert format_number(1.234567) == "1.23457"
