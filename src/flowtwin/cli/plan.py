"""``flowtwin plan``: read a G-code file and plan it as the firmware would."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from flowtwin.cli._common import console, err_console, fmt_duration, print_json, table_from_rows
from flowtwin.defaults import DEFAULT_PRINTER

if TYPE_CHECKING:
    from flowtwin.planner.plan_file import PlanResult
    from flowtwin.planner.plan_stream import PlanStream

__all__ = ["register", "render_plan"]


def render_plan(result: PlanResult | PlanStream, *, layers: bool = True,
                max_layer_rows: int = 40) -> None:
    """Print a plan's summary (and per-layer table) with rich (a streamed plan: after it
    ran)."""
    s = result.summary()
    rows: list[tuple[str, str]] = [
        ("file", s.file), ("printer", f"{s.printer} ({s.firmware})"),
        ("print time", fmt_duration(s.total_time_s)),
        ("net filament (G-code E)", ", ".join(f"T{k}: {v:.2f} mm"
                                               for k, v in s.net_filament_mm.items())),
        ("moves / lines / layers", f"{s.moves:,} / {s.lines:,} / {s.layers:,}"),
    ]
    if s.slicer_time_s:
        rows.append(("slicer's own estimate",
                     f"{fmt_duration(s.slicer_time_s)} ({s.slicer})"))
    unknown = s.unknown_commands
    if unknown:
        rows.append(("unknown commands (ignored)",
                     ", ".join(f"{k}×{v}" for k, v in list(unknown.items())[:8])
                     + (" …" if len(unknown) > 8 else "")))
    console.print(table_from_rows("Plan", ["", ""], rows))
    console.print(table_from_rows("Time by feature", ["feature", "time"],
                                  [(k, fmt_duration(v))
                                   for k, v in s.time_by_feature_s.items()]))
    if layers:
        per = result.per_layer()
        half = max_layer_rows // 2
        shown = per if len(per) <= max_layer_rows else per[:half] + per[-half:]
        note = ", first and last shown" if len(shown) < len(per) else ""
        console.print(table_from_rows(
            f"Per layer ({len(per)} layers{note}; -1 = before the first layer)",
            ["layer", "z (mm)", "time", "filament (mm)", "moves"],
            [(r["layer"], f"{r['z_mm']:.3f}", fmt_duration(float(r["time_s"])),
              f"{r['filament_mm']:.2f}", r["moves"]) for r in shown]))
    from flowtwin.planner.plan_file import PlanResult

    warnings = (result.table.warnings + result.timeline.warnings
                if isinstance(result, PlanResult) else result.warnings)
    for w in warnings[:10]:
        err_console.print(f"[yellow]warning:[/] {w}")


def register(app: typer.Typer) -> None:
    """Add ``flowtwin plan``."""

    @app.command("plan")
    def plan_cmd(
        gcode: Annotated[Path, typer.Argument(help="G-code file (plain or .gz; '-' for stdin).")],
        profile: Annotated[str, typer.Option("--profile", "-p",
                                             help="Printer profile: built-in name or TOML file.")
                           ] = DEFAULT_PRINTER,
        klipper_config: Annotated[Path | None, typer.Option(
            "--klipper-config", help="Plan with this Klipper printer.cfg instead.")] = None,
        slicer_limits: Annotated[bool, typer.Option(
            "--slicer-limits", help="Marlin-style firmware: use the machine limits embedded "
            "in the slicer's header.")] = False,
        strict: Annotated[bool, typer.Option("--strict", help="Unknown commands are errors.")
                          ] = False,
        json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
        layers: Annotated[bool, typer.Option("--layers/--no-layers",
                                             help="Show the per-layer table.")] = True,
        stream: Annotated[bool | None, typer.Option(
            "--stream/--no-stream", help="Read and plan in bounded memory (same figures; "
            "default: for files over 32 MB).")] = None,
    ) -> None:
        """Plan a G-code file as Klipper or Marlin would: time, filament, moves, layers."""
        from flowtwin.planner.plan_file import plan_gcode
        from flowtwin.planner.plan_stream import plan_stream, should_stream

        result: PlanResult | PlanStream
        if stream is None:
            stream = should_stream(str(gcode), printer=profile, klipper_config=klipper_config)
        with console.status("reading and planning…", spinner="dots") if not json_out else _null():
            if stream:
                result = plan_stream(str(gcode), printer=profile, klipper_config=klipper_config,
                                     use_slicer_limits=slicer_limits, strict=strict).run()
            else:
                result = plan_gcode(str(gcode), printer=profile, klipper_config=klipper_config,
                                    use_slicer_limits=slicer_limits, strict=strict)
        if json_out:
            out = result.summary().as_dict()
            out["per_layer"] = result.per_layer()
            print_json(out)
        else:
            render_plan(result, layers=layers)


class _null:
    def __enter__(self) -> None:
        return None

    def __exit__(self, *args: object) -> None:
        return None
