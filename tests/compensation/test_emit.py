"""Writing pieces: exact decimal E, the E coordinate of absolute files, feeds, refusals, and
the move table of a draft equal, bit for bit, to what its written file reads back as."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flowtwin.compensation.draft import Draft
from flowtwin.compensation.original import read_original
from flowtwin.errors import GcodeError
from flowtwin.gcode.moves import MOVE_DTYPE
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
    return Draft.identity(read_original(path, table), table)


def assert_reads_back(draft: Draft, out: Path) -> None:
    """The written file reads back as the draft's own move table, bit for bit."""
    mine = draft.to_table().moves
    read = read_gcode(out).moves
    assert read.shape == mine.shape
    for name in MOVE_DTYPE.names or ():
        np.testing.assert_array_equal(read[name], mine[name], err_msg=name)


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


def test_absolute_e_after_a_change_is_set_back_by_g92(tmp_path: Path) -> None:
    src = tmp_path / "abs.gcode"
    src.write_text(ABS)
    d = draft_of(src)
    assert d.original.e_decimals == 5
    # line 6 (1.0 mm) becomes 3 pieces holding 1.1 mm: a G92 after it gives the next line
    # (not rewritten, it may read the coordinate) the coordinate it was written for
    new = split_first_print(d, [30000, 40000, 40000])
    out = tmp_path / "out.gcode"
    res = new.render(out)
    text = out.read_text().splitlines()
    assert text[5:9] == ["G1 X3.33333 E0.3 F1800", "G1 X6.66667 E0.7", "G1 X10 E1.1",
                         "G92 E1"]
    assert text[9:] == ABS.splitlines()[6:]  # everything after: untouched
    assert res.lines_rewritten == 1
    mv_in, mv_out = read_gcode(src).moves, read_gcode(out).moves
    assert np.sum(mv_out["de"]) == pytest.approx(np.sum(mv_in["de"]) + 0.1, abs=1e-12)
    # every move after the changed line extrudes what it did
    np.testing.assert_allclose(mv_out["de"][4:], mv_in["de"][2:], atol=1e-12)
    assert_reads_back(new, out)


def test_consecutive_rewritten_lines_carry_the_coordinate(tmp_path: Path) -> None:
    src = tmp_path / "abs.gcode"
    src.write_text(ABS)
    d = draft_of(src)
    # lines 6 and 7 both rewritten (+0.1 mm on line 6, −0.05 on line 7): line 7 goes on
    # from 1.1, and the G92 comes after it, before the retraction of line 8
    new = split_first_print(d, [30000, 40000, 40000])
    e = new.e_grid.copy()
    e[4] = 95000
    out = tmp_path / "out.gcode"
    new.with_e(e).render(out)
    text = out.read_text().splitlines()
    assert text[8:11] == ["G1 Y10 E2.05 F1800", "G92 E2", "G1 E1.20000 F2400"]
    assert_reads_back(new.with_e(e), out)
    # where the stretch ends on the original coordinate, no G92 is needed
    e[4] = 90000
    new.with_e(e).render(out)
    text = out.read_text().splitlines()
    assert text[8:10] == ["G1 Y10 E2 F1800", "G1 E1.20000 F2400"]
    assert_reads_back(new.with_e(e), out)


def test_relative_pieces_add_up_exactly(tmp_path: Path) -> None:
    src = tmp_path / "rel.gcode"
    src.write_text("G21\nG90\nM83\nG1 X0 Y1 F1200\nG1 X10 Y1 E0.33333 F1800\nG1 X20 E0.1\n")
    d = draft_of(src)
    new = split_first_print(d, [11111, 11111, 11111])
    out = tmp_path / "out.gcode"
    new.render(out)
    lines = out.read_text().splitlines()
    assert lines[4:7] == ["G1 X3.33333 E0.11111 F1800", "G1 X6.66667 E0.11111",
                          "G1 X10 E0.11111"]
    assert lines[7] == "G1 X20 E0.1"
    assert_reads_back(new, out)


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
    assert lines[4:8] == ["G1 E-0.05 F2100", "G1 X10 F9000", "G1 E0.03 F2100",
                          "G1 F9000"]
    assert lines[8:] == ["G1 X20 E0.3 F1800", "G1 X30 E0.3"]
    assert len(read_gcode(out)) == len(new)  # one move per piece
    assert_reads_back(new, out)


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
    assert_reads_back(d.with_feed(feed), out)


def checksummed_draft(tmp_path: Path) -> Draft:
    """A draft of a file with a checksummed line (N5 … *check), its E doubled."""
    src = tmp_path / "n.gcode"
    body = "N5 G1 X10 E0.5 F1200"
    check = 0
    for ch in body.encode():
        check ^= ch
    src.write_text(f"G21\nM83\n{body}*{check}\n")
    d = draft_of(src)
    return d.with_e(d.e_grid * 2)


def test_checksummed_lines_are_refused(tmp_path: Path) -> None:
    new = checksummed_draft(tmp_path)
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
    assert out.read_text().splitlines()[4:7] == [
        "G1 X3.33367 Y0.00067 E0.2 F1200", "G1 X3.33366 Y0.00066 E0.2",
        "G1 X3.33367 Y0.00067 E0.1"]


def test_comments_and_line_endings_are_kept(tmp_path: Path) -> None:
    src = tmp_path / "crlf.gcode"
    src.write_bytes(b"G21\r\nM83\r\nG1 X0 Y1 F1200\r\nG1 X10 Y1 E0.5 ; wall\r\nG1 X20 E0.1")
    d = draft_of(src)
    new = split_first_print(d, [25000, 25000])
    out = tmp_path / "out.gcode"
    new.render(out)
    assert out.read_bytes() == (b"G21\r\nM83\r\nG1 X0 Y1 F1200\r\n"
                                b"G1 X5 E0.25 F1200 ; wall\r\nG1 X10 E0.25\r\nG1 X20 E0.1")
    assert_reads_back(new, out)


def test_no_change_is_a_byte_identical_copy(tmp_path: Path) -> None:
    src = tmp_path / "abs.gcode"
    src.write_text(ABS)
    out = tmp_path / "out.gcode"
    res = draft_of(src).render(out)
    assert out.read_bytes() == src.read_bytes() and res.lines_rewritten == 0
