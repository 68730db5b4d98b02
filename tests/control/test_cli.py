"""``flowtwin control`` on the twin (accelerated time): JSON summary, CSV log, errors."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from flowtwin.cli import control as control_cli
from flowtwin.control.log import COLUMNS
from flowtwin.errors import FlowtwinError


@pytest.fixture
def app() -> typer.Typer:
    application = typer.Typer()
    control_cli.register(application)

    @application.callback()
    def _root() -> None:
        pass

    return application


def test_json_summary_and_csv_log(app: typer.Typer, tmp_path: Path) -> None:
    log = tmp_path / "run.csv"
    r = CliRunner().invoke(app, ["control", "--printer", "twin?delay=0.5", "--synthetic",
                                 "--duration", "30", "--speedup", "200", "--json",
                                 "--log", str(log), "--seed", "4"])
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    assert s["restored"] is True and s["faults"] == []
    assert s["final_factors"] == {"speed_pct": 100.0, "flow_pct": 100.0, "source": "printer"}
    assert s["samples"] > 10 and s["multiplier_min_pct"] < 95.0
    assert s["multiplier_max_pct"] == 100.0 and s["channel"] == "speed"
    rows = list(csv.DictReader(log.open()))
    assert tuple(rows[0].keys()) == COLUMNS
    events = [row["event"] for row in rows]
    assert events[0] == "start" and events[-3:] == ["restore", "read", "end"]
    assert any(row["gcode"].startswith("M220 S") and row["ack"] == "1" for row in rows)


def test_klipper_twin_flow_channel(app: typer.Typer) -> None:
    r = CliRunner().invoke(app, ["control", "--printer", "twin?firmware=klipper",
                                 "--synthetic", "--duration", "20", "--speedup", "200",
                                 "--controller", "feedforward", "--json"])
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    assert s["channel"] == "flow" and s["multiplier_max_pct"] > 105.0
    assert s["multiplier_max_pct"] != round(s["multiplier_max_pct"])  # Klipper: floats


def test_rich_status_mode_prints_summary(app: typer.Typer) -> None:
    r = CliRunner().invoke(app, ["control", "--printer", "twin", "--synthetic",
                                 "--duration", "5", "--speedup", "100"])
    assert r.exit_code == 0, r.output
    assert "Control run" in r.output and "restored to 100 %" in r.output


@pytest.mark.parametrize(("args", "match"), [
    (["--printer", "twin"], "no measurement source"),
    (["--printer", "twin", "--synthetic", "--duration", "-1"], "duration must be positive"),
    (["--printer", "moonraker://127.0.0.1:9", "--synthetic", "--speedup", "5"],
     "only applies to the twin"),
    (["--printer", "octoprint://127.0.0.1:9", "--synthetic", "--api-key-env", "NOPE_UNSET"],
     "needs an API key"),
    (["--printer", "twin", "--synthetic", "--controller", "magic"], "unknown controller"),
    (["--printer", "twin", "--synthetic", "--min-pct", "120"], "must contain 100"),
])
def test_user_errors(app: typer.Typer, args: list[str], match: str) -> None:
    r = CliRunner().invoke(app, ["control", *args])
    assert isinstance(r.exception, FlowtwinError)
    assert match in str(r.exception)
