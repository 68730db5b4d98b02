"""Running jobs on dask.distributed: the client, the submission window and the result loop.

Reliability comes from dask itself:

* a task whose worker dies is rescheduled by the scheduler on another worker (up to
  ``distributed.scheduler.allowed-failures`` deaths, default 3, after which it fails with
  ``KilledWorker``: the row says so and the run goes on);
* a task that raises (anything but a :class:`~flowtwin.errors.FlowtwinError`, which
  :func:`~flowtwin.batch.jobs.run_job` turns into an error row) is run again up to
  ``retries`` times (``Client.submit(retries=...)``), then its row carries the exception;
* rows are deduplicated by ``row_id`` when written, so a result that arrives twice (a
  recomputed task) is stored once.

At most ``window`` tasks are in flight; the next one is submitted as each result arrives
(``as_completed``), so memory stays bounded for any number of jobs and Ctrl-C stops
quickly.
"""

from __future__ import annotations

import contextlib
import json
import logging
import math
import os
import time
import uuid
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from flowtwin.atomic import atomic_write_text
from flowtwin.batch.jobs import Cell, Job, JobResult, error_row, run_job
from flowtwin.batch.options import DEFAULT_RETRIES
from flowtwin.batch.store import ResultWriter
from flowtwin.errors import FlowtwinError

if TYPE_CHECKING:
    from distributed import Client

__all__ = [
    "DEFAULT_RETRIES",
    "ClusterError",
    "Progress",
    "RunStats",
    "dask_client",
    "default_workers",
    "run_jobs",
]

#: How often the result loop wakes up to apply the time-based flush, s.
_POLL_S = 0.05


class ClusterError(FlowtwinError):
    """The dask scheduler cannot be reached or the cluster cannot be started."""


@dataclass(frozen=True, slots=True)
class Progress:
    """One result arrived.

    Attributes
    ----------
    done
        Rows finished in this run so far (this one included).
    total
        Rows this run computes (skipped rows excluded).
    failed
        Of ``done``, rows with an error.
    row
        The row that arrived.
    """

    done: int
    total: int
    failed: int
    row: Mapping[str, Cell]


@dataclass(frozen=True, slots=True)
class RunStats:
    """Counts of a result loop: rows written with and without error, results dropped
    as duplicates, and the worker threads of the cluster."""

    ok: int
    failed: int
    duplicates: int
    threads: int


