"""``flowtwin simulate``: predict what a G-code really extrudes on a machine."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.markup import escape

from flowtwin.atomic import atomic_write_text
from flowtwin.cli._common import console, err_console, fmt_duration, print_json, table_from_rows
from flowtwin.defaults import DEFAULT_MACHINE
from flowtwin.errors import FlowtwinError

if TYPE_CHECKING:
    from flowtwin.report.spots import Spot
    from flowtwin.report.verdict import Verdict
    from flowtwin.simulation import SimulationResult, SimulationSummary, StreamResult

__all__ = ["FIT_MAX_MOVES", "register", "render_simulation", "run_simulation"]

_STAGES = ["read and plan", "physics", "integrate", "deposit", "fit pressure advance",
           "report"]
#: Fit the firmware's pressure advance for the advice up to this many moves (the fit
#: simulates the file ~15 times: ~4 s for a 112 k-move Benchy, measured under load).
FIT_MAX_MOVES = 300_000


def run_simulation(gcode: str, *, machine: str, klipper_config: Path | None,
                   out_dir: Path | None, series: Path | None, pressure_advance: bool,
                   slicer_limits: bool, show_progress: bool, fit: bool = True,
                   series_dt_s: float = 0.01) -> tuple[SimulationResult, Verdict]:
    """Simulate with a progress bar, build the verdict and write the requested outputs.

    ``fit``: fit the firmware's pressure advance for the advice (files up to
    :data:`FIT_MAX_MOVES` moves). ``series_dt_s``: the interval of ``series``.
    """
    import json

    from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    from flowtwin.profiles.machine import load_machine
    from flowtwin.report.verdict import build_verdict
    from flowtwin.simulation import simulate

    with Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
                  TextColumn("{task.completed}/{task.total}"), TimeElapsedColumn(),
                  console=err_console, disable=not show_progress, transient=True) as bar:
        task = bar.add_task("simulating", total=len(_STAGES))

        def stage(name: str) -> None:
            done = _STAGES.index(name) if name in _STAGES else 0
            bar.update(task, description=name, completed=done)

        setup = load_machine(machine)  # once, for the simulation and the fit
        result = simulate(gcode, machine=setup, klipper_config=klipper_config,
                          pressure_advance=pressure_advance,
                          series_dt_s=series_dt_s if series else None,
                          use_slicer_limits=slicer_limits, progress=stage)
        advance_fit = None
        if fit and len(result.plan.table) <= FIT_MAX_MOVES and gcode != "-":
            stage("fit pressure advance")
            from flowtwin.calibration.tuning.advance_settings import best_pressure_advance

            try:
                advance_fit = best_pressure_advance(gcode, machine=setup,
                                                    klipper_config=klipper_config)
            except FlowtwinError as exc:
                result.warnings.append(f"no pressure advance fit: {exc}")
        verdict = build_verdict(result, fit=advance_fit)
        stage("report")
        if out_dir is not None:
            from flowtwin.report import write_report  # plotting: only for a report

            out_dir.mkdir(parents=True, exist_ok=True)
            write_report(result, out_dir / "report.html", verdict=verdict)
            body = {"summary": result.summary().as_dict(), "verdict": verdict.as_dict(),
                    "per_layer": result.per_layer(), "per_feature": result.per_feature(),
                    "worst_by_force": result.worst_moves("force")}
            atomic_write_text(out_dir / "summary.json",
                              json.dumps(body, indent=2, default=_json_default) + "\n")
        if series is not None:
            result.write_series(series)
        bar.update(task, completed=len(_STAGES))
    return result, verdict


class _quiet:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *args: object) -> None:
        return None


def _json_default(value: object) -> object:
    if isinstance(value, float):
        return None
    return str(value)


def _spot_rows(spots: tuple[Spot, ...]) -> list[tuple[object, ...]]:
    return [(f"{s.line_first}" if s.line_first == s.line_last else
             f"{s.line_first}–{s.line_last}", s.layer, s.feature or "-",
             f"{100 * s.error:+.1f} %", f"{s.excess_mm3:+.4f}",
             f"{s.width_nominal_mm:.2f}→{s.width_predicted_mm:.2f}",
             "restart" if s.after_retraction else "") for s in spots]


def _large(gcode: Path, profile: str, klipper_config: Path | None) -> bool:
    """Whether the file is large enough to simulate streamed (the plan's rule)."""
    from flowtwin.planner.plan_stream import is_large, should_stream
    from flowtwin.profiles.machine import load_machine

    if not is_large(str(gcode)):
        return False
    return should_stream(str(gcode), klipper_config=klipper_config,
                         printer=None if klipper_config else load_machine(profile).printer)


def render_simulation(result: SimulationResult | StreamResult,
                      verdict: Verdict | None = None) -> None:
    """Print the verdict, the figures and the worst places with rich (a streamed result:
    the figures and the worst moves; its verdict needs the whole tables)."""
    from flowtwin.simulation import SimulationResult

    if not isinstance(result, SimulationResult):
        _render_streamed(result)
        return
    from flowtwin.report.verdict import build_verdict

    v = verdict if verdict is not None else build_verdict(result)
    s = result.summary()
    console.print(f"[bold]{escape(v.headline)}[/]")
    for line in v.sentences()[1:]:
        console.print(f"  {escape(line)}")
    console.print("[bold]What to do[/]")
    for k, a in enumerate(v.advice, 1):
        console.print(f"  {k}. {escape(a.text)}")
        if a.command:
            console.print(f"     [cyan]{escape(a.command)}[/]")
    rows = _figure_rows(s, (f"worst over- / under-extrusion over {v.window_mm:g} mm",
                            f"{_pct(v.over.error if v.over else 0.0)} / "
                            f"{_pct(v.under.error if v.under else 0.0)}"))
    console.print(table_from_rows("Simulation", ["", ""], rows))
    cols = ["lines", "layer", "feature", "flow", "mm³", "bead mm", ""]
    console.print(table_from_rows(
        f"Worst over-extrusion over {v.window_mm:g} mm of path", cols,
        _spot_rows(v.worst_over[:8])))
    console.print(table_from_rows(
        f"Worst under-extrusion over {v.window_mm:g} mm of path", cols,
        _spot_rows(v.worst_under[:8])))
    for w in s.warnings:
        err_console.print(f"[yellow]warning:[/] {escape(w)}", markup=True)


def _pct(x: float | None) -> str:
    return f"{100 * x:+.2f} %" if x is not None else "-"


def _figure_rows(s: SimulationSummary, peaks: tuple[str, str]) -> list[tuple[str, object]]:
    """The whole-print figures as rows of the console table (``peaks``: the row of the
    worst over- and under-extrusion)."""
    return [
        ("file", s.file), ("machine", f"{s.machine} ({s.printer}, {s.firmware})"),
        ("pressure advance", s.pressure_advance),
        ("print time", fmt_duration(s.total_time_s)),
        ("commanded / delivered melt",
         f"{s.commanded_volume_mm3:.1f} / {s.delivered_volume_mm3:.1f} mm³"),
        ("volume error", _pct(s.volume_error)),
        ("RMS flow error per move (beads)", f"{100 * s.rms_flow_error:.2f} %"),
        peaks,
        ("mean slip", f"{100 * s.mean_slip:.2f} %"),
        ("max feed force / min margin",
         f"{s.max_feed_force_n:.2f} N / "
         + (f"{s.min_force_margin_n:.2f} N" if s.min_force_margin_n is not None else "-")),
        ("grinding events", s.grinding_events),
        ("ooze (travels and stops)", f"{s.ooze_volume_mm3:.2f} mm³"),
    ]


def _render_streamed(result: StreamResult) -> None:
    s = result.aggregates.summary()
    rows = _figure_rows(s, ("peak over- / under-extrusion per move",
                            f"{_pct(s.peak_overextrusion)} / {_pct(-s.peak_underextrusion)}"))
    console.print(table_from_rows("Simulation (streamed: no verdict, run with --no-stream "
                                  "for it)", ["", ""], rows))
    console.print(table_from_rows(
        "Worst moves by width error", ["line", "layer", "nominal (mm)", "predicted (mm)",
                                       "flow error"],
        [(w["line"], w["layer"], f"{w['width_nominal_mm']:.3f}", f"{w['width_mean_mm']:.3f}",
          f"{100 * w['flow_error']:+.1f} %") for w in result.worst_moves("width", 8)]))
    console.print(table_from_rows(
        "Smallest margins to grinding", ["line", "layer", "peak force (N)", "margin (N)"],
        [(w["line"], w["layer"], f"{w['peak_force_n']:.2f}", f"{w['force_margin_n']:.2f}")
         for w in result.worst_moves("force", 5)]))
    for w in s.warnings:
        err_console.print(f"[yellow]warning:[/] {escape(w)}", markup=True)


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
        no_fit: Annotated[bool, typer.Option(
            "--no-fit", help="Do not fit the firmware's pressure advance for the advice "
            f"(it is fitted on files up to {FIT_MAX_MOVES:,} moves).")] = False,
        series_dt: Annotated[float, typer.Option(
            "--series-dt", help="Sample interval of --series, s.")] = 0.01,
        stream: Annotated[bool | None, typer.Option(
            "--stream/--no-stream", help="Bounded memory: whole-print, per-layer and "
            "per-feature figures and the worst moves; no verdict, report or series "
            "(default: for files over 32 MB without --out, --series, --slicer-limits).")
        ] = None,
        json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    ) -> None:
        """Predict what a G-code really extrudes: flow, bead width, slip, force, grinding."""
        if not (series_dt > 0.0 and series_dt < float("inf")):
            raise FlowtwinError("the series sample interval must be positive",
                                field="--series-dt", value=series_dt, allowed="> 0 s")
        asked = stream
        if stream is None:
            stream = (out is None and series is None and not slicer_limits
                      and _large(gcode, profile, klipper_config))
        if stream:
            if out is not None or series is not None:
                raise FlowtwinError("--stream gives whole-print figures only",
                                    field="--stream", allowed="without --out and --series")
            from flowtwin.simulation import simulate_stream

            with console.status("simulating (streaming)…") if not json_out else _quiet():
                streamed = simulate_stream(str(gcode), machine=profile,
                                           klipper_config=klipper_config,
                                           pressure_advance=not no_pa)
            if json_out:
                # chosen by size: the figures of the whole-table object; asked for: with
                # the stream's own counts
                figures = streamed.summary() if asked else streamed.aggregates.summary()
                print_json(figures.as_dict())
            else:
                render_simulation(streamed)
            return
        result, verdict = run_simulation(str(gcode), machine=profile,
                                         klipper_config=klipper_config, out_dir=out,
                                         series=series, pressure_advance=not no_pa,
                                         slicer_limits=slicer_limits,
                                         show_progress=not json_out, fit=not no_fit,
                                         series_dt_s=series_dt)
        if json_out:
            print_json({**result.summary().as_dict(), "verdict": verdict.as_dict()})
            return
        render_simulation(result, verdict)
        if out is not None:
            console.print(f"wrote {out / 'report.html'} and {out / 'summary.json'}")
