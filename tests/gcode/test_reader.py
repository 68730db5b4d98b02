"""Reader semantics on hand-written G-code with known answers."""

from __future__ import annotations

import gzip
import io
import math

import numpy as np
import pytest

from flowtwin.errors import GcodeError
from flowtwin.gcode.moves import MoveKind
from flowtwin.gcode.reader import ReadOptions, iter_move_chunks, read_gcode


def read(text: str, **opts: object) -> object:
    return read_gcode(text.encode(), options=ReadOptions(**opts))  # type: ignore[arg-type]


def test_absolute_and_relative_positions() -> None:
    t = read("G90\nG1 X10 Y5 F600\nG91\nG1 X1 Y-1 Z0.2\nG90\nG1 X0\n")
    m = t.moves
    assert m["x"].tolist() == [10.0, 11.0, 0.0]
    assert m["y"].tolist() == [5.0, 4.0, 4.0]
    assert m["z"].tolist() == [0.0, 0.2, 0.2]
    assert m["feed_mm_s"].tolist() == [10.0, 10.0, 10.0]
    assert m["line"].tolist() == [2, 4, 6]


def test_extrusion_modes_and_g92() -> None:
    t = read("M82\nG1 X1 E1\nG1 X2 E3\nG92 E0\nG1 X3 E0.5\nM83\nG1 X4 E0.25\nG91\nG1 X1 E0.1\n")
    assert np.allclose(t.moves["de"], [1, 2, 0.5, 0.25, 0.1])
    assert np.allclose(t.moves["e"], [1, 3, 3.5, 3.75, 3.85])
    assert t.net_filament_mm() == pytest.approx({0: 3.85})


def test_g92_xyz_offsets_and_g28_axes() -> None:
    t = read("G1 X10 Y10\nG92 X0 Y0\nG1 X5 Y5\nG28 X\nG1 Y6\n", home_xyz=(-3.0, -4.0, 1.0))
    m = t.moves
    assert (m["x"][1], m["y"][1]) == (15.0, 15.0)   # G92 made 10 the new 0
    assert (m["x"][2], m["y"][2]) == (-3.0, 16.0)   # G28 X: only X went home
    # the modal commands are events too (compensation reads its modes from them)
    assert [(e.code, e.move_index) for e in t.events] == [("G92", 1), ("G28", 2)]
    assert t.events[0].params == {"X": 0.0, "Y": 0.0}


def test_modal_commands_are_events_in_order() -> None:
    t = read("G21\nM82\nG90\nG1 X1 E1\nG92 E0\nM83\nG91\nG1 X1 E0.5\nG90\nG20\nG1 X1\n")
    assert [(e.code, e.move_index, e.line) for e in t.events] == [
        ("G21", 0, 1), ("M82", 0, 2), ("G90", 0, 3), ("G92", 1, 5), ("M83", 1, 6),
        ("G91", 1, 7), ("G90", 2, 9), ("G20", 2, 10)]
    assert t.events[3].params == {"E": 0.0}
    assert t.unknown_commands == {}


def test_inches_and_speed_and_flow_factors() -> None:
    t = read("G20\nG1 X1 F60\nG21\nM220 S50\nM221 S90\nG1 X30 E1 F600\n")
    m = t.moves
    assert m["x"][0] == pytest.approx(25.4)
    assert m["feed_mm_s"][0] == pytest.approx(25.4)  # 60 inch/min
    assert m["feed_mm_s"][1] == pytest.approx(5.0)   # 600 mm/min at 50 %
    assert m["flow"][1] == pytest.approx(0.9)
    assert m["de"][1] == pytest.approx(1.0)  # E as written; the factor is separate


def test_tools_keep_separate_e_and_pseudo_tools() -> None:
    t = read("M83\nT0\nG1 X1 E2\nT1\nG1 X2 E3\nT1000\nG1 X3 E0.5\nT0\nG1 X4 E1\n")
    assert t.net_filament_mm() == pytest.approx({0: 3.0, 1: 3.0, 1000: 0.5})
    assert [e.code for e in t.events] == ["M83", "T0", "T1", "T1000", "T0"]


