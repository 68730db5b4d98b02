"""Writing pieces: exact decimal E, the E coordinate of absolute files, feeds, refusals."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flowtwin.compensation.draft import Draft
from flowtwin.compensation.source import read_source, row_e_grid, scan_source
from flowtwin.errors import GcodeError
from flowtwin.gcode.reader import read_gcode

ABS = """G21
G90
M82
G92 E0
G1 X0 Y1 F1200
G1 X10 Y1 E1.00000 F1800
G1 X10 Y10 E2.00000
G1 E1.20000 F2400
G1 X0 Y10 F9000
G1 E2.00000
G1 X0 Y1 E3.00000 F1800
G92 E0
G1 X5 Y5 E0.50000
"""


def draft_of(path: Path) -> Draft:
    table = read_gcode(path)
    scanned = scan_source(read_source(path), table)
    return Draft.identity(scanned, table, row_e_grid(scanned, table))


def split_first_print(d: Draft, e_pieces: list[int]) -> Draft:
    """Cut row 1 (line 6) into pieces with the given E (grid units)."""
    start = d.start_xyz()
    k = len(e_pieces)
    rows = [0] + [1] * k + list(range(2, len(d)))
    f = np.arange(1, k + 1) / k
    pts = [d.xyz_mm[0]] + [start[1] + fi * (d.xyz_mm[1] - start[1]) for fi in f] + \
        list(d.xyz_mm[2:])
    es = [int(d.e_grid[0]), *e_pieces, *d.e_grid[2:].tolist()]
    return d.split(np.array(rows), np.vstack(pts), np.array(es))


def test_absolute_e_lines_after_a_change_are_shifted(tmp_path: Path) -> None:
    src = tmp_path / "abs.gcode"
    src.write_text(ABS)
    d = draft_of(src)
    assert d.scanned.e_decimals == 5
    # line 6 (1.0 mm) becomes 3 pieces holding 1.1 mm: every later E word moves by +0.1
    # until the G92 E0 of line 12
    new = split_first_print(d, [30000, 40000, 40000])
    out = tmp_path / "out.gcode"
    res = new.render(out)
    text = out.read_text().splitlines()
    assert text[5:8] == ["G1 X3.33333 E0.3 F1800", "G1 X6.66667 E0.7", "G1 X10 Y1 E1.1"]
    assert text[8] == "G1 X10 Y10 E2.1" and text[9] == "G1 E1.3 F2400"
    assert text[11] == "G1 E2.1" and text[12] == "G1 X0 Y1 E3.1 F1800"
    assert text[13:] == ["G92 E0", "G1 X5 Y5 E0.50000"]  # after the reset: untouched
    assert res.lines_rewritten == 1 and res.lines_shifted == 4
    mv_in, mv_out = read_gcode(src).moves, read_gcode(out).moves
    assert np.sum(mv_out["de"]) == pytest.approx(np.sum(mv_in["de"]) + 0.1, abs=1e-12)
    # every move after the changed line extrudes what it did
    np.testing.assert_allclose(mv_out["de"][4:], mv_in["de"][2:], atol=1e-12)


def test_relative_pieces_add_up_exactly(tmp_path: Path) -> None:
    src = tmp_path / "rel.gcode"
    src.write_text("G21\nG90\nM83\nG1 X0 Y1 F1200\nG1 X10 Y1 E0.33333 F1800\nG1 X20 E0.1\n")
    d = draft_of(src)
    new = split_first_print(d, [11111, 11111, 11111])
    out = tmp_path / "out.gcode"
    new.render(out)
    lines = out.read_text().splitlines()
    assert lines[4:7] == ["G1 X3.33333 E0.11111 F1800", "G1 X6.66667 E0.11111",
                          "G1 X10 Y1 E0.11111"]
    assert lines[7] == "G1 X20 E0.1"


def test_feeds_of_e_only_pieces_are_restored(tmp_path: Path) -> None:
    src = tmp_path / "rel.gcode"
    src.write_text("G21\nG90\nM83\nG1 X0 Y1 F1200\nG1 X10 Y1 F9000\nG1 X20 E0.3 F1800\n"
                   "G1 X30 E0.3\n")
    d = draft_of(src)
    start = d.start_xyz()
    # travel (row 1) becomes: retract 0.05 at its start, travel, push back 0.03 at its end
    rows = np.array([0, 1, 1, 1, 2, 3])
    pts = np.vstack([d.xyz_mm[0], start[1], d.xyz_mm[1], d.xyz_mm[1], d.xyz_mm[2],
                     d.xyz_mm[3]])
    es = np.array([0, -5000, 0, 3000, 30000, 30000])
    feed = np.array([np.nan, 2100.0, np.nan, 2100.0, np.nan, np.nan])
    new = d.split(rows, pts, es, feed)
    out = tmp_path / "out.gcode"
    new.render(out)
    lines = out.read_text().splitlines()
    assert lines[4:8] == ["G1 E-0.05 F2100", "G1 X10 F9000", "G1 X10 Y1 E0.03 F2100",
                          "G1 F9000"]
    assert lines[8:] == ["G1 X20 E0.3 F1800", "G1 X30 E0.3"]
    assert len(read_gcode(out)) == len(new)  # one move per piece


def test_guard_feed_is_written_and_restored(tmp_path: Path) -> None:
    src = tmp_path / "rel.gcode"
    src.write_text("G21\nG90\nM83\nG1 X0 Y1 F1800\nG1 X20 E0.3\nG1 X30 E0.3\n")
    d = draft_of(src)
    feed = d.feed_mm_min.copy()
    feed[1] = 900.0
    out = tmp_path / "out.gcode"
    d.with_feed(feed).render(out)
    assert out.read_text().splitlines()[4:] == ["G1 X20 E0.3 F900", "G1 F1800",
                                                "G1 X30 E0.3"]


def test_checksummed_lines_are_refused(tmp_path: Path) -> None:
    src = tmp_path / "n.gcode"
    body = "N5 G1 X10 E0.5 F1200"
    check = 0
    for ch in body.encode():
        check ^= ch
    src.write_text(f"G21\nM83\n{body}*{check}\n")
    d = draft_of(src)
    new = d.with_e(d.e_grid * 2)
    with pytest.raises(GcodeError, match="checksum") as info:
        new.render(tmp_path / "out.gcode")
    assert info.value.line == 3
    assert not (tmp_path / "out.gcode").exists()


def test_relative_xyz_steps_are_exact(tmp_path: Path) -> None:
    src = tmp_path / "g91.gcode"
    src.write_text("G21\nM83\nG1 X0 Y1 F1200\nG91\nG1 X10.001 Y0.002 E0.5\nG1 X1 E0.1\n")
    d = draft_of(src)
    start = d.start_xyz()
    f = np.array([1 / 3, 2 / 3, 1.0])
    pts = np.vstack([d.xyz_mm[0]] + [start[1] + fi * (d.xyz_mm[1] - start[1]) for fi in f]
                    + [d.xyz_mm[2]])
    new = d.split(np.array([0, 1, 1, 1, 2]), pts, np.array([0, 20000, 20000, 10000, 10000]))
    out = tmp_path / "out.gcode"
    new.render(out)
    mv_in, mv_out = read_gcode(src).moves, read_gcode(out).moves
    assert mv_out["x"][-1] == pytest.approx(mv_in["x"][-1], abs=1e-12)
    assert mv_out["y"][3] == pytest.approx(mv_in["y"][1], abs=1e-12)
