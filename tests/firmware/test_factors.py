"""Per-firmware encoding of M220/M221, parsing of Marlin's reports, refused commands."""

from __future__ import annotations

import re

import pytest

from flowtwin.errors import FlowtwinError, GcodeError
from flowtwin.firmware import (
    Channel,
    Firmware,
    applied_percent,
    check_command,
    encode_factor,
    parse_factor_report,
    query_command,
    read_factor_command,
)

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


def test_klipper_guards_read_the_words_not_the_text() -> None:
    # line numbers, checksums and lower case are read as the reader reads them
    with pytest.raises(GcodeError, match="no M900"):
        check_command(K, "N12 m900 k0.05*37")
    assert check_command(K, "M9000") == "M9000"
    assert check_command(K, "M221 S95 ; keep") == "M221 S95 ; keep"


@pytest.mark.parametrize(("line", "expected"), [
    ("M221 S95.5", (Channel.FLOW, 95.5)),
    ("m220 s90", (Channel.SPEED, 90.0)),
    ("M221", (Channel.FLOW, None)),
    ("M221 S", (Channel.FLOW, None)),
    ("N3 M220 S80*12", (Channel.SPEED, 80.0)),
    ("M900 K0.1", None),
    ("G1 X1", None),
])
def test_read_factor_command(line: str, expected: tuple[Channel, float | None] | None) -> None:
    assert read_factor_command(line) == expected


@pytest.mark.parametrize("fw", [f for f in Firmware if f.factor_decimals is None])
def test_unmodelled_firmwares_are_refused_not_guessed(fw: Firmware) -> None:
    with pytest.raises(FlowtwinError, match=re.escape(f"does not model the M220/M221 "
                                                      f"commands of {fw.label}")
                       + ".*allowed: klipper, marlin"):
        encode_factor(fw, Channel.FLOW, 95.0)
    with pytest.raises(FlowtwinError, match="does not"):
        query_command(fw, Channel.FLOW)
    assert parse_factor_report(fw, "echo:E0 Flow: 95%") is None
