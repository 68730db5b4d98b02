"""``flowtwin demo``: the main job on the built-in example print."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
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
    from flowtwin.simulation import SimulationResult, SimulationSummary

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
    verdict
        What the twin says about the print (:class:`~flowtwin.report.verdict.Verdict`).
    outputs
        File name → path of every file written.
    result
        The simulation itself (for the tables printed on the console).
    """

    plan: dict[str, object]
    simulation: SimulationSummary
    verdict: Verdict
    outputs: dict[str, str]
    result: SimulationResult = field(repr=False, compare=False)

    def as_dict(self) -> dict[str, object]:
        """The ``demo --json`` object."""
        return {"plan": self.plan, "simulation": self.simulation.as_dict(),
                "verdict": self.verdict.as_dict(), "outputs": dict(self.outputs)}


def run_demo(out_dir: Path, *, machine: str = DEFAULT_MACHINE, show_progress: bool = False
             ) -> DemoOutcome:
    """Generate the built-in print into ``out_dir``, plan and simulate it, write the report.

    Writes ``demo.gcode``, ``plan.json``, ``summary.json`` and ``report.html``; returns the
    plan and simulation summaries, the verdict and the written paths.
    """
    from flowtwin.gcode.generator import PrintSpec, write_print
    from flowtwin.planner.plan_file import plan_gcode
    from flowtwin.profiles import load_machine

    out_dir.mkdir(parents=True, exist_ok=True)
    gcode = out_dir / "demo.gcode"
    write_print(gcode, PrintSpec())
    plan = plan_gcode(gcode, printer=load_machine(machine).printer)
    plan_summary = plan.summary().as_dict()
    plan_summary["per_layer"] = plan.per_layer()
    atomic_write_text(out_dir / "plan.json",
                      json.dumps(plan_summary, indent=2, allow_nan=False, default=str) + "\n")
    sim, verdict = run_simulation(str(gcode), machine=machine, klipper_config=None,
                                  out_dir=out_dir, series=None, pressure_advance=True,
                                  slicer_limits=False, show_progress=show_progress)
    return DemoOutcome(plan_summary, sim.summary(), verdict,
                       {name: str(out_dir / name) for name in
                        ("demo.gcode", "plan.json", "summary.json", "report.html")}, sim)


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
        outcome = run_demo(out, machine=profile, show_progress=not json_out)
        if json_out:
            print_json(outcome.as_dict())
            return
        from flowtwin.planner.plan_file import plan_gcode
        from flowtwin.profiles import load_machine

        render_plan(plan_gcode(out / "demo.gcode", printer=load_machine(profile).printer))
        render_simulation(outcome.result, outcome.verdict)
        console.print("\nwrote " + ", ".join(outcome.outputs.values()))
