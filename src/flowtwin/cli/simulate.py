"""``flowtwin simulate``: predict what a G-code really extrudes on a machine."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

from flowtwin.atomic import atomic_write_text
from flowtwin.cli._common import console, err_console, fmt_duration, print_json, table_from_rows
from flowtwin.errors import FlowtwinError
from flowtwin.simulation import DEFAULT_MACHINE, SimulationResult, simulate

__all__ = ["register", "render_simulation", "run_simulation"]

_STAGES = ["read and plan", "physics", "integrate", "deposit", "report"]


def run_simulation(gcode: str, *, machine: str, klipper_config: Path | None,
                   out_dir: Path | None, series: Path | None, pressure_advance: bool,
                   slicer_limits: bool, show_progress: bool) -> SimulationResult:
    """Simulate with a progress bar and write the requested outputs."""
    import json

    from flowtwin.report import write_report

    with Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
                  TextColumn("{task.completed}/{task.total}"), TimeElapsedColumn(),
                  console=err_console, disable=not show_progress, transient=True) as bar:
        task = bar.add_task("simulating", total=len(_STAGES))

        def stage(name: str) -> None:
            done = _STAGES.index(name) if name in _STAGES else 0
            bar.update(task, description=name, completed=done)

        result = simulate(gcode, machine=machine, klipper_config=klipper_config,
                          pressure_advance=pressure_advance,
                          series_dt_s=0.01 if (series or out_dir) else None,
                          use_slicer_limits=slicer_limits, progress=stage)
        stage("report")
        if out_dir is not None:
            out_dir.mkdir(parents=True, exist_ok=True)
            write_report(result, out_dir / "report.html")
            body = {"summary": result.summary().as_dict(), "per_layer": result.per_layer(),
                    "per_feature": result.per_feature(),
                    "worst_by_width": result.worst_moves("width"),
                    "worst_by_force": result.worst_moves("force")}
            atomic_write_text(out_dir / "summary.json",
                              json.dumps(body, indent=2, default=_json_default) + "\n")
        if series is not None:
            result.write_series(series)
        bar.update(task, completed=len(_STAGES))
    return result


class _quiet:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *args: object) -> None:
        return None


def _json_default(value: object) -> object:
    if isinstance(value, float):
        return None
    return str(value)


def render_simulation(result: SimulationResult) -> None:
    """Print the summary table and the worst moves with rich."""
    s = result.summary()

    def pct(v: float | None) -> str:
        return f"{100 * v:+.2f} %" if v is not None else "-"

    rows = [
        ("file", s.file), ("machine", f"{s.machine} ({s.printer}, {s.firmware})"),
        ("pressure advance", s.pressure_advance),
        ("print time", fmt_duration(s.total_time_s)),
        ("commanded / delivered melt",
         f"{s.commanded_volume_mm3:.1f} / {s.delivered_volume_mm3:.1f} mm³"),
        ("volume error", pct(s.volume_error)),
        ("RMS flow error (beads)", f"{100 * s.rms_flow_error:.2f} %"),
        ("peak over- / under-extrusion",
         f"{pct(s.peak_overextrusion)} / {pct(-s.peak_underextrusion)}"),
        ("worst width error", f"{s.worst_width_error_mm:.3f} mm"),
        ("mean slip", f"{100 * s.mean_slip:.2f} %"),
        ("max feed force / min margin",
         f"{s.max_feed_force_n:.2f} N / "
         + (f"{s.min_force_margin_n:.2f} N" if s.min_force_margin_n is not None else "-")),
        ("grinding events", s.grinding_events),
        ("ooze (travels and stops)", f"{s.ooze_volume_mm3:.2f} mm³"),
    ]
    console.print(table_from_rows("Simulation", ["", ""], rows))
    worst = result.worst_moves("width", 8)
    console.print(table_from_rows(
        "Worst moves by width error", ["line", "layer", "nominal (mm)", "predicted (mm)",
                                       "flow error"],
        [(w["line"], w["layer"], f"{w['width_nominal_mm']:.3f}", f"{w['width_mean_mm']:.3f}",
          f"{100 * w['flow_error']:+.1f} %") for w in worst]))
    force = result.worst_moves("force", 5)
    console.print(table_from_rows(
        "Smallest margins to grinding", ["line", "layer", "peak force (N)", "margin (N)"],
        [(w["line"], w["layer"], f"{w['peak_force_n']:.2f}", f"{w['force_margin_n']:.2f}")
         for w in force]))
    for w in s.warnings:
        err_console.print(f"[yellow]warning:[/] {w}", markup=True)


def register(app: typer.Typer) -> None:
    """Add ``flowtwin simulate``."""

    @app.command("simulate")
    def simulate_cmd(
        gcode: Annotated[Path, typer.Argument(help="G-code file (plain or .gz; '-' for stdin).")],
        profile: Annotated[str, typer.Option(
            "--profile", "-p", help="Machine set-up: built-in name (flowtwin profiles list) "
            "or set-up TOML.")] = DEFAULT_MACHINE,
        klipper_config: Annotated[Path | None, typer.Option(
            "--klipper-config", help="Plan with this Klipper printer.cfg (drive, hot end and "
            "material still from the set-up).")] = None,
        out: Annotated[Path | None, typer.Option(
            "--out", "-o", help="Folder for report.html and summary.json.")] = None,
        series: Annotated[Path | None, typer.Option(
            "--series", help="Write the time series to this .parquet or .csv file.")] = None,
        no_pa: Annotated[bool, typer.Option(
            "--no-pa", help="Predict without the firmware's pressure advance.")] = False,
        slicer_limits: Annotated[bool, typer.Option(
            "--slicer-limits", help="Marlin-style firmware: plan with the slicer's machine "
            "limits.")] = False,
        stream: Annotated[bool, typer.Option(
            "--stream", help="Bounded memory for multi-GB files: whole-print figures only "
            "(no report, series or per-move tables).")] = False,
        json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    ) -> None:
        """Predict what a G-code really extrudes: flow, bead width, slip, force, grinding."""
        if stream:
            if out is not None or series is not None:
                raise FlowtwinError("--stream gives whole-print figures only",
                                    field="--stream", allowed="without --out and --series")
            from flowtwin.simulation import simulate_stream

            with console.status("simulating (streaming)…") if not json_out else _quiet():
                streamed = simulate_stream(str(gcode), machine=profile,
                                           klipper_config=klipper_config,
                                           pressure_advance=not no_pa)
            summary = streamed.summary().as_dict()
            if json_out:
                print_json(summary)
            else:
                console.print(table_from_rows("Simulation (streamed)", ["", ""],
                                              [(k, v) for k, v in summary.items()
                                               if not isinstance(v, dict | list)]))
            return
        result = run_simulation(str(gcode), machine=profile, klipper_config=klipper_config,
                                out_dir=out, series=series, pressure_advance=not no_pa,
                                slicer_limits=slicer_limits, show_progress=not json_out)
        if json_out:
            print_json(result.summary().as_dict())
            return
        render_simulation(result)
        if out is not None:
            console.print(f"wrote {out / 'report.html'} and {out / 'summary.json'}")
