"""``run_batch`` and ``run_sweep``: the Python API behind ``flowtwin batch`` and ``sweep``.

Both prepare every job on the client first (inputs expanded, parameters parsed, every
sweep point's machine built and checked), so a bad path, value or profile is reported
before any task is submitted; then they run the jobs on dask and stream the rows to the
output (:mod:`flowtwin.batch.store`).
"""

from __future__ import annotations

import glob
import os
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from flowtwin.batch.cluster import DEFAULT_RETRIES, Progress, RunStats, dask_client, run_jobs
from flowtwin.batch.jobs import (
    DEFAULT_ENGINE,
    ENGINES,
    Engine,
    Job,
    machine_fingerprint,
    row_identity,
)
from flowtwin.batch.overrides import (
    MachineBuilder,
    check_axes,
    count_points,
    grid_points,
    load_base,
    sample_points,
)
from flowtwin.batch.params import Axis, ParamValue, parse_axis
from flowtwin.batch.shadowed import shadowed_parameters
from flowtwin.batch.store import ResultWriter
from flowtwin.errors import FlowtwinError, GcodeError, ProfileError
from flowtwin.profiles.machine import Machine
from flowtwin.profiles.setup import SetupProfile

__all__ = ["GCODE_SUFFIXES", "RunSummary", "expand_inputs", "run_batch", "run_sweep"]

#: File endings a folder is searched for (each also with ``.gz``).
GCODE_SUFFIXES = (".gcode", ".gco", ".g", ".bgcode")

ProfileSpec = str | os.PathLike[str] | SetupProfile | Machine | None


@dataclass(frozen=True, slots=True)
class RunSummary:
    """What a batch or sweep run did.

    Attributes
    ----------
    command
        ``"batch"`` or ``"sweep"``.
    out
        The results table.
    jobs
        Rows of the run (done earlier and now).
    skipped
        Rows already done by an earlier run (``resume``).
    ok, failed
        Rows computed now, without and with an error.
    complete
        Every job has its row.
    elapsed_s
        Wall time of the run, s (cluster start-up included).
    threads
        Worker threads of the cluster.
    engine
        The model used.
    warnings
        Things the user should know about the results (e.g. swept parameters that the
        G-code sets itself, :mod:`flowtwin.batch.shadowed`).
    """

    command: str
    out: Path
    jobs: int
    skipped: int
    ok: int
    failed: int
    complete: bool
    elapsed_s: float
    threads: int
    engine: str
    warnings: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, object]:
        """Plain JSON-able values."""
        return {"command": self.command, "out": str(self.out), "jobs": self.jobs,
                "skipped": self.skipped, "ok": self.ok, "failed": self.failed,
                "complete": self.complete, "elapsed_s": self.elapsed_s,
                "threads": self.threads, "engine": self.engine,
                "warnings": list(self.warnings)}


def _is_gcode(path: Path) -> bool:
    name = path.name.lower().removesuffix(".gz")
    return any(name.endswith(s) for s in GCODE_SUFFIXES)


def expand_inputs(patterns: Sequence[str | os.PathLike[str]]) -> list[Path]:
    """The G-code files named by paths, glob patterns and folders.

    Parameters
    ----------
    patterns
        Each one a file (kept even if it does not exist: its row then carries the error),
        a glob pattern (``*``, ``?``, ``[...]``, ``**`` for any depth), or a folder
        (searched at any depth for ``.gcode``, ``.gco``, ``.g`` and their ``.gz``).

    Returns
    -------
    list of Path
        In the order given (pattern and folder matches sorted), each file once.

    Raises
    ------
    GcodeError
        No pattern given, or a pattern or folder matches no G-code file.
    """
    if not patterns:
        raise GcodeError("no G-code files given", allowed="files, folders or glob patterns")
    out: dict[str, Path] = {}
    for item in patterns:
        text = os.fspath(item)
        if text == "-":
            raise GcodeError("standard input cannot be part of a batch", source=text,
                             allowed="files, folders or glob patterns")
        if glob.has_magic(text):
            found = sorted(Path(p) for p in glob.glob(text, recursive=True) if Path(p).is_file())
            if not found:
                raise GcodeError("the pattern matches no file", source=text,
                                 allowed="a pattern matching G-code files")
        elif Path(text).is_dir():
            found = sorted(p for p in Path(text).rglob("*") if p.is_file() and _is_gcode(p))
            if not found:
                raise GcodeError("the folder holds no G-code file", source=text,
                                 allowed="a folder with " + ", ".join(GCODE_SUFFIXES)
                                         + " (or .gz) files")
        else:
            found = [Path(text)]
        for path in found:
            out.setdefault(os.path.abspath(path), path)
    return list(out.values())


