"""What Klipper's extruder corner velocity costs a compensated file (corner.py)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from flowtwin.cli.compensate import register
from flowtwin.compensation import compensate
from flowtwin.compensation.corner import CORNER_REPORT_SHARE, corner_velocity_cost
from flowtwin.planner.plan_file import plan_gcode

from .test_relief_along import CUP, _combing

SETUP = CUP / "klipper-volcano.toml"


def _cfg(tmp_path: Path, corner_mm_s: float) -> Path:
    """The cup's printer.cfg with the extruder's corner velocity set (Klipper's default
    is 1 mm/s, which the cup's file leaves)."""
    text = (CUP / "printer.cfg").read_text()
    assert "instantaneous_corner_velocity" not in text
    out = tmp_path / f"icv{corner_mm_s:g}.cfg"
    out.write_text(re.sub(r"^\[extruder\]\s*$",
                          f"[extruder]\ninstantaneous_corner_velocity: {corner_mm_s:g}",
                          text, count=1, flags=re.M))
    return out


def test_the_times_are_the_written_file_planned_with_that_corner_velocity(
        tmp_path: Path) -> None:
    src = _combing(tmp_path / "comb.gcode")
    out = tmp_path / "out.gcode"
    report = compensate(src, out, machine=SETUP, klipper_config=CUP / "printer.cfg",
                        advance=True)
    cost = report.corner_velocity
    assert cost is not None and cost.corner_velocity_mm_s == 1.0
    assert report.time_after_s > (1 + CORNER_REPORT_SHARE) * report.time_before_s
    # each time is Klipper's plan of the written text with a printer.cfg that says so
    for v, t in cost.times_s:
        planned = plan_gcode(out, klipper_config=_cfg(tmp_path, v))
        assert t == pytest.approx(planned.timeline.total_time_s, rel=1e-12)
    times = [t for _v, t in cost.times_s]
    assert times == sorted(times, reverse=True) and times[0] < report.time_after_s
    # tried up to the first that brings the increase within the share (or the last)
    limit = (1 + CORNER_REPORT_SHARE) * report.time_before_s
    assert all(t > limit for t in times[:-1])
    # the note names the setting and every figure
    note = cost.note()
    assert "instantaneous_corner_velocity 1 mm/s" in note
    for v, t in cost.times_s:
        assert f"{100 * (t / report.time_before_s - 1):+.1f} % with {v:g} mm/s" in note


def test_nothing_is_reported_on_marlin_or_where_the_advance_is_cheap(tmp_path: Path) -> None:
    src = _combing(tmp_path / "comb.gcode")
    fast = compensate(src, tmp_path / "fast.gcode", machine=SETUP,
                      klipper_config=_cfg(tmp_path, 10.0), advance=True)
    assert fast.time_after_s <= (1 + CORNER_REPORT_SHARE) * fast.time_before_s
    assert fast.corner_velocity is None
    marlin = compensate(src, tmp_path / "marlin.gcode", advance=True)
    assert marlin.corner_velocity is None
    # without the advance there is nothing of the advance's to report
    slow = compensate(src, tmp_path / "slow.gcode", machine=SETUP,
                      klipper_config=CUP / "printer.cfg", slip=True)
    assert slow.corner_velocity is None
    # a Marlin plan has no such setting, however slow the file
    assert marlin.compensated_result is not None
    plan = marlin.compensated_result.plan
    assert plan.timeline.firmware == "marlin"
    assert corner_velocity_cost(plan, 0.5 * plan.timeline.total_time_s) is None


def test_the_cli_prints_the_note_and_the_json_key(tmp_path: Path) -> None:
    src = _combing(tmp_path / "comb.gcode")
    application = typer.Typer(pretty_exceptions_enable=False)
    register(application)
    args = ["compensate", str(src), "-o", str(tmp_path / "o.gcode"), "--profile", str(SETUP),
            "--klipper-config", str(CUP / "printer.cfg"), "--advance"]
    res = CliRunner().invoke(application, args)
    assert res.exit_code == 0, res.output
    assert "instantaneous_corner_velocity 1 mm/s in [extruder]" in " ".join(res.stdout.split())
    res = CliRunner().invoke(application, [*args, "--json"])
    assert res.exit_code == 0, res.output
    key = json.loads(res.stdout)["extruder_corner_velocity"]
    assert key["instantaneous_corner_velocity_mm_s"] == 1.0
    assert set(key["time_at_corner_velocity_s"]) <= {"2", "3", "5", "10"}
