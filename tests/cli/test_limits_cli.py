"""``flowtwin limits``: JSON key, table, swapped parts, clear errors."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from flowtwin.cli.main import app
from flowtwin.profiles import load_machine
from flowtwin.simulation.limits import flow_limit

RUNNER = CliRunner()


def test_limits_json_matches_the_api() -> None:
    res = RUNNER.invoke(app, ["limits", "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    expected = flow_limit(load_machine("tronvoll2019")).max_volumetric_flow_mm3_s
    assert data["max_volumetric_flow_mm3_s"] == expected
    assert data["reason"] == "slip"
    temps = [row["temperature_c"] for row in data["table"]]
    assert temps[0] == 190.0 and temps[-1] == 230.0
    assert [r["max_volumetric_flow_mm3_s"] for r in data["table"]] == sorted(
        r["max_volumetric_flow_mm3_s"] for r in data["table"])


def test_limits_with_a_longer_melt_zone_and_text_output() -> None:
    res = RUNNER.invoke(app, ["limits", "--hotend", "e3d-volcano-0.4", "--json"])
    volcano = json.loads(res.output)
    v6 = json.loads(RUNNER.invoke(app, ["limits", "--json"]).output)
    assert volcano["melt_capacity_mm3_s"] > 1.5 * v6["melt_capacity_mm3_s"]
    text = RUNNER.invoke(app, ["limits", "--material", "petg"])
    assert text.exit_code == 0 and "maximum volumetric flow" in text.output


def test_limits_bad_part_is_a_clear_error() -> None:
    res = RUNNER.invoke(app, ["limits", "--hotend", "nope"])
    assert res.exit_code != 0
