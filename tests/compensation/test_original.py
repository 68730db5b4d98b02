"""The modes of every row come from the reader's events; E on an exact decimal grid."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flowtwin.compensation.original import e_grid_text, read_original
from flowtwin.errors import GcodeError
from flowtwin.gcode.moves import MoveKind
from flowtwin.gcode.reader import read_gcode

MIXED = """G21
G90
M82
G92 E0
G1 Z0.2 F600
G1 X10 Y10 E0.5 F1800
G1 X20 E1.25
G92 E0
G1 X20 Y20 E0.33333
M83
G1 X25 E.2
G91
G1 X1 Y1 E0.1
G90
G92 X0 Y0
G1 X5 Y0 E0.3
G2 X10 Y5 I0 J5 E0.4
G1 E-0.8 F2100
G1 E0.8
M82
G1 X7 Y7 E5.123456
M220 S50
G1 X8 E5.2
"""
#: E of every line as written (grid units of 10⁻⁶ mm), by line
LINE_E = {6: 500000, 7: 750000, 9: 333330, 11: 200000, 13: 100000, 16: 300000, 17: 400000,
          18: -800000, 19: 800000, 21: 5123456 - 333330 - 200000 - 100000 - 300000 - 400000,
          23: 5200000 - 5123456}


@pytest.fixture()
def mixed(tmp_path: Path) -> Path:
    path = tmp_path / "mixed.gcode"
    path.write_text(MIXED)
    return path


def test_modes_follow_the_readers_events(mixed: Path) -> None:
    table = read_gcode(mixed)
    orig = read_original(mixed, table)
    mv = table.moves
    line = mv["line"]
    assert orig.e_decimals == 6  # E words have up to 6 decimals: the grid follows the file
    at = {int(ln): int(np.flatnonzero(line == ln)[0]) for ln in np.unique(line).tolist()}
    # G91 makes E relative too; M83 makes only E relative
    assert orig.abs_e[at[6]] and orig.abs_xyz[at[6]]
    assert not orig.abs_e[at[11]] and orig.abs_xyz[at[11]]
    assert not orig.abs_e[at[13]] and not orig.abs_xyz[at[13]]
    assert orig.abs_e[at[21]]
    # G92 X0 Y0: toolhead = G-code + offset, the offset is where the head was
    assert orig.offset_xyz[at[16], 0] == pytest.approx(float(mv["x"][at[13]]))
    assert mv["x"][at[16]] == pytest.approx(5.0 + orig.offset_xyz[at[16], 0])
    assert orig.speed_factor[at[23]] == 0.5 and orig.speed_factor[at[21]] == 1.0
    # every line's E exactly, arcs split over their chords
    written = (mv["kind"] & MoveKind.FW_RETRACT) == 0
    for ln, grid in LINE_E.items():
        rows = (line == ln) & written
        assert int(np.sum(orig.row_e[rows])) == grid, ln
    assert np.count_nonzero(line == 17) > 1
    # the E coordinate before every row (G92 E0 resets it)
    assert orig.e_before[at[7]] == 500000 and orig.e_before[at[9]] == 0
    assert orig.e_before[at[21]] == 333330 + 200000 + 100000 + 300000 + 400000
    assert orig.e_reset[at[9]] and not orig.e_reset[at[7]]


@pytest.mark.parametrize(("value", "decimals", "text"), [
    (120000, 5, "1.2"), (-5, 5, "-0.00005"), (0, 5, "0"), (123456789, 6, "123.456789"),
    (-1000000, 6, "-1")])
def test_e_grid_text(value: int, decimals: int, text: str) -> None:
    assert e_grid_text(value, decimals) == text


@pytest.mark.parametrize(("extra", "message"), [("G20\n", "inch"), ("M200 D1.75\n", "volumetric")])
def test_unsupported_units_name_the_line(tmp_path: Path, extra: str, message: str) -> None:
    path = tmp_path / "bad.gcode"
    path.write_text("G1 X1 E0.1 F600\n" + extra + "G1 X2 E0.2\n")
    table = read_gcode(path)
    with pytest.raises(GcodeError, match=message) as info:
        read_original(path, table)
    assert info.value.line == 2 and info.value.source == str(path)


def test_too_many_e_decimals_are_refused(tmp_path: Path) -> None:
    path = tmp_path / "fine.gcode"
    path.write_text("M83\nG1 X1 E0.1234567891 F600\n")
    with pytest.raises(GcodeError, match="decimals") as info:
        read_original(path, read_gcode(path))
    assert info.value.line == 2
