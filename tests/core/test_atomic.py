"""Atomic output: complete or absent, with ordinary permissions."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest

from flowtwin.atomic import atomic_open, atomic_write_text


def test_written_file_has_umask_permissions(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        atomic_write_text(tmp_path / "a.txt", "x")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "a.txt").stat().st_mode) == 0o644


def test_failure_leaves_nothing_and_keeps_the_old_file(tmp_path: Path) -> None:
    target = tmp_path / "b.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError), atomic_open(target) as fh:
        fh.write("new, half")
        raise RuntimeError("boom")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["b.txt"]


def test_temporaries_of_dead_writers_are_removed_by_the_next_write(tmp_path: Path) -> None:
    """A writer killed outright can leave ``.NAME.PID.XXXX.tmp``: the next write to NAME
    removes those whose process is gone and keeps a live writer's."""
    import subprocess
    import sys

    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    dead_pid = int(dead.stdout)
    stale = tmp_path / f".out.gcode.{dead_pid}.abcd1234.tmp"
    live = tmp_path / f".out.gcode.{os.getpid()}.ffff0000.tmp"
    other = tmp_path / f".other.gcode.{dead_pid}.abcd1234.tmp"
    for p in (stale, live, other):
        p.write_text("half")
    atomic_write_text(tmp_path / "out.gcode", "complete\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [live.name, other.name, "out.gcode"])
    assert (tmp_path / "out.gcode").read_text() == "complete\n"


def test_an_unfinished_write_is_invisible(tmp_path: Path) -> None:
    """While the file is written nothing of it is in the folder (unnamed, O_TMPFILE)."""
    target = tmp_path / "c.txt"
    with atomic_open(target) as fh:
        fh.write("in progress")
        fh.flush()
        assert list(tmp_path.iterdir()) == []
    assert target.read_text() == "in progress"
