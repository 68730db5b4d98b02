"""``flowtwin teststand simulate|analyse`` through a typer app that registers the group."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from flowtwin.cli import teststand as cli
from flowtwin.errors import ProfileError
from flowtwin.teststand.summary import analyse_file


def _app() -> typer.Typer:
    app = typer.Typer()
    cli.register(app)

    @app.callback()
    def _root() -> None:
        """flowtwin (test)."""

    return app


def test_simulate_then_analyse(tmp_path: Path) -> None:
    runner = CliRunner()
    out = tmp_path / "stand.csv"
    result = runner.invoke(_app(), ["teststand", "simulate", str(out), "--roller", "3",
                                    "--pinch-forces", "20,40,80,100,130", "--speeds",
                                    "0.5,1,2,5,10,15", "--repeats", "1", "--law", "pinch",
                                    "--seed", "4", "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["records"] == 5 * 6 and report["roller_id"] == "3"
    assert out.is_file()
    figs = tmp_path / "figs"
    result = runner.invoke(_app(), ["teststand", "analyse", str(out), "--json",
                                    "--figures", str(figs)])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    (roller,) = summary["rollers"]
    checks = {c["parameter"]: c for c in roller["comparison"]}
    assert checks["k_s"]["pass"] and checks["k_inf"]["pass"]
    assert roller["pinch_law"]["k_s_pct_N"] == pytest.approx(96.0, abs=3.0)
    assert len(summary["figures"]) == 5
    assert all(Path(p).stat().st_size > 10_000 for p in summary["figures"])
    # the human-readable table
    result = runner.invoke(_app(), ["teststand", "analyse", str(out)])
    assert result.exit_code == 0 and "Table 3" in result.stdout


def test_drive_profile_roller_and_errors(tmp_path: Path) -> None:
    roller = cli.resolve_roller(None, "hobb-goblin-80n")
    assert roller.number == 3
    with pytest.raises(ProfileError, match="exactly one"):
        cli.resolve_roller(None, None)
    with pytest.raises(ProfileError, match="unknown roller"):
        cli.resolve_roller(9, None)
    runner = CliRunner()
    result = runner.invoke(_app(), ["teststand", "simulate", str(tmp_path / "x.csv"),
                                    "--roller", "3", "--speeds", "1,a"])
    assert isinstance(result.exception, ProfileError)
    assert "--speeds" in str(result.exception)


def test_analyse_a_file_with_two_rollers(tmp_path: Path) -> None:
    a = tmp_path / "a.csv"
    text = ("roller_id,pinch_force_set_n,nominal_speed_mm_s,repeat,t_s,filament_speed_mm_s,"
            "feed_force_n,pinch_force_n\n")
    for rid in ("custom", "7"):
        for i in range(40):
            text += f"{rid},100,2,0,{0.02 * i:.2f},{2 - 0.002 * i:.4f},{0.08 * i:.3f},100\n"
    a.write_text(text)
    summary = analyse_file(a)
    assert [r["roller_id"] for r in summary["rollers"]] == ["7", "custom"]
    assert "comparison" in summary["rollers"][0] and "comparison" not in summary["rollers"][1]
    # one pinch force: the laws cannot be fitted, and the summary says why
    assert summary["rollers"][1]["pinch_law"] is None
    assert "three or more pinch forces" in summary["rollers"][1]["problems"]["pinch_law"]