def _check_common(engine: str, retries: int) -> None:
    if engine not in ENGINES:
        raise FlowtwinError("unknown engine", field="--engine", value=engine,
                            allowed=", ".join(ENGINES))
    if retries < 0:
        raise FlowtwinError("retries must not be negative", field="--retries", value=retries,
                            allowed=">= 0")


def _execute(command: str, jobs: Iterator[Job], ids: list[str], *, out: str | os.PathLike[str],
             config: dict[str, object], engine: str, resume: bool, client: object | None,
             scheduler: str | None, workers: int | None, retries: int,
             reports_dir: str | os.PathLike[str] | None, flush_rows: int, flush_s: float,
             on_start: Callable[[int, int], None] | None,
             on_result: Callable[[Progress], None] | None,
             skip: Callable[[frozenset[str]], None],
             warnings: Sequence[str] = ()) -> RunSummary:
    t0 = time.perf_counter()
    writer = ResultWriter(out, config=config, resume=resume, flush_rows=flush_rows,
                          flush_s=flush_s)
    skip(writer.done_ids)
    skipped = sum(1 for rid in ids if rid in writer.done_ids)
    todo = len(ids) - skipped
    reports = Path(reports_dir) if reports_dir is not None else None
    if reports is not None:
        reports.mkdir(parents=True, exist_ok=True)
    if on_start is not None:
        on_start(todo, skipped)
    stats = RunStats(0, 0, 0, 0)
    complete = False
    try:
        if todo:
            with (dask_client(scheduler=scheduler, workers=workers) if client is None
                  else _given(client)) as active:
                stats = run_jobs(active, jobs, writer=writer, total=todo, retries=retries,
                                 reports_dir=reports, on_result=on_result)
        complete = stats.ok + stats.failed == todo
    finally:
        writer.finish(complete=complete)
    return RunSummary(command, Path(out), len(ids), skipped, stats.ok, stats.failed, complete,
                      time.perf_counter() - t0, stats.threads, engine, tuple(warnings))


class _given:
    """Context manager yielding a client the caller owns (not closed here)."""

    def __init__(self, client: object) -> None:
        self.client = client

    def __enter__(self) -> object:
        return self.client

    def __exit__(self, *args: object) -> None:
        return None


def _read_bytes(path: Path) -> bytes | None:
    try:
        return path.read_bytes()
    except OSError:
        return None  # the worker reads the path and reports the error in the row


def run_batch(files: Sequence[str | os.PathLike[str]], *, out: str | os.PathLike[str],
              profile: ProfileSpec = None, engine: Engine = DEFAULT_ENGINE,
              reports_dir: str | os.PathLike[str] | None = None, client: object | None = None,
              scheduler: str | None = None, workers: int | None = None,
              retries: int = DEFAULT_RETRIES, resume: bool = False, ship_files: bool = False,
              flush_rows: int = 256, flush_s: float = 1.0,
              on_start: Callable[[int, int], None] | None = None,
              on_result: Callable[[Progress], None] | None = None) -> RunSummary:
    """Simulate many G-code files on one machine; one row per file.

    Parameters
    ----------
    files
        Files, folders and glob patterns (:func:`expand_inputs`).
    out
        Results table, ``.parquet`` or ``.csv``.
    profile
        Set-up (built-in name, ``.toml`` path, :class:`SetupProfile` or :class:`Machine`);
        default :data:`~flowtwin.batch.overrides.DEFAULT_SETUP`.
    engine
        ``"plan"`` or ``"simulate"`` (:mod:`flowtwin.batch.jobs`).
    reports_dir
        Also write each file's full report (JSON) into this folder.
    client
        A ``distributed.Client`` to use (left open); else one is made from ``scheduler``
        or a local cluster of ``workers`` processes and closed at the end.
    scheduler, workers
        See :func:`~flowtwin.batch.cluster.dask_client`.
    retries
        Extra attempts of a task that raised.
    resume
        Keep the rows of an earlier interrupted (or finished) run of the same profile and
        engine in ``out`` and compute only the missing ones.
    ship_files
        Read each file here and send its bytes to the workers (for workers that do not
        share this file system).
    flush_rows, flush_s
        Part-file policy of :class:`~flowtwin.batch.store.ResultWriter`.
    on_start
        Called with (rows to compute, rows skipped) before the cluster starts.
    on_result
        Called as each row is stored.

    Returns
    -------
    RunSummary

    Raises
    ------
    FlowtwinError
        Bad inputs, profile or options (before any task is submitted); a run that cannot
        reach its cluster. A file the model rejects is not an exception: its row carries
        the message.
    """
    _check_common(engine, retries)
    paths = expand_inputs(files)
    machine = load_base(profile)
    keys = [os.path.abspath(p) for p in paths]
    ids = [row_identity(k, (), engine) for k in keys]
    config: dict[str, object] = {"command": "batch", "engine": engine,
                                 "machine": machine_fingerprint(machine)}
    done: set[str] = set()

    def jobs() -> Iterator[Job]:
        for index, (path, key, rid) in enumerate(zip(paths, keys, ids, strict=True)):
            if rid in done:
                continue
            data = _read_bytes(path) if ship_files else None
            # Workers get the absolute path: their working directory is not ours.
            yield Job(index, rid, str(path), data if data is not None else key, machine,
                      (), engine, reports_dir is not None)

    return _execute("batch", jobs(), ids, out=out, config=config, engine=engine, resume=resume,
                    client=client, scheduler=scheduler, workers=workers, retries=retries,
                    reports_dir=reports_dir, flush_rows=flush_rows, flush_s=flush_s,
                    on_start=on_start, on_result=on_result, skip=done.update)


