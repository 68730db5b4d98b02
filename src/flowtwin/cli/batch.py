"""``flowtwin batch`` and ``flowtwin sweep``: many prints or many profile variants on dask.

A thin layer over :mod:`flowtwin.batch`: options in, :func:`~flowtwin.batch.run_batch` /
:func:`~flowtwin.batch.run_sweep` run, a progress bar on stderr, a summary (or with
``--json`` one JSON object) on stdout. Exit status 0 when every row succeeded, 1 when some
rows carry an error (the table is still complete), 2 for a user error before the run.
Ctrl-C (or SIGTERM) stops the run and leaves the rows done so far in ``--out``;
``--resume`` continues it.
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Callable, Iterator
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Annotated, cast

import typer

from flowtwin.batch.options import DEFAULT_ENGINE, DEFAULT_RETRIES, DEFAULT_SETUP, ENGINES, Engine
from flowtwin.cli._common import console, err_console, fmt_duration, print_json, table_from_rows
from flowtwin.errors import FlowtwinError

if TYPE_CHECKING:
    import pyarrow as pa
    from rich.progress import Progress as RichProgress
    from rich.progress import TaskID

    from flowtwin.batch import Progress, RunSummary

__all__ = ["register"]

#: Exit status when some rows carry an error.
EXIT_ROW_ERRORS = 1


class _Bar:
    """Rich progress bar (tasks done/total, failures) on stderr."""

    def __init__(self, label: str, *, enabled: bool) -> None:
        self.label = label
        self.enabled = enabled
        self.progress: RichProgress | None = None
        self.task: TaskID | None = None

    def start(self, total: int, skipped: int) -> None:
        if not self.enabled:
            return
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )
        from rich.progress import Progress as RichProgress

        if skipped:
            err_console.print(f"resuming: {skipped} row(s) already done")
        self.progress = RichProgress(
            TextColumn("[bold]{task.description}"), BarColumn(), MofNCompleteColumn(),
            TextColumn("{task.fields[failed]} failed"), TimeElapsedColumn(),
            TimeRemainingColumn(), console=err_console, transient=False)
        self.progress.start()
        self.task = self.progress.add_task(self.label, total=total, failed=0)

    def update(self, event: Progress) -> None:
        if self.progress is not None and self.task is not None:
            self.progress.update(self.task, completed=event.done, failed=event.failed)

    def close(self) -> None:
        if self.progress is not None:
            self.progress.stop()
            self.progress = None


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM stops the run like Ctrl-C (the partial table is written)."""

    def handler(signum: int, frame: FrameType | None) -> None:
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread (e.g. an embedding application)
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _param_paths(text: str) -> list[str]:
    """Canonical column names of one ``--param`` text (empty if it does not parse)."""
    from flowtwin.batch.params import ALIASES

    names = text.split("=", 1)[0].split("+")
    return [ALIASES.get(n.strip(), n.strip()) for n in names]


def _engine(value: str) -> Engine:
    if value not in ENGINES:
        raise FlowtwinError("unknown engine", field="--engine", value=value,
                            allowed=", ".join(ENGINES))
    return cast(Engine, value)


#: Result columns shown in the terminal when present (all are in the table).
_SHOWN = ("total_time_s", "volume_error", "worst_width_error_mm", "min_force_margin_n",
          "grinding_events", "ooze_volume_mm3", "rms_flow_error")


def _fmt(value: object) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _print_rows(table: pa.Table, params: list[str], *, limit: int = 20) -> None:
    """The first rows of the table with the parameters and the main figures."""
    names = table.column_names
    # At most six columns fit a terminal; every column is in the table file.
    columns = ["file", *(p for p in params if p in names)][:4]
    columns += [c for c in _SHOWN if c in names][:max(0, 6 - len(columns))]
    rows = table.select(columns).slice(0, limit).to_pylist()
    shown = [[Path(str(r["file"])).name if c == "file" else _fmt(r[c]) for c in columns]
             for r in rows]
    more = f" (first {limit} of {table.num_rows})" if table.num_rows > limit else ""
    console.print(table_from_rows(f"Rows{more}", columns, shown))


