"""gzip-compressed G-code (``flowtwin.gcode.gz``, ISA-L): standard gzip both ways, and a
clear error on a damaged file."""

from __future__ import annotations

import gzip
import shutil
import subprocess
from pathlib import Path

import pytest

from flowtwin.errors import GcodeError
from flowtwin.gcode import gz
from flowtwin.gcode.reader import read_gcode

TEXT = b"".join(b"G1 X%d.%03d Y%d E%.5f F1800\n" % (i % 200, i % 997, i % 150, i * 0.0123)
                for i in range(20000))


def test_what_flowtwin_writes_is_standard_gzip() -> None:
    packed = gz.compress(TEXT)
    assert gzip.decompress(packed) == TEXT
    assert packed == gz.compress(TEXT)  # no time stamp: the same bytes every time
    assert len(packed) < len(TEXT) / 3
    tool = shutil.which("gzip")
    assert tool is not None, "Debian's gzip is part of the base system"
    out = subprocess.run([tool, "-dc"], input=packed, capture_output=True, check=True)
    assert out.stdout == TEXT


def test_the_writer_and_reader_round_trip_through_the_standard_library(tmp_path: Path) -> None:
    path = tmp_path / "a.gcode.gz"
    with open(path, "wb") as raw:
        sink = gz.writer(raw)
        sink.write(TEXT)
        sink.close()
    assert gzip.decompress(path.read_bytes()) == TEXT
    path.write_bytes(gzip.compress(TEXT, compresslevel=9))
    with open(path, "rb") as raw:
        assert gz.reader(raw).read() == TEXT
    assert len(read_gcode(path).moves) == len(read_gcode(TEXT).moves) > 19000


@pytest.mark.parametrize("damage", ["truncated", "crc"])
def test_a_damaged_gzip_file_is_a_clear_error_naming_the_file(tmp_path: Path,
                                                               damage: str) -> None:
    packed = gzip.compress(TEXT)
    bad = packed[:len(packed) // 2] if damage == "truncated" else packed[:-8] + bytes(8)
    path = tmp_path / "damaged.gcode.gz"
    path.write_bytes(bad)
    with pytest.raises(GcodeError, match=r"damaged\.gcode\.gz") as err:
        read_gcode(path)
    assert "cannot read G-code" in str(err.value)