def test_compact_words_without_spaces() -> None:
    t = read("G1X5Y98F9000\nG1Z0.3\n")
    assert (t.moves["x"][0], t.moves["y"][0], t.moves["z"][1]) == (5.0, 98.0, 0.3)


def test_full_circle_arc_klipper_segmentation() -> None:
    # r = 10 full circle: L = 62.83 mm -> floor(L/1.0) = 62 equal-angle segments
    t = read("G1 X10 Y0\nG2 X10 Y0 I-10 J0 E6.2832\n", arc_segment_mm=1.0)
    arc = t.moves[1:]
    assert len(arc) == 62
    assert np.all((arc["kind"] & MoveKind.ARC) != 0)
    r = np.hypot(arc["x"], arc["y"])
    assert np.allclose(r, 10.0)
    assert arc["de"].sum() == pytest.approx(6.2832)
    assert (arc["x"][-1], arc["y"][-1]) == (10.0, 0.0)
    # clockwise: the first segment goes to negative y
    assert arc["y"][0] < 0


def test_arc_chord_tolerance_and_r_form_and_helix() -> None:
    tol = 0.002
    t = read("G1 X0 Y0\nG3 X20 Y0 R10 Z2 E1\n", arc_tolerance_mm=tol)
    arc = t.moves  # G1 X0 Y0 from the origin is no move
    # half circle, counter-clockwise with r>0 -> centre (10, 0), passes through y<0
    pts = np.column_stack([np.r_[0.0, arc["x"]], np.r_[0.0, arc["y"]]])
    mids = (pts[1:] + pts[:-1]) / 2
    sagitta = 10.0 - np.hypot(mids[:, 0] - 10.0, mids[:, 1])
    assert sagitta.max() <= tol * (1 + 1e-9)
    assert arc["y"].min() < -9.9
    assert np.allclose(np.diff(np.r_[0.0, arc["z"]]), 2.0 / len(arc))  # helical Z
    with pytest.raises(GcodeError, match=r":2: arc needs"):
        read("G1 X0 Y0\nG2 X30 Y0 R10\n")


def test_firmware_retraction_and_rrf_temperature_g10() -> None:
    text = "M207 S1.5 F1800 Z0.4\nM208 S0.1 F600\nG1 X5 Z1\nG10\nG1 X10\nG11\nG10 P0 S195 R160\n"
    t = read(text)
    fw = t.moves[(t.moves["kind"] & MoveKind.FW_RETRACT) != 0]
    assert fw["de"].tolist() == pytest.approx([-1.5, 0.0, 0.0, 1.6])
    assert fw["z"].tolist() == pytest.approx([1.0, 1.4, 1.0, 1.0])
    assert fw["feed_mm_s"][0] == pytest.approx(30.0)
    assert fw["feed_mm_s"][3] == pytest.approx(10.0)
    assert t.net_filament_mm() == {0: 0.0}  # firmware retractions are not written filament
    rrf = [e for e in t.events if e.code == "G10"]
    assert rrf and rrf[-1].params == {"P": 0.0, "S": 195.0, "R": 160.0}
    off = read("G10\nG11\n", firmware_retraction=None)
    assert len(off.moves) == 0


def test_m200_volumetric_extrusion() -> None:
    t = read("M83\nM200 D1.75\nG1 X1 E2.405282\nM200 D0\nG1 X2 E1\n")
    assert t.moves["de"][0] == pytest.approx(1.0, rel=1e-6)
    assert t.moves["de"][1] == pytest.approx(1.0)


def test_line_numbers_and_checksums() -> None:
    def cs(body: str) -> str:
        x = 0
        for ch in body.encode():
            x ^= ch
        return f"{body}*{x}"

    t = read(cs("N1 G1 X5") + "\n" + cs("N2 G1 Y3") + "\n")
    assert (t.moves["x"][-1], t.moves["y"][-1]) == (5.0, 3.0)
    with pytest.raises(GcodeError, match=r":1: checksum"):
        read("N1 G1 X5*99\n")


