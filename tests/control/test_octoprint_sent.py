"""The OctoPrint connection matches its commands in the terminal log with the reader's
word parser (one G-code word parser: flowtwin.gcode.words)."""

from __future__ import annotations

from flowtwin.control.transports.octoprint import normalize_sent


def test_line_number_checksum_case_and_spaces_do_not_matter() -> None:
    want = normalize_sent("M221 S95")
    assert want == ("M221", (("S", 95.0),))
    assert normalize_sent("N12 M221 S95*87") == want
    assert normalize_sent("  n7   m221   s95.0 *3 ") == want
    assert normalize_sent("N3 SET_PRESSURE_ADVANCE ADVANCE=0.04*21") == (
        "SET_PRESSURE_ADVANCE", (("ADVANCE", 0.04),))


def test_other_commands_and_non_gcode_do_not_match() -> None:
    want = normalize_sent("M221 S95")
    assert normalize_sent("M221 S96") != want
    assert normalize_sent("M220 S95") != want
    assert normalize_sent("M221 S95 T1") != want
    assert normalize_sent("") is None
    assert normalize_sent("; just a comment") is None
