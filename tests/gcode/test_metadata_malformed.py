"""Slicer comments with the wrong separator or no value never stop a read (#21).

A comment is free text: ``; total filament length [mm] = 1503.2`` (an ``=`` where PrusaSlicer
writes ``:``) once made every command fail with an IndexError. Each estimate key is tried
with ``:``, ``=``, no separator and an empty or non-numeric value; the read must succeed and
take a value only where there is one.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flowtwin.errors import FlowtwinError
from flowtwin.gcode.reader import read_gcode

KEYS = ("estimated printing time (normal mode)", "total estimated time", "time", "print time",
        "build time", "estimated build time", "filament used [mm]", "filament used",
        "filament length", "total filament length [mm]")


def _read(tmp_path: Path, comment: str) -> dict[str, object]:
    path = tmp_path / "m.gcode"
    path.write_text(f"G90\nM83\n; {comment}\nG1 X10 E1 F1200\n", encoding="utf-8")
    return read_gcode(path).metadata


@pytest.mark.parametrize("key", KEYS)
@pytest.mark.parametrize("tail", ["", " ", " = ", ":", " : abc", " = 1503.2", ": 1503.2",
                                  " 1503.2", " = 1h 2m", ":::", " = = 3"])
def test_estimate_comments_of_any_shape_are_read(tmp_path: Path, key: str, tail: str) -> None:
    md = _read(tmp_path, key + tail)
    for name in ("slicer_time_s", "slicer_filament_mm"):
        value = md.get(name)
        assert value is None or (isinstance(value, float) and value >= 0.0)


def test_the_reported_comment_gives_its_filament(tmp_path: Path) -> None:
    md = _read(tmp_path, "total filament length [mm] = 1503.2")
    assert md["slicer_filament_mm"] == 1503.2


@settings(max_examples=300, deadline=None)
@given(key=st.sampled_from(KEYS),
       tail=st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="\r\n"),
                    max_size=40))
def test_any_text_after_an_estimate_key_is_read(tmp_path_factory: pytest.TempPathFactory,
                                                key: str, tail: str) -> None:
    """Read, or refused with the project's own error (a NUL byte is binary data)."""
    try:
        _read(tmp_path_factory.mktemp("m"), key + tail)
    except FlowtwinError as exc:
        assert "m.gcode:3" in str(exc) and "\x00" in tail
