"""``flowtwin batch`` / ``flowtwin sweep`` through a typer app that registers them.

The commands run against the test's own LocalCluster (``--scheduler``). The interruption
test runs the command in a child process, sends it SIGINT mid-run, reads the partial
table, and finishes it with ``--resume``.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import typer
from typer.testing import CliRunner

from flowtwin.batch import parts_dir, read_results
from flowtwin.cli.batch import register
from flowtwin.errors import ProfileError

pytestmark = [pytest.mark.service, pytest.mark.xdist_group("batch-dask")]

# The child restores Python's own Ctrl-C handler: a process started with SIGINT ignored
# (as some test runners start their workers) would otherwise inherit the ignore.
SCRIPT = """
import signal
import typer
signal.signal(signal.SIGINT, signal.default_int_handler)
from flowtwin.cli.batch import register
app = typer.Typer()
register(app)
app()
"""


def _app() -> typer.Typer:
    app = typer.Typer()
    register(app)
    return app


def _address(client: object) -> str:
    return str(client.scheduler.address)  # type: ignore[attr-defined]


def test_batch_json_reports_rows_and_errors(dask_cluster: object, prints: dict[str, Path],
                                            tmp_path: Path) -> None:
    out = tmp_path / "farm.parquet"
    result = CliRunner().invoke(_app(), [
        "batch", str(prints["p2"]), str(prints["bad"]), str(prints["p5"]), "--out", str(out),
        "--scheduler", _address(dask_cluster), "--json", "--no-progress"])
    assert result.exit_code == 1, result.output  # some rows carry an error
    document = json.loads(result.stdout)  # exactly one JSON object on stdout
    assert (document["rows"], document["ok"], document["failed"]) == (3, 2, 1)
    assert [e["file"] for e in document["errors"]] == [str(prints["bad"])]
    assert read_results(out).num_rows == 3


def test_sweep_table_and_parameter_error(dask_cluster: object, prints: dict[str, Path],
                                         tmp_path: Path) -> None:
    out = tmp_path / "sweep.parquet"
    ok = CliRunner().invoke(_app(), [
        "sweep", str(prints["p2"]), "--param", "material.temperature_c=190:230:20",
        "-P", "drive.roller_id=1,3", "--out", str(out),
        "--scheduler", _address(dask_cluster), "--no-progress"])
    assert ok.exit_code == 0, ok.output
    assert "Rows" in ok.stdout and "p2.gcode" in ok.stdout  # the terminal table
    table = pq.read_table(out)
    assert table.num_rows == 6
    assert table.column("setup.temperature_c").to_pylist() == [190.0, 190.0, 210.0, 210.0,
                                                               230.0, 230.0]
    assert table.column("drive.roller_id").to_pylist() == [1, 3, 1, 3, 1, 3]
    bad_out = tmp_path / "bad.parquet"
    bad = CliRunner().invoke(_app(), [
        "sweep", str(prints["p2"]), "--param", "drive.pinch_force_n=50,900",
        "--out", str(bad_out), "--scheduler", _address(dask_cluster)])
    assert isinstance(bad.exception, ProfileError)
    assert "drive.pinch_force_n" in str(bad.exception) and "900" in str(bad.exception)
    assert "<= 500" in str(bad.exception)
    assert not bad_out.exists() and not parts_dir(bad_out).exists()


def test_interrupted_sweep_leaves_a_readable_partial_table_and_resumes(
        dask_cluster: object, prints: dict[str, Path], tmp_path: Path) -> None:
    script = tmp_path / "flowtwin_cli.py"
    script.write_text(SCRIPT)
    out = tmp_path / "sweep.parquet"
    args = ["sweep", str(prints["p30"]), "--param", "setup.temperature_c=180:240:0.25",
            "--out", str(out), "--scheduler", _address(dask_cluster), "--flush-rows", "1",
            "--engine", "plan", "--no-progress"]  # 241 points, one part file per row
    # 241 rows take seconds even on a fast machine (dask's ~10 ms per task), so the run
    # cannot end between the check below and the signal (121 rows once did on a busy CI).
    child = subprocess.Popen([sys.executable, str(script), *args], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    manifest = parts_dir(out) / "manifest.jsonl"
    deadline = time.monotonic() + 60.0
    try:
        # Wait for the first two parts (rows) on disk, then interrupt.
        while time.monotonic() < deadline and child.poll() is None:
            if manifest.is_file() and manifest.read_text().count("\n") >= 3:
                break
            time.sleep(0.01)
        assert child.poll() is None, "the run ended before it could be interrupted"
        child.send_signal(signal.SIGINT)
        _, stderr = child.communicate(timeout=60)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
    assert child.returncode == 130  # typer's exit status after Ctrl-C
    assert "interrupted: the rows done so far are in" in stderr
    partial = pq.read_table(out)  # a complete Parquet file any tool can read
    done = partial.num_rows
    assert 2 <= done < 241
    ids = partial.column("row_id").to_pylist()
    assert len(set(ids)) == done and partial.column("error").null_count == done
    assert read_results(out).column("row_id").to_pylist() == ids
    assert manifest.is_file()  # kept for --resume

    result = CliRunner().invoke(_app(), [*args, "--resume", "--json"])
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert (document["skipped"], document["ok"], document["rows"]) == (done, 241 - done, 241)
    final = read_results(out)
    assert final.num_rows == 241 and len(set(final.column("row_id").to_pylist())) == 241
    assert final.column("index").to_pylist() == list(range(241))
    assert not parts_dir(out).exists()
