"""Writer: byte-identical round trip, minimal edits, atomic output."""

from __future__ import annotations

import gzip
from pathlib import Path

import pytest

from flowtwin.errors import GcodeError
from flowtwin.gcode.writer import rewrite_gcode

SAMPLE = b"; head\r\nG1 X1 E1 ; c\r\n\r\nG1 X2   \nM104 S200\nG1 X3"


def test_no_edit_round_trip_is_byte_identical(tmp_path: Path) -> None:
    src = tmp_path / "in.gcode"
    src.write_bytes(SAMPLE)
    assert rewrite_gcode(src, tmp_path / "out.gcode") == 0
    assert (tmp_path / "out.gcode").read_bytes() == SAMPLE


def test_edits_touch_only_their_lines(tmp_path: Path) -> None:
    src = tmp_path / "in.gcode"
    src.write_bytes(SAMPLE)
    out = tmp_path / "out.gcode"
    n = rewrite_gcode(src, out, {2: ["G1 X0.5 E0.5", "G1 X1 E0.5"], 5: None, 6: "G1 X4"})
    assert n == 3
    assert out.read_bytes() == (b"; head\r\nG1 X0.5 E0.5\r\nG1 X1 E0.5\r\n\r\nG1 X2   \nG1 X4")


def test_gzip_round_trip(tmp_path: Path) -> None:
    src = tmp_path / "in.gcode.gz"
    src.write_bytes(gzip.compress(SAMPLE))
    rewrite_gcode(src, tmp_path / "out.gcode.gz")
    assert gzip.decompress((tmp_path / "out.gcode.gz").read_bytes()) == SAMPLE


def test_bad_edit_leaves_no_output(tmp_path: Path) -> None:
    src = tmp_path / "in.gcode"
    src.write_bytes(SAMPLE)
    out = tmp_path / "out.gcode"
    with pytest.raises(GcodeError, match="line the file does not have"):
        rewrite_gcode(src, out, {99: "G1 X1"})
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [src]  # no temporary file left behind
    with pytest.raises(GcodeError, match="line breaks"):
        rewrite_gcode(src, out, {1: "G1\nG2"})
    assert not out.exists()


@pytest.mark.corpus
def test_every_corpus_file_round_trips_byte_identical(corpus_dir: Path, tmp_path: Path) -> None:
    for path in sorted(corpus_dir.glob("*.gcode")):
        out = tmp_path / path.name
        rewrite_gcode(path, out)
        assert out.read_bytes() == path.read_bytes(), path.name
        out.unlink()
