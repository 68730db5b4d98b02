"""The line-state scanner replays the reader exactly; E on an exact decimal grid."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flowtwin.compensation.source import (
    format_grid,
    read_source,
    row_e_grid,
    scan_source,
)
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
"""


@pytest.fixture()
def mixed(tmp_path: Path) -> Path:
    path = tmp_path / "mixed.gcode"
    path.write_text(MIXED)
    return path


def test_scanner_matches_reader(mixed: Path) -> None:
    table = read_gcode(mixed)
    scanned = scan_source(read_source(mixed), table)
    # E words have up to 6 decimals here: the grid follows the file
    assert scanned.e_decimals == 6
    mv = table.moves
    for line in np.unique(mv["line"]).tolist():
        rows = mv["line"] == line
        de = float(np.sum(mv["de"][rows & ((mv["kind"] & MoveKind.FW_RETRACT) == 0)]))
        ml = scanned.motion[line]
        assert ml.de_grid * scanned.e_unit == pytest.approx(de, abs=1e-12)
    # modes as the reader applies them (G91 makes E relative too)
    assert scanned.motion[6].abs_e and not scanned.motion[11].abs_e
    assert not scanned.motion[13].abs_xyz and not scanned.motion[13].abs_e
    # G92 X0 Y0 offsets: toolhead = G-code + offset
    ml = scanned.motion[16]
    last = np.flatnonzero(mv["line"] == 16)[-1]
    assert float(ml.words["X"]) + ml.offset_xyz[0] == pytest.approx(float(mv["x"][last]))


def test_row_grid_splits_arcs_exactly(mixed: Path) -> None:
    table = read_gcode(mixed)
    scanned = scan_source(read_source(mixed), table)
    rows = row_e_grid(scanned, table)
    arc = table.moves["line"] == 17
    assert np.count_nonzero(arc) > 1
    assert int(np.sum(rows[arc])) == scanned.motion[17].de_grid  # exact in grid units


@pytest.mark.parametrize(("value", "decimals", "text"), [
    (120000, 5, "1.2"), (-5, 5, "-0.00005"), (0, 5, "0"), (123456789, 6, "123.456789"),
    (-1000000, 6, "-1")])
def test_format_grid(value: int, decimals: int, text: str) -> None:
    assert format_grid(value, decimals) == text


@pytest.mark.parametrize(("extra", "message"), [("G20\n", "inch"), ("M200 D1.75\n", "volumetric")])
def test_unsupported_units_name_the_line(tmp_path: Path, extra: str, message: str) -> None:
    path = tmp_path / "bad.gcode"
    path.write_text("G1 X1 E0.1 F600\n" + extra + "G1 X2 E0.2\n")
    table = read_gcode(path)
    with pytest.raises(GcodeError, match=message) as info:
        scan_source(read_source(path), table)
    assert info.value.line == 2 and info.value.source == str(path)
