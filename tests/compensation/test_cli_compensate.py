"""``flowtwin compensate`` / ``flowtwin tune`` through their own typer app."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from flowtwin.cli.compensate import register
from flowtwin.errors import ProfileError

runner = CliRunner()


def app() -> typer.Typer:
    application = typer.Typer(pretty_exceptions_enable=False)
    register(application)
    return application


def test_no_flag_changes_nothing(example: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.gcode"
    res = runner.invoke(app(), ["compensate", str(example), "-o", str(out), "--json"])
    assert res.exit_code == 0, res.output
    s = json.loads(res.stdout)
    assert out.read_bytes() == example.read_bytes()
    assert s["transformations"] == [] and s["slowed_moves"] == 0
    assert s["rms_flow_error_after"] == s["rms_flow_error_before"]


def test_json_keys_and_figures(example: Path, tmp_path: Path) -> None:
    out = tmp_path / "out.gcode"
    res = runner.invoke(app(), ["compensate", str(example), "-o", str(out), "--advance",
                                "--slip", "--guard", "--json"])
    assert res.exit_code == 0, res.output
    s = json.loads(res.stdout)
    for key in ("rms_flow_error_before", "rms_flow_error_after", "peak_overextrusion_before",
                "peak_overextrusion_after", "added_volume_mm3", "slowed_moves"):
        assert key in s
    assert s["transformations"] == ["guard", "advance", "slip"]
    assert s["rms_flow_error_after"] * 5 <= s["rms_flow_error_before"]
    assert s["added_volume_mm3"] > 0


def test_pace_flag_reports_its_moves_and_time(thin_gcode: Path, tmp_path: Path) -> None:
    src = thin_gcode
    out = tmp_path / "out.gcode"
    # no time budget: pacing every spot here costs ~+25 % (the default 10 % paces none)
    res = runner.invoke(app(), ["compensate", str(src), "-o", str(out), "--pace",
                                "--pace-budget", "inf", "--json"])
    assert res.exit_code == 0, res.output
    s = json.loads(res.stdout)
    assert s["transformations"] == ["pace"]
    assert s["paced_moves"] > 0 and s["pace_time_cost_s"] > 0
    # only the pacing ran: the result's print time is the original's plus its cost
    assert s["time_after_s"] == pytest.approx(s["time_before_s"] + s["pace_time_cost_s"],
                                              rel=1e-12)
    res = runner.invoke(app(), ["compensate", str(src), "-o", str(out), "--pace",
                                "--pace-max-slowdown", "0"])
    assert isinstance(res.exception, ProfileError) and "max_slowdown" in str(res.exception)


def test_table_output_prints_before_and_after(example: Path, tmp_path: Path) -> None:
    res = runner.invoke(app(), ["compensate", str(example), "-o", str(tmp_path / "o.gcode"),
                                "--advance", "--law", "discrete", "--no-refine"])
    assert res.exit_code == 0, res.output
    assert "before" in res.stdout and "after" in res.stdout and "RMS flow error" in res.stdout


def test_tune_json_and_table_file(tmp_path: Path) -> None:
    table = tmp_path / "pa.txt"
    res = runner.invoke(app(), ["tune", "--json", "--table-out", str(table), "--flows", "3,9",
                                "--accels", "1000,4000"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["best"]["command"].startswith("M900 K")
    rows = table.read_text().splitlines()
    assert len(rows) == 4 and all(len(r.split(",")) == 3 for r in rows)


def test_relief_min_lags_relieves_shorter_travels(example: Path, tmp_path: Path) -> None:
    def relieved(*extra: str) -> int:
        res = runner.invoke(app(), ["compensate", str(example), "-o",
                                    str(tmp_path / "out.gcode"), "--advance", "--json",
                                    *extra])
        assert res.exit_code == 0, res.output
        return int(json.loads(res.stdout)["advance"][0]["relief_travels"])

    # the example's printer is Marlin's: a quarter of K by default (half on Klipper)
    half, default = relieved("--relief-min-lags", "0.5"), relieved()
    assert half > 0 and default > half
    assert relieved("--relief-min-lags", "0.25") == default
    res = runner.invoke(app(), ["compensate", str(example), "-o", str(tmp_path / "o.gcode"),
                                "--advance", "--relief-min-lags", "-1"])
    assert res.exit_code != 0
    assert "relief_min_lags" in str(res.exception) and "0 .. 100" in str(res.exception)


def test_bad_input_exits_with_the_error(tmp_path: Path) -> None:
    bad = tmp_path / "bad.gcode"
    bad.write_text("G1 X1 E0.1 F600\nG20\n")
    res = runner.invoke(app(), ["compensate", str(bad), "-o", str(tmp_path / "o.gcode"),
                                "--advance"])
    assert res.exit_code != 0
    assert "inch" in str(res.exception) and ":2" in str(res.exception)
    assert not (tmp_path / "o.gcode").exists()