def _run(label: str, out: Path, progress: bool, json_out: bool,
         call: Callable[[Callable[[int, int], None], Callable[[Progress], None]], RunSummary],
         *, params: list[str] | None = None) -> None:
    from rich.markup import escape

    from flowtwin.batch import read_results

    bar = _Bar(label, enabled=progress)
    try:
        with _sigterm_as_interrupt():
            summary = call(bar.start, bar.update)
    except KeyboardInterrupt:
        bar.close()
        err_console.print(f"interrupted: the rows done so far are in {out}; run again with "
                          "--resume to finish")
        raise
    finally:
        bar.close()
    table = read_results(out)
    params = [path for text in (params or []) for path in _param_paths(text)]
    failures = []
    if "error" in table.column_names:
        for row in table.select(["index", "file", "error", "error_kind"]).to_pylist():
            if row["error"] is not None:
                failures.append(row)
    for warning in summary.warnings:
        err_console.print(f"[yellow]warning:[/] {escape(warning)}")
    if json_out:
        document = summary.as_dict()
        document["rows"] = table.num_rows
        document["errors"] = failures
        print_json(document)
    else:
        console.print(table_from_rows(f"{summary.command}: {summary.engine}", ["", ""], [
            ("results", str(summary.out)),
            ("rows", f"{table.num_rows} ({summary.ok} ok, {summary.failed} failed now, "
                     f"{summary.skipped} done earlier)"),
            ("time", f"{fmt_duration(summary.elapsed_s)} on {summary.threads} worker "
                     f"thread(s)"),
        ]))
        _print_rows(table, params)
        if failures:
            console.print(table_from_rows("Rows with errors", ["#", "error"], [
                (r["index"], r["error"]) for r in failures[:20]]))
            if len(failures) > 20:
                console.print(f"… and {len(failures) - 20} more (column 'error')")
    if failures:
        raise typer.Exit(EXIT_ROW_ERRORS)


# Options shared by both commands.
_PROFILE_OPT = typer.Option("--profile", "-p",
                           help="Set-up: built-in name (flowtwin profiles list) or .toml.")
_OUT_OPT = typer.Option("--out", "-o", help="Results table (.parquet or .csv).")
_REPORTS_OPT = typer.Option("--reports", help="Also write each row's full report (JSON) "
                                             "into this folder.")
_ENGINE_OPT = typer.Option("--engine", help="Model per row: " + ", ".join(ENGINES) + ".")
_SCHEDULER_OPT = typer.Option("--scheduler", help="Use a running dask cluster "
                                                 "(tcp://HOST:PORT).")
_WORKERS_OPT = typer.Option("--workers", "-w", help="Worker processes of the local "
                                                   "cluster (default: one per CPU).")
_RETRIES_OPT = typer.Option("--retries", help="Extra attempts of a task that raised.")
_RESUME_OPT = typer.Option("--resume", help="Keep the rows already in --out (same "
                                           "profile and engine) and add the missing ones.")
_SHIP_OPT = typer.Option("--ship-files", help="Send the G-code bytes to the workers "
                                             "(workers without this file system).")
_FLUSH_ROWS_OPT = typer.Option("--flush-rows", help="Write a part file every N rows.")
_FLUSH_S_OPT = typer.Option("--flush-seconds", help="… or once a row has waited this "
                                                   "long, s.")
_PROGRESS_OPT = typer.Option("--progress/--no-progress", help="Progress bar on stderr.")
_JSON_OPT = typer.Option("--json", help="Print one JSON object.")


