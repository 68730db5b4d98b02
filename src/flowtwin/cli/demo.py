"""``flowtwin demo``: the main job on the built-in example print."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from flowtwin.atomic import atomic_write_text
from flowtwin.cli._common import console, print_json
from flowtwin.cli.plan import render_plan
from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.planning import DEFAULT_PRINTER, plan_gcode

__all__ = ["register", "run_demo"]


def run_demo(out_dir: Path, *, printer: str = DEFAULT_PRINTER) -> dict[str, object]:
    """Generate the built-in print into ``out_dir``, plan it, write ``plan.json``.

    Returns the plan summary (with the per-layer table and the written paths).
    """
    import json

    out_dir.mkdir(parents=True, exist_ok=True)
    gcode = out_dir / "demo.gcode"
    write_print(gcode, PrintSpec())
    result = plan_gcode(gcode, printer=printer)
    summary = result.summary()
    summary["per_layer"] = result.per_layer()
    summary["outputs"] = {"gcode": str(gcode), "plan": str(out_dir / "plan.json")}
    atomic_write_text(out_dir / "plan.json", json.dumps(summary, indent=2, allow_nan=False,
                                                        default=str) + "\n")
    return summary


def register(app: typer.Typer) -> None:
    """Add ``flowtwin demo``."""

    @app.command("demo")
    def demo_cmd(
        out: Annotated[Path, typer.Option("--out", "-o", help="Folder for the outputs.")
                       ] = Path("demo-out"),
        profile: Annotated[str, typer.Option("--profile", "-p", help="Printer profile.")
                           ] = DEFAULT_PRINTER,
        json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    ) -> None:
        """Generate the built-in example print, plan it and write a report to OUT."""
        summary = run_demo(out, printer=profile)
        if json_out:
            print_json(summary)
            return
        result = plan_gcode(out / "demo.gcode", printer=profile)
        render_plan(result)
        console.print(f"\nwrote {out / 'demo.gcode'} and {out / 'plan.json'}")
