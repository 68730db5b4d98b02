"""Work done on two threads gives the bytes of the work done on one.

The refinement's independent blocks are solved by numba's threads, and the written file's
bytes are made by a worker thread while the slip's last draft is simulated
(:mod:`flowtwin.compensation.ahead`): neither may change a byte of what is written.
"""

from __future__ import annotations

import gzip
import os
import subprocess
import sys
from pathlib import Path

import pytest

from flowtwin.compensation import compensate, readback
from flowtwin.compensation.ahead import WriteAhead
from flowtwin.compensation.draft import Draft
from flowtwin.compensation.emit import draft_text
from flowtwin.errors import GcodeError
from flowtwin.gcode.reader import ReadOptions

from .test_emit import checksummed_draft

_RUN = """
import sys
from flowtwin.compensation import compensate
from flowtwin.compensation import _qp
sizes = []
solve = _qp._solve_blocks
def counted(x, starts, *rest):
    sizes.append(starts.size)
    return solve(x, starts, *rest)
_qp._solve_blocks = counted
compensate(sys.argv[1], sys.argv[2], advance=True, slip=True)
print(max(sizes))
"""


@pytest.fixture(scope="module")
def example_gz(example: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The example print, gzip-compressed (the written file is then compressed too)."""
    path = tmp_path_factory.mktemp("gz") / "example.gcode.gz"
    path.write_bytes(gzip.compress(example.read_bytes(), mtime=0))
    return path


def test_the_thread_count_does_not_change_the_written_file(example_gz: Path,
                                                           tmp_path: Path) -> None:
    """The same file with numba on one thread and on two (fresh processes: the count is
    fixed when numba starts), the refinement's blocks solved on both."""
    outs = []
    for threads in (1, 2):
        out = tmp_path / f"t{threads}.gcode.gz"
        env = {**os.environ, "NUMBA_NUM_THREADS": str(threads)}
        done = subprocess.run([sys.executable, "-c", _RUN, str(example_gz), str(out)],
                              env=env, capture_output=True, text=True, timeout=600,
                              check=False)
        assert done.returncode == 0, done.stderr[-2000:]
        assert int(done.stdout.split()[-1]) > 1  # blocks to share between the threads
        outs.append(out.read_bytes())
    assert outs[0] == outs[1]
    assert gzip.decompress(outs[0]) != gzip.decompress(example_gz.read_bytes())


def test_bytes_made_ahead_are_the_serial_bytes(example: Path, example_gz: Path, tmp_path: Path,
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """The file written from the worker's bytes (read back from its text, stored after)
    is the file written after the stages, gzip or plain; the figures are the same."""
    ahead = compensate(example_gz, tmp_path / "ahead.gcode.gz", advance=True, slip=True)
    plain = compensate(example, tmp_path / "plain.gcode", advance=True, slip=True)
    monkeypatch.setattr(WriteAhead, "start", lambda self, draft, layout: None)
    serial = compensate(example_gz, tmp_path / "serial.gcode.gz", advance=True, slip=True)
    gz = (tmp_path / "ahead.gcode.gz").read_bytes()
    assert gz == (tmp_path / "serial.gcode.gz").read_bytes()
    assert gzip.decompress(gz) == (tmp_path / "plain.gcode").read_bytes()
    assert "slip" in ahead.transformations
    assert ahead.after.as_dict() == serial.after.as_dict() == plain.after.as_dict()


def test_a_layout_refused_ahead_raises_and_writes_nothing(tmp_path: Path) -> None:
    """A check that fails in the worker raises in the caller, as the serial write does."""
    new = checksummed_draft(tmp_path)
    layout = new.layout(check=False)
    with WriteAhead(ReadOptions()) as ahead:
        ahead.start(new, layout)
        assert ahead.take(new, new.layout(check=False)) is None  # another layout
        ahead.start(new, layout)
        pending = ahead.take(new, layout)
        assert pending is not None
        with pytest.raises(GcodeError, match="checksum"):
            pending.text()
    assert not (tmp_path / "out.gcode").exists()


def test_the_pipeline_stores_the_file_before_it_returns(example: Path, tmp_path: Path,
                                                        monkeypatch: pytest.MonkeyPatch
                                                        ) -> None:
    """A read-back that fails (on the worker) still leaves the file stored and raises in
    the caller, as the serial write did."""
    def broken(*_args: object, **_kw: object) -> None:
        raise GcodeError("read-back refused", source=str(tmp_path / "out.gcode"))

    monkeypatch.setattr(readback, "iter_move_chunks", broken)
    with pytest.raises(GcodeError, match="read-back refused"):
        compensate(example, tmp_path / "out.gcode", advance=True, slip=True)
    assert (tmp_path / "out.gcode").stat().st_size > 0


def test_the_workers_read_back_is_the_callers(example: Path, tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    """The worker reads the text back while the draft is simulated: the same moves and the
    same verdict as reading that text in the caller, for the pipeline's last draft."""
    kept: list[tuple[Draft, object, ReadOptions]] = []
    start = WriteAhead.start

    def keep(self: WriteAhead, draft: Draft, layout: object) -> None:
        kept.append((draft, layout, self._options))  # type: ignore[arg-type]
        start(self, draft, layout)  # type: ignore[arg-type]

    monkeypatch.setattr(WriteAhead, "start", keep)
    compensate(example, tmp_path / "out.gcode", advance=True, slip=True)
    draft, layout, options = kept[-1]
    assert options is not None  # the pipeline hands the worker its reader's options
    with WriteAhead(options) as ahead:
        ahead.start(draft, layout)  # type: ignore[arg-type]
        pending = ahead.take(draft, layout)  # type: ignore[arg-type]
        assert pending is not None
        text = pending.text()
        assert text is not None
        worker = pending.checked()
    caller = readback.read_back(draft_text(draft, layout), layout, options)  # type: ignore[arg-type]
    assert worker == caller and worker is not None
    assert worker.moves == len(draft) and worker.same
