"""The per-task job of a batch or sweep: one G-code on one machine -> one table row.

:func:`run_job` is a pure function of its :class:`Job` (the same job gives the same row,
on any worker, in any order), so dask can run it anywhere and run it again after a worker
is lost. The model behind it is chosen by :data:`Engine`:

* ``"simulate"`` (default) — :func:`flowtwin.simulation.simulate`, the whole-print twin
  (print time, commanded and delivered volume, width, force, grinding and ooze figures);
* ``"plan"`` — :func:`flowtwin.planner.plan_file.plan_gcode` only (print time, filament, moves,
  layers): faster, for time estimates.

A row is flat: the job's identity (``index``, ``row_id``, ``file``, one column per swept
parameter path, ``setup``, ``engine``), ``error`` and ``error_kind`` (``None`` when the file
was simulated), then the engine's summary with nested tables as JSON text.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from flowtwin.batch.options import DEFAULT_ENGINE, ENGINES, Engine
from flowtwin.batch.params import ParamValue
from flowtwin.errors import FlowtwinError
from flowtwin.profiles.machine import Machine

__all__ = [
    "DEFAULT_ENGINE",
    "ENGINES",
    "Cell",
    "Engine",
    "ErrorKind",
    "Job",
    "JobResult",
    "error_row",
    "evaluate",
    "flatten_summary",
    "machine_fingerprint",
    "row_identity",
    "run_job",
]

#: Why a row has no results: ``input`` = the G-code or profile was rejected (a
#: FlowtwinError, deterministic); ``internal`` = the task raised another exception on every
#: attempt; ``killed`` = the task took down the workers that ran it too often.
ErrorKind = Literal["input", "internal", "killed"]

#: A value of a table cell.
Cell = float | int | bool | str | None

_META = ("index", "row_id", "file")


@dataclass(frozen=True, slots=True)
class Job:
    """One G-code on one machine.

    Attributes
    ----------
    index
        Position of the job in its run (rows of the final table are sorted by it).
    row_id
        Stable identity of the row (:func:`row_identity`); ``--resume`` skips done ids.
    file
        Name of the G-code shown in the table (its path as given).
    source
        The G-code: a path readable by the worker, or the file's bytes.
    machine
        The resolved machine (parameters already applied and checked).
    params
        The swept parameters of this point, ``(path, value)`` in axis order.
    engine
        The model that computes the row.
    want_report
        Also return the engine's full report.
    """

    index: int
    row_id: str
    file: str
    source: str | bytes
    machine: Machine
    params: tuple[tuple[str, ParamValue], ...] = ()
    engine: Engine = DEFAULT_ENGINE
    want_report: bool = False


@dataclass(frozen=True, slots=True)
class JobResult:
    """What a job returns: its table row and, on request, the engine's full report."""

    row: dict[str, Cell]
    report: dict[str, object] | None = field(default=None)


def _canonical(obj: object) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=str)


def row_identity(file_key: str, params: Sequence[tuple[str, ParamValue]],
                 engine: Engine) -> str:
    """A short stable id of a row: hash of the file, the parameter point and the engine.

    Parameters
    ----------
    file_key
        Identity of the G-code: its absolute path, or ``sha256:<hex>`` of its bytes.
    params
        ``(path, value)`` pairs of the point (order does not matter).
    engine
        The engine.

    Returns
    -------
    str
        16 hexadecimal characters.
    """
    text = _canonical([file_key, sorted((p, repr(v)) for p, v in params), engine])
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def machine_fingerprint(machine: Machine) -> str:
    """Hash of every part of a machine (identifies the profile a table was made with)."""
    parts = {name: getattr(machine, name).model_dump(mode="json")
             for name in ("setup", "printer", "drive", "roller", "hotend", "material",
                          "filament")}
    return hashlib.sha256(_canonical(parts).encode()).hexdigest()[:16]