def test_events_and_extended_commands() -> None:
    t = read("M204 P1500 T3000\nSET_VELOCITY_LIMIT ACCEL=500 SQUARE_CORNER_VELOCITY=4\n"
             "G4 P250\nM221 S\nSET_PRESSURE_ADVANCE ADVANCE=0.04\nM900 K0.05\nG1 X1\n")
    codes = {e.code: e.params for e in t.events}
    assert codes["M204"] == {"P": 1500.0, "T": 3000.0}
    assert codes["SET_VELOCITY_LIMIT"] == {"ACCEL": 500.0, "SQUARE_CORNER_VELOCITY": 4.0}
    assert codes["G4"] == {"P": 250.0}
    assert codes["M221"] == {"S": ""}
    assert codes["SET_PRESSURE_ADVANCE"] == {"ADVANCE": 0.04}
    assert all(e.move_index == 0 for e in t.events)
    assert any("M221" in w for w in t.warnings)


def test_unknown_commands_counted_or_strict() -> None:
    t = read("M486 S1\nEXCLUDE_OBJECT_START NAME=a\nM486 S2\nG1 X1\n")
    assert t.unknown_commands == {"M486": 2, "EXCLUDE_OBJECT_START": 1}
    with pytest.raises(GcodeError, match=r":1: unknown command M486"):
        read("M486 S1\n", strict=True)


def test_layers_and_features_from_markers_and_from_z() -> None:
    marked = read(";LAYER_CHANGE\n;Z:0.2\nG1 Z0.2\n;TYPE:Perimeter\nG1 X1 E1\n"
                  ";TYPE:Solid infill\nG1 X2 E1\n;LAYER_CHANGE\n;Z:0.4\nG1 Z0.4\nG1 X3 E1\n")
    assert marked.moves["layer"].tolist() == [0, 0, 0, 1, 1]
    names = [marked.features[i] if i >= 0 else None for i in marked.moves["feature"]]
    assert names == [None, "Perimeter", "Solid infill", "Solid infill", "Solid infill"]
    unmarked = read("M83\nG1 Z0.2\nG1 X1 E1\nG1 Z0.6\nG1 Z0.4\nG1 X2 E1\nG1 X3 E1\n")
    assert unmarked.moves["layer"].tolist() == [-1, 0, 0, 0, 1, 1]
    assert unmarked.layer_z == [0.2, 0.4]


def test_streaming_chunks_equal_whole_read() -> None:
    lines = ["G90", "M83"]
    for i in range(3000):
        lines.append(f"G1 X{i % 97}.5 Y{(i * 7) % 89}.25 E0.0{i % 9} F{1200 + i % 5}")
        if i % 100 == 0:
            lines.append(f";TYPE:feature{i % 3}")
            lines.append("G2 X10 Y10 I1 J1 E0.1")
    data = ("\n".join(lines) + "\n").encode()
    whole = read_gcode(data)
    parts = list(iter_move_chunks(data, chunk_bytes=997))
    assert len(parts) > 50
    joined = np.concatenate([p.moves for p in parts])
    for name in whole.moves.dtype.names:  # bit-identical, field by field (not padding)
        assert np.array_equal(joined[name], whole.moves[name]), name


def test_gzip_and_stream_sources(tmp_path: object) -> None:
    text = b"M83\nG1 X1 E1\nG1 X2 E1\n"
    assert len(read_gcode(io.BytesIO(gzip.compress(text))).moves) == 2
    path = tmp_path / "a.gcode.gz"  # type: ignore[operator]
    path.write_bytes(gzip.compress(text))
    assert read_gcode(path).net_filament_mm() == {0: 2.0}


