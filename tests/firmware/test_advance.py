"""Advance and acceleration commands per firmware, written and read back by the reader."""

from __future__ import annotations

import pytest

from flowtwin.errors import GcodeError, ProfileError
from flowtwin.firmware import (
    AdvanceAlgorithm,
    Firmware,
    PaChange,
    PlannerFamily,
    accel_command,
    pa_command,
    read_pa_command,
)
from flowtwin.gcode.emitter import format_number
from flowtwin.gcode.moves import Event
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
    # Repetier is given Marlin's command (flowtwin has no model of Repetier's own advance)
    (Firmware.REPETIER, "M900 K0.045", "M900", {"K": 0.045}),
])
def test_pa_command_syntax_and_reader(fw: Firmware, text: str, code: str,
                                      params: dict[str, float]) -> None:
    smooth = 0.03 if fw.smooths_advance else None
    line = pa_command(fw, 0.045, smooth_time_s=smooth)
    assert line == text
    table = read_gcode((line + "\n").encode())
    assert table.unknown_commands == {}
    (event,) = table.events
    assert event.code == code == fw.pa_syntax.code
    assert event.params == params
    # and the firmware reads back what it was told
    change = read_pa_command(fw, event, tool=0, source="t", warnings=[])
    assert change == PaChange(0.045, smooth)


def test_pa_command_without_smoothing_leaves_it_unchanged() -> None:
    assert pa_command(Firmware.KLIPPER, 0.0) == "SET_PRESSURE_ADVANCE ADVANCE=0"
    assert pa_command(Firmware.PRUSA, 0.1) == "M572 S0.1"


def test_pa_command_keeps_five_decimals() -> None:
    # one format for every writer (patterns, firmware settings, the closed loop)
    assert pa_command(Firmware.MARLIN, 0.0456789) == "M900 K0.04568"
    assert pa_command(Firmware.KLIPPER, 0.00125) == "SET_PRESSURE_ADVANCE ADVANCE=0.00125"


@pytest.mark.parametrize("fw", [f for f in Firmware if not f.smooths_advance])
def test_smoothing_window_rejected_where_firmware_has_none(fw: Firmware) -> None:
    with pytest.raises(GcodeError, match=r"pa_smooth_time_s.*no advance smoothing"):
        pa_command(fw, 0.05, smooth_time_s=0.04)


@pytest.mark.parametrize("t", [0.0, 0.25, float("nan")])
def test_smoothing_window_out_of_range(t: float) -> None:
    with pytest.raises(GcodeError, match=r"\[pa_smooth_time_s\].*out of range"):
        pa_command(Firmware.KLIPPER, 0.05, smooth_time_s=t)


@pytest.mark.parametrize("k", [-0.01, 10.5, float("nan"), float("inf")])
def test_advance_factor_out_of_range(k: float) -> None:
    with pytest.raises(GcodeError, match=r"\[k_s\].*out of range"):
        pa_command(Firmware.MARLIN, k)


def test_accel_command_klipper_uses_set_velocity_limit() -> None:
    # Klipper ignores M204 with only P or only T: use SET_VELOCITY_LIMIT
    line = accel_command(Firmware.KLIPPER, 2500.0)
    assert line == "SET_VELOCITY_LIMIT ACCEL=2500"
    (event,) = read_gcode((line + "\n").encode()).events
    assert event.params == {"ACCEL": 2500.0}


@pytest.mark.parametrize("fw", [f for f in Firmware if f.planner is PlannerFamily.MARLIN])
def test_accel_command_marlin_family(fw: Firmware) -> None:
    line = accel_command(fw, 1500.5)
    (event,) = read_gcode((line + "\n").encode()).events
    assert event.code == "M204" and event.params == {"P": 1500.5, "T": 1500.5}


@pytest.mark.parametrize("a", [0.0, -5.0, 2e6, float("nan")])
def test_accel_out_of_range(a: float) -> None:
    with pytest.raises(GcodeError, match=r"\[accel_mm_s2\].*out of range"):
        accel_command(Firmware.MARLIN, a)


def test_parse_firmware() -> None:
    assert Firmware.parse("RRF") is Firmware.REPRAPFIRMWARE
    assert Firmware.parse(" Klipper ") is Firmware.KLIPPER
    assert Firmware.parse(Firmware.PRUSA) is Firmware.PRUSA
    with pytest.raises(ProfileError, match="allowed: klipper, marlin, reprapfirmware, "
                                           "prusa, repetier"):
        Firmware.parse("smoothie")


def test_traits_of_the_table() -> None:
    # the rows of flowtwin.firmware.kinds, as the module docstring states them
    assert Firmware.KLIPPER.planner is PlannerFamily.KLIPPER
    assert all(f.planner is PlannerFamily.MARLIN for f in Firmware if f is not Firmware.KLIPPER)
    assert Firmware.PRUSA.advance is Firmware.KLIPPER.advance is AdvanceAlgorithm.SMOOTHED
    assert Firmware.REPETIER.advance is AdvanceAlgorithm.LINEAR_ADVANCE
    assert Firmware.REPRAPFIRMWARE.advance is AdvanceAlgorithm.WITHIN_MOVE
    assert Firmware.KLIPPER.default_printer == "generic-klipper"
    assert Firmware.PRUSA.default_printer == "generic-marlin"


def _ev(code: str, **params: float | str) -> Event:
    return Event(0, 7, code, dict(params))


def test_read_pa_command_ranges_and_extruders() -> None:
    w: list[str] = []
    # Klipper: negative ADVANCE and a window over 0.2 s are rejected, the other kept
    assert read_pa_command(Firmware.KLIPPER, _ev("SET_PRESSURE_ADVANCE", ADVANCE=-1.0,
                                                 SMOOTH_TIME=0.02),
                           tool=0, source="f", warnings=w) == PaChange(None, 0.02)
    assert w == ["f:7: ADVANCE=-1.0 < 0 rejected by Klipper"]
    assert read_pa_command(Firmware.KLIPPER, _ev("SET_PRESSURE_ADVANCE", EXTRUDER="extruder1",
                                                 ADVANCE=0.1),
                           tool=0, source="f", warnings=w) is None
    # Marlin: T selects the tool, K over 10 is refused, M900 alone reports only
    assert read_pa_command(Firmware.MARLIN, _ev("M900", T=1.0, K=0.1), tool=0, source="f",
                           warnings=w) is None
    assert read_pa_command(Firmware.MARLIN, _ev("M900", K=11.0), tool=0, source="f",
                           warnings=w) is None
    assert read_pa_command(Firmware.MARLIN, _ev("M900"), tool=0, source="f",
                           warnings=w) is None
    # RRF: D lists extruders (colon separated)
    assert read_pa_command(Firmware.REPRAPFIRMWARE, _ev("M572", D="1:2", S=0.1), tool=2,
                           source="f", warnings=w) == PaChange(0.1)
    assert read_pa_command(Firmware.REPRAPFIRMWARE, _ev("M572", D="1:2", S=0.1), tool=0,
                           source="f", warnings=w) is None
    # Prusa: S out of 0-10 and W out of 0-0.2 ignored with a message, D ignored
    w.clear()
    assert read_pa_command(Firmware.PRUSA, _ev("M572", D=3.0, S=12.0, W=0.1), tool=0,
                           source="f", warnings=w) == PaChange(None, 0.1)
    assert w == ["f:7: M572 S12.0 out of range 0-10; ignored"]


def test_format_number() -> None:
    assert format_number(0.0) == "0"
    assert format_number(-0.0000001) == "0"
    assert format_number(0.05) == "0.05"
    assert format_number(1.234567) == "1.23457"
