"""Reliability on a real LocalCluster of worker processes on 127.0.0.1.

A worker is killed for real (SIGKILL) while it holds tasks; a task that raises is
retried by dask and then recorded; the local cluster of ``dask_client`` starts and stops.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path
from typing import Any

import pytest

from flowtwin.batch import (
    DEFAULT_ENGINE,
    ClusterError,
    Job,
    MachineBuilder,
    Progress,
    ResultWriter,
    dask_client,
    grid_points,
    load_base,
    parse_axis,
    read_results,
    row_identity,
    run_job,
    run_jobs,
    run_sweep,
)
from flowtwin.batch.jobs import Cell

pytestmark = [pytest.mark.service, pytest.mark.xdist_group("batch-dask")]


def _expected_sweep_rows(source: Path, texts: list[str]) -> dict[str, dict[str, Cell]]:
    """The rows of a sweep computed here, in this process, one job after the other."""
    builder = MachineBuilder(load_base(None))
    rows: dict[str, dict[str, Cell]] = {}
    for index, point in enumerate(grid_points([parse_axis(t) for t in texts])):
        params = tuple(point.items())
        rid = row_identity(os.path.abspath(source), params, DEFAULT_ENGINE)
        job = Job(index, rid, str(source), str(source), builder.build(point), params,
                  DEFAULT_ENGINE)
        rows[rid] = run_job(job).row
    return rows


def test_killed_worker_tasks_are_retried_table_complete_no_duplicates(
        dask_cluster: object, prints: dict[str, Path], tmp_path: Path) -> None:
    client = dask_cluster
    params = ["setup.temperature_c=190:234:4"]  # 12 points
    pids: dict[str, int] = client.run(os.getpid)  # type: ignore[attr-defined]
    killed: dict[str, Any] = {}

    def kill_busiest_worker(event: Progress) -> None:
        if killed:
            return
        processing: dict[str, list[str]] = client.processing()  # type: ignore[attr-defined]
        address = max(processing, key=lambda a: len(processing[a]))
        killed.update(address=address, keys=list(processing[address]),
                      done_before=event.done)
        os.kill(pids[address], signal.SIGKILL)

    out = tmp_path / "sweep.parquet"
    summary = run_sweep(prints["p30"], params, out=out, client=client,
                        on_result=kill_busiest_worker)
    # The killed worker held tasks that had not returned when it died.
    assert killed["keys"], "the killed worker held no task: the test did not test anything"
    assert killed["done_before"] < 12
    assert summary.complete and summary.ok == 12 and summary.failed == 0
    table = read_results(out)
    ids = table.column("row_id").to_pylist()
    assert len(ids) == len(set(ids)) == 12
    # Every task the dead worker held has its row, and every row is the row computed
    # in-process (per-task determinism).
    held = {str(k).split("-")[1] for k in killed["keys"]}
    assert held <= set(ids)
    expected = _expected_sweep_rows(prints["p30"], params)
    assert {r["row_id"]: r for r in table.to_pylist()} == expected
    # The process is really gone (the nanny started a new worker in its place).
    assert pids[str(killed["address"])] not in client.run(os.getpid).values()  # type: ignore[attr-defined]


def test_task_that_raises_is_retried_then_recorded(
        dask_cluster: object, prints: dict[str, Path], tmp_path: Path) -> None:
    machine = load_base(None)
    good = Job(0, "good", str(prints["p2"]), str(prints["p2"]), machine)
    # A source that is neither a path nor bytes makes the reader raise AttributeError on
    # the worker: not a user error, so it propagates, dask runs the task 1 + retries
    # times, and the row records it.
    broken = Job(1, "broken", "twelve", 12345, machine)  # type: ignore[arg-type]
    writer = ResultWriter(tmp_path / "r.parquet", config={"test": 1})
    stats = run_jobs(dask_cluster, [good, broken], writer=writer, total=2, retries=1)
    rows = {r["row_id"]: r for r in writer.finish(complete=True).to_pylist()}
    assert (stats.ok, stats.failed) == (1, 1)
    assert rows["good"]["error"] is None and rows["good"]["total_time_s"] > 0
    assert rows["broken"]["error_kind"] == "internal"
    assert "AttributeError" in rows["broken"]["error"]
    assert "after 2 attempts" in rows["broken"]["error"]


def test_local_cluster_is_started_on_loopback_and_closed() -> None:
    with dask_client(workers=1) as client:
        info = client.scheduler_info()  # type: ignore[attr-defined]
        assert info["address"].startswith("tcp://127.0.0.1:")
        assert sum(client.nthreads().values()) == 1  # type: ignore[attr-defined]
        assert all(a.startswith("tcp://127.0.0.1:") for a in info["workers"])
    assert client.status == "closed"  # type: ignore[attr-defined]


def test_cluster_options_are_checked() -> None:
    with pytest.raises(ClusterError, match="not both"), \
            dask_client(scheduler="tcp://127.0.0.1:1", workers=2):
        pass
    with pytest.raises(ClusterError, match="at least one worker"), dask_client(workers=0):
        pass
