"""``flowtwin demo``: the main job on the built-in example print."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from flowtwin.atomic import atomic_write_text
from flowtwin.cli._common import console, print_json
from flowtwin.cli.plan import render_plan
from flowtwin.cli.simulate import render_simulation, run_simulation
from flowtwin.defaults import DEFAULT_MACHINE

if TYPE_CHECKING:
    from flowtwin.report.verdict import Verdict
    from flowtwin.simulation import SimulationResult

__all__ = ["register", "run_demo"]


def run_demo(out_dir: Path, *, machine: str = DEFAULT_MACHINE, show_progress: bool = False
             ) -> dict[str, object]:
    """Generate the built-in print into ``out_dir``, plan and simulate it, write the report.

    Writes ``demo.gcode``, ``plan.json``, ``summary.json`` and ``report.html``; returns the
    plan and simulation summaries, the verdict and the written paths.
    """
    return _demo(out_dir, machine=machine, show_progress=show_progress)[0]


def _demo(out_dir: Path, *, machine: str, show_progress: bool
          ) -> tuple[dict[str, object], SimulationResult, Verdict]:
    from flowtwin.gcode.generator import PrintSpec, write_print
    from flowtwin.planner.plan_file import plan_gcode
    from flowtwin.profiles import load_machine

    out_dir.mkdir(parents=True, exist_ok=True)
    gcode = out_dir / "demo.gcode"
    write_print(gcode, PrintSpec())
    plan = plan_gcode(gcode, printer=load_machine(machine).printer)
    plan_summary = plan.summary()
    plan_summary["per_layer"] = plan.per_layer()
    atomic_write_text(out_dir / "plan.json",
                      json.dumps(plan_summary, indent=2, allow_nan=False, default=str) + "\n")
    sim, verdict = run_simulation(str(gcode), machine=machine, klipper_config=None,
                                  out_dir=out_dir, series=None, pressure_advance=True,
                                  slicer_limits=False, show_progress=show_progress)
    return ({"plan": plan_summary, "simulation": sim.summary(), "verdict": verdict.as_dict(),
             "outputs": {name: str(out_dir / name) for name in
                         ("demo.gcode", "plan.json", "summary.json", "report.html")}},
            sim, verdict)


def register(app: typer.Typer) -> None:
    """Add ``flowtwin demo``."""

    @app.command("demo")
    def demo_cmd(
        out: Annotated[Path, typer.Option("--out", "-o", help="Folder for the outputs.")
                       ] = Path("demo-out"),
        profile: Annotated[str, typer.Option("--profile", "-p", help="Machine set-up.")
                           ] = DEFAULT_MACHINE,
        json_out: Annotated[bool, typer.Option("--json", help="Print one JSON object.")] = False,
    ) -> None:
        """Generate the built-in example print, plan and simulate it, write report.html."""
        summary, sim, verdict = _demo(out, machine=profile, show_progress=not json_out)
        if json_out:
            print_json(summary)
            return
        from flowtwin.planner.plan_file import plan_gcode
        from flowtwin.profiles import load_machine

        render_plan(plan_gcode(out / "demo.gcode", printer=load_machine(profile).printer))
        render_simulation(sim, verdict)
        console.print("\nwrote " + ", ".join(str(v) for v in summary["outputs"].values()))  # type: ignore[attr-defined]