@pytest.mark.parametrize(("text", "match"), [
    ("G1 X1.2.3\n", r":1 \[X\]: "),
    ("G1 X1e308\n", r":1\b"),
    ("G1 Xnan\n", r":1 \[X\]: "),
    ("G1 Y-inf\n", r":1 \[Y\]: "),
    ("G1 X99999999999\n", r":1\b"),
    ("G1 X1 F0\n", r":1 \[F\]: feed rate must be positive"),
    ("G1 X1\n\x00\x01\x02\n", r":2: binary data"),
    ("G1 X1\n%%%garbage\n", r":2: line does not start with a command"),
    ("G4 Pabc\n", r":1 \[P\]: G4 parameter P is not a number"),
])
def test_bad_input_names_line(text: str, match: str) -> None:
    with pytest.raises(GcodeError, match=match):
        read(text)


def test_truncated_file_is_a_counted_warning_not_wrong_total() -> None:
    t = read("M83\nG1 X1 E1\nG1 X2 E0.5")
    assert t.net_filament_mm() == {0: 1.5}
    assert any("does not end with a line break" in w for w in t.warnings)


def test_one_megabyte_line_of_junk_is_an_error() -> None:
    with pytest.raises(GcodeError, match=r":2 \[X\]: "):
        read("G1 X1\nG1 X" + "9" * 1_000_000 + "\n")
    long_comment = read("G1 X1\n;" + "x" * 1_000_000 + "\nG1 X2\n")
    assert len(long_comment.moves) == 2


def test_bgcode_and_missing_file(tmp_path: object) -> None:
    with pytest.raises(GcodeError, match="binary G-code"):
        read_gcode(io.BytesIO(b"GCDE\x01\x00\x00\x00"))
    with pytest.raises(GcodeError, match="cannot open"):
        read_gcode(tmp_path / "missing.gcode")  # type: ignore[operator]


def test_numbers_parse_like_python_float() -> None:
    rng = np.random.default_rng(7)
    raw = zip(rng.uniform(-500, 500, 2000), rng.integers(0, 6, 2000), strict=True)
    values = np.array([round(v, int(d)) for v, d in raw])
    text = "".join(f"G1 X{float(v)!r}\n" for v in values)
    t = read(text)
    # every distinct value produced a row whose X equals float(text) exactly
    xs = t.moves["x"]
    expected = [v for i, v in enumerate(values) if i == 0 or v != values[i - 1]]
    assert len(xs) == len(expected)
    assert np.array_equal(xs, np.array(expected))
    assert math.isfinite(float(xs.sum()))


def test_klipper_heater_macros_become_temperature_events() -> None:
    """Klipper slicer profiles heat in the start macro (``M104 S0`` then ``START_PRINT
    EXTRUDER_TEMP=220``): without reading it the twin would print the whole file with the
    heater off."""
    text = (b"M104 S0\nSTART_PRINT EXTRUDER_TEMP=220 BED_TEMP=60\n"
            b"PRINT_START EXTRUDER=205\nSET_HEATER_TEMPERATURE HEATER=extruder1 TARGET=215\n"
            b"SET_HEATER_TEMPERATURE HEATER=heater_bed TARGET=60\nSTART_PRINT BED=55\n"
            b"G1 X10 E1 F1000\n")
    table = read_gcode(text)
    assert [(e.code, e.params, e.line) for e in table.events] == [
        ("M104", {"S": 0.0}, 1), ("M109", {"S": 220.0}, 2), ("M109", {"S": 205.0}, 3),
        ("M104", {"S": 215.0, "T": 1.0}, 4)]
    # the bed heater and a start macro without a nozzle temperature stay unknown commands
    assert table.unknown_commands == {"SET_HEATER_TEMPERATURE": 1, "START_PRINT": 1}
    notes = [w for w in table.warnings if "read as M109 S220" in w]
    assert len(notes) == 1 and ":2:" in notes[0]  # said once, with its line
    with pytest.raises(GcodeError) as info:
        read_gcode(b"G28\nSTART_PRINT EXTRUDER_TEMP=hot\n")
    assert info.value.line == 2 and info.value.field == "EXTRUDER_TEMP"
    assert "hot" in str(info.value)
    with pytest.raises(GcodeError, match="0–1000"):
        read_gcode(b"START_PRINT EXTRUDER_TEMP=5000\n")
