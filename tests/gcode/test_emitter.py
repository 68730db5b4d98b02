"""The G-code emitter: number formats, modal F, relative and absolute E, read back."""

from __future__ import annotations

import numpy as np
import pytest

from flowtwin.errors import GcodeError
from flowtwin.gcode.emitter import (
    GcodeEmitter,
    NumberFormat,
    Retraction,
    WordFormats,
    format_number,
)
from flowtwin.gcode.reader import read_gcode


def test_number_formats() -> None:
    assert NumberFormat(3)(1.5) == "1.500"
    assert NumberFormat(3, trim=True)(1.5) == "1.5"
    assert NumberFormat(0)(599.7) == "600"
    assert NumberFormat(5, trim=True)(-0.000001) == "0"
    assert format_number(2.0) == "2"
    for bad in (float("nan"), float("inf")):
        with pytest.raises(GcodeError, match="must be finite"):
            NumberFormat(3)(bad)
        with pytest.raises(GcodeError, match="must be finite"):
            format_number(bad)


def test_words_in_order_and_state_kept() -> None:
    out = GcodeEmitter()
    out.begin()
    assert out.move(x=10.0, y=5.0, e_mm=0.25, f_mm_min=1200.0) == 4
    out.move(z=0.3, f_mm_min=600.0)
    assert out.lines[-2:] == ["G1 X10.000 Y5.000 E0.25000 F1200", "G1 Z0.300 F600"]
    assert (out.x, out.y, out.z, out.f_mm_min) == (10.0, 5.0, 0.3, 600.0)
    assert out.e_words == 1 and out.filament_mm == 0.25


def test_modal_feed_rate() -> None:
    out = GcodeEmitter(repeat_f=False)
    out.move(x=1.0, f_mm_min=3000.0)
    out.move(x=2.0, f_mm_min=3000.0)
    out.move(x=3.0, f_mm_min=1500.0)
    assert out.lines == ["G1 X1.000 F3000", "G1 X2.000", "G1 X3.000 F1500"]
    # the default writes F on every move (as the built-in writers do)
    rep = GcodeEmitter()
    rep.move(x=1.0, f_mm_min=3000.0)
    rep.move(x=2.0, f_mm_min=3000.0)
    assert rep.lines[-1] == "G1 X2.000 F3000"


def _read_e(text: str) -> np.ndarray:
    return np.asarray(read_gcode(text.encode()).moves["de"])


def test_relative_and_absolute_e_extrude_the_same() -> None:
    # the same filament through M83 increments and M82 positions (with a G92 reset)
    steps = [0.4, -0.8, 0.8, 1.25, 0.3]
    texts = []
    for relative in (True, False):
        out = GcodeEmitter(WordFormats(e=NumberFormat(5, trim=True)))
        out.begin(relative_e=relative)
        out.reset_e()
        for i, e in enumerate(steps):
            if i == 3:
                out.reset_e(10.0)
            out.move(x=float(i + 1), e_mm=e, f_mm_min=1200.0)
        texts.append(out.text())
        assert out.filament_mm == pytest.approx(sum(steps))
    assert "M82 ; absolute E" in texts[1] and "G92 E10" in texts[1]
    assert "E11.25" in texts[1]  # a position after the reset, not an increment
    np.testing.assert_allclose(_read_e(texts[0]), steps, atol=1e-12)
    np.testing.assert_allclose(_read_e(texts[1]), steps, atol=1e-12)


def test_travel_retracts_lifts_and_restores() -> None:
    out = GcodeEmitter()
    out.move(z=0.2, f_mm_min=600.0)
    out.travel(20.0, 0.0, 9000.0, Retraction(0.8, 2100.0, 0.4, 600.0))
    assert out.lines[1:] == ["G1 E-0.80000 F2100", "G1 Z0.600 F600", "G1 X20.000 Y0.000 F9000",
                             "G1 Z0.200 F600", "G1 E0.80000 F2100"]
    assert out.z == 0.2 and out.filament_mm == 0.0
    n = out.n_lines
    out.travel(20.0, 0.0, 9000.0)  # already there: nothing
    assert out.n_lines == n


def test_commands_comments_markers_and_arcs() -> None:
    out = GcodeEmitter()
    out.comment("made by a test")
    out.marker("TYPE", "External perimeter")
    out.marker("LAYER_CHANGE")
    out.heat_nozzle(215, wait=True)
    out.heat_nozzle(190.5, either_way=True, comment="next set")
    out.heat_bed(60)
    out.fan(50.0)
    out.fan(0.0)
    out.command("M204", P=1500.5, T=1500.5)
    out.move(x=5.0, y=0.0, f_mm_min=600.0)
    out.arc(x=5.0, y=0.0, i=-5.0, j=0.0, e_mm=1.0, f_mm_min=1200.0)
    assert out.lines == ["; made by a test", ";TYPE:External perimeter", ";LAYER_CHANGE",
                         "M109 S215", "M109 R190.5 ; next set", "M140 S60", "M106 S128",
                         "M107", "M204 P1500.5 T1500.5", "G1 X5.000 Y0.000 F600",
                         "G3 X5.000 Y0.000 I-5.000 J0.000 E1.00000 F1200"]
    table = read_gcode(out.text().encode())
    assert table.unknown_commands == {}
    assert table.moves["de"].sum() == pytest.approx(1.0)


def test_drain_streams_and_keeps_numbering() -> None:
    out = GcodeEmitter()
    out.line("G21")
    assert list(out.drain()) == ["G21"]
    assert out.line("G90") == 2 and list(out.drain()) == ["G90"] and out.lines == []
    with pytest.raises(GcodeError, match="one line at a time"):
        out.line("G1 X1\nG1 X2")
