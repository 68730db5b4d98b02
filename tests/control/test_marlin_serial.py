"""Marlin serial protocol over a real pty pair with a Marlin-like responder process."""

from __future__ import annotations

import re

import pytest

from flowtwin.control.printer import ConnectionLost
from flowtwin.control.transports.marlin_serial import (
    MarlinLineCodec,
    SerialPrinter,
    checksum,
    parse_reply,
)
from flowtwin.firmware import Channel


def test_checksum_is_xor_of_the_bytes() -> None:
    # Hand-computed: XOR over "N1 M110" bytes.
    expected = 0
    for ch in "N1 M110":
        expected ^= ord(ch)
    assert checksum("N1 M110") == expected
    # Known value used by hosts for the reset line "N0 M110 N0" (RepRap wiki example: 125).
    assert checksum("N0 M110 N0") == 125


def test_codec_numbers_lines_and_resends() -> None:
    codec = MarlinLineCodec()
    assert codec.reset_command() == b"M110 N0\n"
    a = codec.frame("M221 S95")
    b = codec.frame("M220 S90")
    assert a == f"N1 M221 S95*{checksum('N1 M221 S95')}\n".encode()
    assert b.startswith(b"N2 M220 S90*")
    assert codec.resend_from(1) == [a, b]
    with pytest.raises(ValueError, match="bare G-code"):
        codec.frame("M221 S95*12")


@pytest.mark.parametrize(("line", "kind", "no"), [
    ("ok", "ok", None), ("ok T:21.3 /0.0", "ok", None), ("Resend: 7", "resend", 7),
    ("rs N7", "resend", 7), ("echo:busy: processing", "busy", None),
    ("Error:checksum mismatch, Last Line: 6", "error", None), ("start", "start", None),
    ("echo:E0 Flow: 95%", "info", None),
])
def test_parse_reply(line: str, kind: str, no: int | None) -> None:
    r = parse_reply(line)
    assert (r.kind, r.line_no) == (kind, no)


def _numbered(lines: list[str]) -> list[tuple[int, str]]:
    out = []
    for text in lines:
        m = re.match(r"^N(\d+) (.*)\*(\d+)$", text)
        if m:
            assert checksum(f"N{m.group(1)} {m.group(2)}") == int(m.group(3))
            out.append((int(m.group(1)), m.group(2)))
    return out


def test_set_and_read_factors_marlin_semantics(marlin_pty) -> None:
    fw = marlin_pty()
    p = SerialPrinter(fw.path, command_timeout_s=3.0)
    p.connect()
    try:
        assert p.set_flow_factor(95.4).gcode == "M221 S95"  # Marlin takes integers
        assert p.set_speed_factor(87.6).gcode == "M220 S88"
        f = p.read_factors()
        assert (f.speed_pct, f.flow_pct, f.source) == (88.0, 95.0, "printer")
        resp = p.send_gcode("M221")
        assert resp.ok and resp.lines == ("echo:E0 Flow: 95%",)
    finally:
        p.close()
    assert fw.received()[0] == "M110 N0"
    sent = _numbered(fw.received())
    assert [n for n, _ in sent] == [1, 2, 3, 4, 5]  # consecutive line numbers from 1


def test_checksum_error_triggers_resend_of_the_same_line(marlin_pty) -> None:
    fw = marlin_pty("--corrupt", "2")
    p = SerialPrinter(fw.path, command_timeout_s=3.0)
    p.connect()
    try:
        p.set_flow_factor(90)
        r = p.set_flow_factor(80)  # line 2 "arrives corrupted" once, then is resent
        assert r.ok
        assert p.read_factors().flow_pct == 80.0
    finally:
        p.close()
    sent = _numbered(fw.received())
    assert [n for n, _ in sent][:3] == [1, 2, 2]
    assert sent[1] == sent[2] == (2, "M221 S80")


def test_line_number_error_resends_from_requested_line(marlin_pty) -> None:
    # The responder claims line 2 never arrived when it sees line 3: host resends 2 and 3.
    fw = marlin_pty("--skip", "3")
    p = SerialPrinter(fw.path, command_timeout_s=3.0)
    p.connect()
    try:
        for pct in (91, 92, 93):
            p.set_speed_factor(pct)
        assert p.read_factors().speed_pct == 93.0
    finally:
        p.close()
    nums = [n for n, _ in _numbered(fw.received())]
    assert nums[:5] == [1, 2, 3, 2, 3]


def test_busy_extends_the_wait(marlin_pty) -> None:
    fw = marlin_pty("--busy", "1")
    p = SerialPrinter(fw.path, command_timeout_s=3.0)
    p.connect()
    try:
        r = p.send_gcode("G4 P0")
        assert r.ok and not any("busy" in x for x in r.lines)
    finally:
        p.close()


def test_unknown_command_reply_is_kept(marlin_pty) -> None:
    fw = marlin_pty()
    p = SerialPrinter(fw.path, command_timeout_s=3.0)
    p.connect()
    try:
        r = p.send_gcode("M900 K0.05")
        assert r.ok and r.lines == ('echo:Unknown command: "M900 K0.05"',)
    finally:
        p.close()


def test_hangup_is_connection_lost_and_reconnect_works(marlin_pty) -> None:
    fw = marlin_pty("--hangup-after", "1")
    p = SerialPrinter(fw.path, command_timeout_s=2.0)
    p.connect()
    p.set_flow_factor(97)
    with pytest.raises(ConnectionLost):
        p.set_flow_factor(96)
    with pytest.raises(ConnectionLost):
        p.check()
    p.close()
    fw2 = marlin_pty()  # the board is plugged back in (new device)
    p2 = SerialPrinter(fw2.path, command_timeout_s=2.0)
    p2.connect()
    try:
        assert p2.read_factors().get(Channel.FLOW) == 100.0  # a fresh board is at 100 %
    finally:
        p2.close()
