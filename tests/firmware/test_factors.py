"""Per-firmware encoding of M220/M221/M900 and parsing of Marlin's reports."""

from __future__ import annotations

import pytest

from flowtwin.control.firmware import (
    Channel,
    Firmware,
    applied_percent,
    check_command,
    encode_factor,
    encode_pressure_advance,
    parse_factor_report,
    query_command,
)
from flowtwin.errors import FlowtwinError, GcodeError

M, K = Firmware.MARLIN, Firmware.KLIPPER


@pytest.mark.parametrize(("fw", "ch", "pct", "gcode"), [
    (M, Channel.FLOW, 95.0, "M221 S95"),
    (M, Channel.FLOW, 95.5, "M221 S96"),      # integer, halves up
    (M, Channel.FLOW, 94.5, "M221 S95"),      # not banker's rounding
    (M, Channel.SPEED, 87.4, "M220 S87"),
    (K, Channel.FLOW, 95.5, "M221 S95.5"),    # Klipper takes floats
    (K, Channel.SPEED, 100.0, "M220 S100"),
    (K, Channel.FLOW, 97.12345, "M221 S97.123"),
])
def test_encode_factor(fw: Firmware, ch: Channel, pct: float, gcode: str) -> None:
    assert encode_factor(fw, ch, pct) == gcode


def test_applied_percent_matches_encoding() -> None:
    assert applied_percent(M, 95.5) == 96.0
    assert applied_percent(K, 95.5) == 95.5


@pytest.mark.parametrize("pct", [0.0, -5.0, 1000.0, float("nan"), float("inf")])
def test_encode_factor_refuses_out_of_range(pct: float) -> None:
    with pytest.raises(FlowtwinError, match="multiplier out of range"):
        encode_factor(M, Channel.FLOW, pct)


def test_query_only_on_marlin() -> None:
    assert query_command(M, Channel.FLOW) == "M221"
    with pytest.raises(FlowtwinError, match="resets the factor to 100 % on Klipper"):
        query_command(K, Channel.FLOW)


@pytest.mark.parametrize(("line", "expected"), [
    ("echo:E0 Flow: 95%", (Channel.FLOW, 95.0)),
    ("echo: E1 Flow: 110%", (Channel.FLOW, 110.0)),
    ("FR:90%", (Channel.SPEED, 90.0)),
    ("echo:FR:100%", (Channel.SPEED, 100.0)),
    ("ok", None),
    ("T:21.30 /0.00", None),
])
def test_parse_marlin_reports(line: str, expected: tuple[Channel, float] | None) -> None:
    assert parse_factor_report(M, line) == expected


def test_klipper_never_reports_on_console() -> None:
    assert parse_factor_report(K, "echo:E0 Flow: 95%") is None


@pytest.mark.parametrize("line", ["M221", "M220", " m221 ", "M221 T0", "M221 ; query"])
def test_bare_factor_commands_refused_on_klipper(line: str) -> None:
    with pytest.raises(GcodeError, match="resets the factor"):
        check_command(K, line)
    assert check_command(M, line) == line.strip()  # a query on Marlin


def test_m900_refused_on_klipper_only() -> None:
    with pytest.raises(GcodeError, match="no M900"):
        check_command(K, "M900 K0.05")
    assert check_command(M, "M900 K0.05") == "M900 K0.05"
    assert check_command(K, "M221 S95.5") == "M221 S95.5"


def test_multi_line_refused() -> None:
    with pytest.raises(GcodeError, match="exactly one"):
        check_command(M, "M221 S95\nM220 S90")


def test_pressure_advance_per_firmware() -> None:
    assert encode_pressure_advance(M, 0.05) == "M900 K0.05"
    assert encode_pressure_advance(K, 0.05) == "SET_PRESSURE_ADVANCE ADVANCE=0.05"
    assert encode_pressure_advance(K, 0.0) == "SET_PRESSURE_ADVANCE ADVANCE=0"
    with pytest.raises(FlowtwinError, match="pressure advance out of range"):
        encode_pressure_advance(M, -0.1)
