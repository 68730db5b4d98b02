"""The Python API's front door: ``import flowtwin`` is light and names every entry point."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import flowtwin


def test_import_flowtwin_loads_no_numerical_stack() -> None:
    code = ("import sys, flowtwin; print(sorted(m for m in ('numpy', 'numba', 'scipy', 'typer',"
            " 'pydantic', 'rich') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=120).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("name", sorted(set(flowtwin.__all__) - {"__version__"}))
def test_every_entry_point_resolves(name: str) -> None:
    assert getattr(flowtwin, name) is not None
    assert name in dir(flowtwin)


def test_entry_points_are_the_api_functions() -> None:
    from flowtwin.compensation import compensate
    from flowtwin.planner.plan_file import plan_gcode
    from flowtwin.simulation import simulate

    assert flowtwin.plan is plan_gcode
    assert flowtwin.simulate is simulate
    assert flowtwin.compensate is compensate
    with pytest.raises(AttributeError, match="no attribute 'plann'"):
        flowtwin.plann  # noqa: B018


def test_plan_and_simulate_through_the_front_door(tmp_path: Path) -> None:
    path = tmp_path / "p.gcode"
    flowtwin.write_print(path, flowtwin.PrintSpec(layers=2))
    machine = flowtwin.load_machine("tronvoll2019")
    plan = flowtwin.plan(path, printer=machine.printer)
    sim = flowtwin.simulate(path, machine=machine)
    assert plan.summary().total_time_s == sim.summary().total_time_s > 0