def _cell(value: object) -> Cell:
    if isinstance(value, np.generic):
        value = value.item()
    if value is None or isinstance(value, bool | int | str):
        return value  # type: ignore[return-value]
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    return _canonical(value)


def flatten_summary(summary: Mapping[str, object]) -> dict[str, Cell]:
    """Table cells of an engine summary.

    Scalars are kept (numpy scalars become Python ones, NaN and infinities become
    missing values), anything nested (per-feature times, per-tool filament) becomes
    compact JSON text with sorted keys.
    """
    return {str(k): _cell(v) for k, v in summary.items()}


def _meta(job: Job) -> dict[str, Cell]:
    row: dict[str, Cell] = {"index": job.index, "row_id": job.row_id, "file": job.file}
    for path, value in job.params:
        row[path] = value
    row.update(setup=job.machine.name, engine=job.engine, error=None, error_kind=None)
    return row


def error_row(job: Job, kind: ErrorKind, message: str) -> dict[str, Cell]:
    """The row of a job that produced no results: its identity, ``error`` and ``error_kind``."""
    row = _meta(job)
    row.update(error=message, error_kind=kind)
    return row


def _source(job: Job) -> str | io.BytesIO:
    if isinstance(job.source, bytes):
        stream = io.BytesIO(job.source)
        stream.name = job.file  # type: ignore[misc]  # the reader names errors after it
        return stream
    return job.source


def evaluate(source: str | bytes | io.BytesIO, machine: Machine, *, engine: Engine,
             report: bool = False) -> tuple[dict[str, object], dict[str, object] | None]:
    """Run one engine on one G-code: the single place that knows the models.

    Parameters
    ----------
    source
        G-code path, bytes or binary stream.
    machine
        The machine.
    engine
        ``"plan"`` or ``"simulate"``.
    report
        Also build the full report (plan: the summary with the per-layer table).

    Returns
    -------
    summary, report
        The engine's ``summary()`` and the report (``None`` unless asked for).

    Raises
    ------
    FlowtwinError
        The G-code or the machine is rejected by the model.

    Notes
    -----
    Files above :data:`flowtwin.planner.plan_stream.STREAM_ABOVE_BYTES` are read, planned and
    simulated streamed (bounded memory; the same summary keys and figures).
    """
    from flowtwin.planner.plan_stream import should_stream

    large = isinstance(source, str) and should_stream(source, printer=machine.printer)
    if engine == "plan":
        from flowtwin.planner.plan_file import plan_gcode
        from flowtwin.planner.plan_stream import plan_stream

        planned = (plan_stream(source, printer=machine.printer).run() if large
                   else plan_gcode(source, printer=machine.printer))
        summary = planned.summary().as_dict()
        return summary, ({**summary, "per_layer": planned.per_layer()} if report else None)
    if engine == "simulate":
        from flowtwin.simulation import simulate, simulate_stream

        summary = (simulate_stream(source, machine=machine).aggregates.summary() if large
                   else simulate(source, machine=machine).summary()).as_dict()
        return summary, (dict(summary) if report else None)
    raise FlowtwinError("unknown engine", field="engine", value=engine,
                        allowed=", ".join(ENGINES))


def run_job(job: Job) -> JobResult:
    """Compute the row of one job.

    A G-code or profile the model rejects (:class:`~flowtwin.errors.FlowtwinError`) gives
    an error row carrying the message; any other exception propagates, so the scheduler
    retries the task and the caller records it if it keeps failing.

    Parameters
    ----------
    job
        The job.

    Returns
    -------
    JobResult
        The row (always), and the report when ``job.want_report`` and the job succeeded.
    """
    try:
        summary, report = evaluate(_source(job), job.machine, engine=job.engine,
                                   report=job.want_report)
    except FlowtwinError as exc:
        return JobResult(error_row(job, "input", str(exc)))
    row = _meta(job)
    for key, value in flatten_summary(summary).items():
        if key not in row:
            row[key] = value
    return JobResult(row, report)
