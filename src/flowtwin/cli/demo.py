"""``flowtwin demo``: the main job on the built-in example print."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import typer

from flowtwin.atomic import atomic_write_text
from flowtwin.cli._common import console, print_json
from flowtwin.cli.plan import render_plan
from flowtwin.cli.simulate import render_simulation, run_simulation
from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.planning import plan_gcode
from flowtwin.simulation import DEFAULT_MACHINE, SimulationSummary

__all__ = ["DemoOutcome", "register", "run_demo"]


@dataclass(frozen=True, slots=True)
class DemoOutcome:
    """What ``flowtwin demo`` made.

    Attributes
    ----------
    plan
        The plan's ``--json`` object (its summary with the per-layer rows).
    simulation
        The simulation's whole-print figures.
    outputs
        File name → path of every file written.
    """

    plan: dict[str, object]
    simulation: SimulationSummary
    outputs: dict[str, str]

    def as_dict(self) -> dict[str, object]:
        """The ``demo --json`` object."""
        return {"plan": self.plan, "simulation": self.simulation.as_dict(),
                "outputs": dict(self.outputs)}


def run_demo(out_dir: Path, *, machine: str = DEFAULT_MACHINE, show_progress: bool = False
             ) -> DemoOutcome:
    """Generate the built-in print into ``out_dir``, plan and simulate it, write the report.

    Writes ``demo.gcode``, ``plan.json``, ``summary.json`` and ``report.html``; returns the
    plan and simulation summaries with the written paths.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    gcode = out_dir / "demo.gcode"
    write_print(gcode, PrintSpec())
    from flowtwin.profiles import load_machine

    plan = plan_gcode(gcode, printer=load_machine(machine).printer)
    plan_summary = plan.summary().as_dict()
    plan_summary["per_layer"] = plan.per_layer()
    atomic_write_text(out_dir / "plan.json",
                      json.dumps(plan_summary, indent=2, allow_nan=False, default=str) + "\n")
    sim = run_simulation(str(gcode), machine=machine, klipper_config=None, out_dir=out_dir,
                         series=None, pressure_advance=True, slicer_limits=False,
                         show_progress=show_progress)
    return DemoOutcome(plan_summary, sim.summary(),
                       {name: str(out_dir / name) for name in
                        ("demo.gcode", "plan.json", "summary.json", "report.html")})


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
        summary = run_demo(out, machine=profile, show_progress=not json_out)
        if json_out:
            print_json(summary.as_dict())
            return
        from flowtwin.profiles import load_machine

        render_plan(plan_gcode(out / "demo.gcode", printer=load_machine(profile).printer))
        from flowtwin.simulation import simulate

        render_simulation(simulate(out / "demo.gcode", machine=profile))
        console.print("\nwrote " + ", ".join(summary.outputs.values()))