def register(app: typer.Typer) -> None:
    """Add ``flowtwin batch`` and ``flowtwin sweep``."""

    @app.command("batch")
    def batch_cmd(
        files: Annotated[list[str], typer.Argument(help="G-code files, folders, glob "
                                                        "patterns.")],
        profile: Annotated[str, _PROFILE_OPT] = DEFAULT_SETUP,
        out: Annotated[Path, _OUT_OPT] = Path("results.parquet"),
        reports: Annotated[Path | None, _REPORTS_OPT] = None,
        engine: Annotated[str, _ENGINE_OPT] = DEFAULT_ENGINE,
        scheduler: Annotated[str | None, _SCHEDULER_OPT] = None,
        workers: Annotated[int | None, _WORKERS_OPT] = None,
        retries: Annotated[int, _RETRIES_OPT] = DEFAULT_RETRIES,
        resume: Annotated[bool, _RESUME_OPT] = False,
        ship_files: Annotated[bool, _SHIP_OPT] = False,
        flush_rows: Annotated[int, _FLUSH_ROWS_OPT] = 256,
        flush_seconds: Annotated[float, _FLUSH_S_OPT] = 1.0,
        progress: Annotated[bool, _PROGRESS_OPT] = True,
        json_out: Annotated[bool, _JSON_OPT] = False,
    ) -> None:
        """Simulate many G-code files on one machine: one table row per file."""
        from flowtwin.batch import run_batch

        chosen = _engine(engine)
        _run("batch", out, progress, json_out, lambda start, update: run_batch(
            files, out=out, profile=profile, engine=chosen, reports_dir=reports,
            scheduler=scheduler, workers=workers, retries=retries, resume=resume,
            ship_files=ship_files, flush_rows=flush_rows, flush_s=flush_seconds,
            on_start=start, on_result=update))

    @app.command("sweep")
    def sweep_cmd(
        gcode: Annotated[Path, typer.Argument(help="G-code file.")],
        param: Annotated[list[str], typer.Option(
            "--param", "-P", help="PATH=VALUES: START:STOP:STEP (inclusive), A,B,C, or "
                                  "LOW:HIGH with --sample; e.g. setup.temperature_c=190:230:5, "
                                  "drive.pinch_force_n=60,80,100 (see docs/batch.md).")],
        sample: Annotated[int | None, typer.Option(
            "--sample", help="Draw N random points instead of the full grid.")] = None,
        seed: Annotated[int, typer.Option("--seed", help="Seed of --sample.")] = 0,
        profile: Annotated[str, _PROFILE_OPT] = DEFAULT_SETUP,
        out: Annotated[Path, _OUT_OPT] = Path("sweep.parquet"),
        reports: Annotated[Path | None, _REPORTS_OPT] = None,
        engine: Annotated[str, _ENGINE_OPT] = DEFAULT_ENGINE,
        scheduler: Annotated[str | None, _SCHEDULER_OPT] = None,
        workers: Annotated[int | None, _WORKERS_OPT] = None,
        retries: Annotated[int, _RETRIES_OPT] = DEFAULT_RETRIES,
        resume: Annotated[bool, _RESUME_OPT] = False,
        ship_files: Annotated[bool, _SHIP_OPT] = False,
        flush_rows: Annotated[int, _FLUSH_ROWS_OPT] = 256,
        flush_seconds: Annotated[float, _FLUSH_S_OPT] = 1.0,
        progress: Annotated[bool, _PROGRESS_OPT] = True,
        json_out: Annotated[bool, _JSON_OPT] = False,
    ) -> None:
        """Simulate one G-code over a grid (or random sample) of profile parameters."""
        from flowtwin.batch import run_sweep

        chosen = _engine(engine)
        _run("sweep", out, progress, json_out, lambda start, update: run_sweep(
            gcode, param, out=out, profile=profile, sample=sample, seed=seed, engine=chosen,
            reports_dir=reports, scheduler=scheduler, workers=workers, retries=retries,
            resume=resume, ship_files=ship_files, flush_rows=flush_rows,
            flush_s=flush_seconds, on_start=start, on_result=update), params=param)