def default_workers() -> int:
    """Worker processes of a local cluster: one per CPU this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


@contextlib.contextmanager
def dask_client(*, scheduler: str | None = None, workers: int | None = None,
                threads_per_worker: int = 1) -> Iterator[Client]:
    """A dask ``Client``: connected to ``scheduler``, or to a new local cluster.

    Parameters
    ----------
    scheduler
        Address of a running scheduler (``tcp://HOST:PORT``); ``None`` starts a
        ``LocalCluster`` of worker processes on 127.0.0.1 (no dashboard; the scheduler's
        health/metrics HTTP routes on a free port of 127.0.0.1), closed on exit.
    workers
        Worker processes of the local cluster (default :func:`default_workers`); not
        allowed with ``scheduler``.
    threads_per_worker
        Threads per local worker process (the models hold the GIL: keep 1).

    Yields
    ------
    distributed.Client
    """
    from distributed import Client, LocalCluster

    if scheduler is not None:
        if workers is not None:
            raise ClusterError("--workers sizes a local cluster; an existing cluster keeps "
                               "its own workers", field="--workers", value=workers,
                               allowed="--workers or --scheduler, not both")
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            raise ClusterError(f"cannot connect to the dask scheduler: {exc}",
                               field="--scheduler", value=scheduler,
                               allowed="the tcp://HOST:PORT address of a running dask "
                                       "scheduler") from exc
        try:
            yield client
        finally:
            client.close()
        return
    n = default_workers() if workers is None else workers
    if n < 1:
        raise ClusterError("a local cluster needs at least one worker", field="--workers",
                           value=n, allowed=">= 1")
    # Everything listens on 127.0.0.1 only. The scheduler always serves its health and
    # metrics routes over HTTP (on port 8787 unless told otherwise): a free port, and no
    # dashboard.
    cluster = LocalCluster(n_workers=n, threads_per_worker=threads_per_worker,
                           processes=True, host="127.0.0.1", dashboard_address="127.0.0.1:0",
                           scheduler_kwargs={"dashboard": False}, silence_logs=logging.ERROR)
    try:
        with Client(cluster) as client:
            yield client
    finally:
        cluster.close()


def _report_path(folder: Path, job: Job) -> Path:
    stem = Path(job.file).name
    for suffix in (".gz", ".gcode", ".bgcode", ".gco", ".g"):
        stem = stem.removesuffix(suffix)
    return folder / f"{stem or 'gcode'}-{job.row_id[:8]}.json"


def _jsonable(obj: object) -> object:
    """NaN and infinities become null; numpy scalars and tuples become JSON types."""
    if hasattr(obj, "item") and callable(obj.item) and not isinstance(obj, Mapping):
        obj = obj.item()
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, Mapping):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    return obj


def _write_report(folder: Path, job: Job, report: Mapping[str, object]) -> None:
    document = {"row_id": job.row_id, "file": job.file, "setup": job.machine.name,
                "params": dict(job.params), "engine": job.engine, "report": report}
    text = json.dumps(_jsonable(document), indent=1, allow_nan=False, default=str)
    atomic_write_text(_report_path(folder, job), text + "\n")


def run_jobs(client: object, jobs: Iterable[Job], *, writer: ResultWriter, total: int,
             retries: int = DEFAULT_RETRIES, window: int | None = None,
             reports_dir: Path | None = None,
             on_result: Callable[[Progress], None] | None = None) -> RunStats:
    """Run ``jobs`` on ``client`` and stream their rows to ``writer``.

    Parameters
    ----------
    client
        A ``distributed.Client``.
    jobs
        The jobs (consumed lazily, ``window`` at a time).
    writer
        Where the rows go (as they arrive).
    total
        Number of jobs (for progress events).
    retries
        Extra attempts of a task that raised.
    window
        Tasks in flight at most (default: 4 per worker thread, at least 32).
    reports_dir
        Write each job's report there as ``<file stem>-<row id>.json``.
    on_result
        Called after each row is stored (from this thread).

    Returns
    -------
    RunStats

    Raises
    ------
    ClusterError
        A task was cancelled (the scheduler went away).
    """
    from distributed import KilledWorker, as_completed

    threads = sum(client.nthreads().values())  # type: ignore[attr-defined]
    limit = window if window is not None else max(32, 4 * threads)
    nonce = uuid.uuid4().hex[:8]
    pending: dict[str, tuple[object, Job]] = {}
    queue = iter(jobs)
    # with_results: results are fetched in the background as tasks finish, not one
    # round trip per result here.
    ac = as_completed(with_results=True, raise_errors=False)
    ok = failed = duplicates = 0

    def submit_next() -> bool:
        job = next(queue, None)
        if job is None:
            return False
        future = client.submit(run_job, job, key=f"flowtwin-{job.row_id}-{nonce}",  # type: ignore[attr-defined]
                               retries=retries, pure=False)
        pending[future.key] = (future, job)
        ac.add(future)
        return True

    try:
        while len(pending) < limit and submit_next():
            pass
        while pending:
            batch = ac.next_batch(block=False)
            if not batch:
                writer.tick()
                time.sleep(_POLL_S)
                continue
            for future, outcome in batch:
                _, job = pending[future.key]
                report: Mapping[str, object] | None = None
                # The status is read now, not when the task finished: a result already
                # fetched stays good although its worker died since ("lost").
                if isinstance(outcome, JobResult):
                    row, report = outcome.row, outcome.report
                elif future.status in ("lost", "pending"):
                    # Its worker died before the result reached us: the scheduler runs
                    # the task again; wait for that run.
                    ac.add(future)
                    continue
                elif future.status == "error":
                    exc = outcome[1] if isinstance(outcome, tuple) else future.exception()
                    if isinstance(exc, KilledWorker):
                        row = error_row(job, "killed", f"the task killed the workers that "
                                                       f"ran it: {exc}")
                    else:
                        row = error_row(job, "internal", f"{type(exc).__name__}: {exc} "
                                                         f"(after {retries + 1} attempts)")
                else:
                    raise ClusterError(f"task of {job.file} ended as {future.status!r}: the "
                                       "scheduler or this client went away",
                                       field="--scheduler")
                del pending[future.key]
                future.release()
                if writer.add(row):
                    if row.get("error") is None:
                        ok += 1
                    else:
                        failed += 1
                    if report is not None and reports_dir is not None:
                        _write_report(reports_dir, job, report)
                    if on_result is not None:
                        on_result(Progress(ok + failed, total, failed, row))
                else:
                    duplicates += 1
                submit_next()
        writer.flush()
    finally:
        if pending:
            client.cancel([f for f, _ in pending.values()])  # type: ignore[attr-defined]
    return RunStats(ok, failed, duplicates, threads)