def _points(axes: Sequence[Axis], sample: int | None, seed: int
            ) -> list[dict[str, ParamValue]]:
    if sample is None:
        count_points(axes)
        return list(grid_points(axes))
    return sample_points(axes, sample, seed=seed)


def run_sweep(source: str | os.PathLike[str], params: Sequence[str | Axis], *,
              out: str | os.PathLike[str], profile: ProfileSpec = None,
              sample: int | None = None, seed: int = 0, engine: Engine = DEFAULT_ENGINE,
              reports_dir: str | os.PathLike[str] | None = None, client: object | None = None,
              scheduler: str | None = None, workers: int | None = None,
              retries: int = DEFAULT_RETRIES, resume: bool = False, ship_files: bool = False,
              flush_rows: int = 256, flush_s: float = 1.0,
              on_start: Callable[[int, int], None] | None = None,
              on_result: Callable[[Progress], None] | None = None) -> RunSummary:
    """Simulate one G-code over a grid (or random sample) of profile parameters.

    Parameters
    ----------
    source
        The G-code file.
    params
        ``PATH=VALUES`` texts (:func:`~flowtwin.batch.params.parse_axis`) or axes.
    out
        Results table, ``.parquet`` or ``.csv``: one row per point, one column per path.
    profile
        The set-up the parameters change (as in :func:`run_batch`).
    sample
        Draw this many random points instead of the full grid.
    seed
        Seed of the random sample.
    engine, reports_dir, client, scheduler, workers, retries, resume, ship_files,
    flush_rows, flush_s, on_start, on_result
        As in :func:`run_batch`.

    Returns
    -------
    RunSummary
        Its ``warnings`` name swept parameters that the G-code sets itself (``M104``
        temperature, ``M900`` pressure advance, ``M204`` acceleration, …): those values
        apply only before the G-code sets its own, as on the printer.

    Raises
    ------
    ProfileError
        A bad path, value or combination (every point is built and checked before any task
        is submitted); names the parameter, the value and what is allowed.
    """
    _check_common(engine, retries)
    if not params:
        raise ProfileError("a sweep needs at least one --param", field="--param",
                           allowed="PATH=VALUES, e.g. setup.temperature_c=190:230:5")
    axes = [p if isinstance(p, Axis) else parse_axis(p, sampling=sample is not None)
            for p in params]
    seen: dict[str, str] = {}
    for axis in axes:
        for name in axis.paths:
            if name in seen:
                raise ProfileError("a parameter is swept twice", source="--param", field=name,
                                   value=[seen[name], axis.text], allowed="each path once")
            seen[name] = axis.text
    base = load_base(profile)
    builder = MachineBuilder(base)
    check_axes(builder, axes)
    points = _points(axes, sample, seed)
    for point in points:  # every combination checked before anything runs
        builder.build(point)
    path = Path(source)
    if not path.is_file():  # every point would fail the same way
        raise GcodeError("cannot open G-code file", source=str(path),
                         allowed="an existing G-code file")
    key = os.path.abspath(path)
    ids = [row_identity(key, tuple(p.items()), engine) for p in points]
    config: dict[str, object] = {"command": "sweep", "engine": engine, "file": key,
                                 "machine": machine_fingerprint(base)}
    done: set[str] = set()
    data = _read_bytes(path) if ship_files else None

    def jobs() -> Iterator[Job]:
        for index, (point, rid) in enumerate(zip(points, ids, strict=True)):
            if rid in done:
                continue
            yield Job(index, rid, str(path), data if data is not None else key,
                      builder.build(point), tuple(point.items()), engine,
                      reports_dir is not None)

    warnings = shadowed_parameters(path, [p for axis in axes for p in axis.paths])
    return _execute("sweep", jobs(), ids, out=out, config=config, engine=engine, resume=resume,
                    client=client, scheduler=scheduler, workers=workers, retries=retries,
                    reports_dir=reports_dir, flush_rows=flush_rows, flush_s=flush_s,
                    on_start=on_start, on_result=on_result, skip=done.update,
                    warnings=warnings)
