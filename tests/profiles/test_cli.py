"""``flowtwin profiles list`` / ``show`` through the real typer app.

(Lives with the profile tests because tests/cli/ belongs to the CLI entry point's owner.)
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from typer.testing import CliRunner

from flowtwin.cli.main import app, main
from flowtwin.errors import ProfileError
from flowtwin.profiles import library_names, load_builtin, save_profile

runner = CliRunner()


def test_list_json() -> None:
    result = runner.invoke(app, ["profiles", "list", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert [p["name"] for p in data["profiles"]] == library_names()
    kinds = {p["name"]: p["kind"] for p in data["profiles"]}
    assert kinds["roller-3"] == "roller" and kinds["tronvoll2019"] == "setup"
    assert all(p["description"] for p in data["profiles"])


def test_list_table() -> None:
    result = runner.invoke(app, ["profiles", "list"])
    assert result.exit_code == 0
    for name in ("generic-klipper", "pla-4043d", "greeff2017", "roller-7"):
        assert name in result.stdout


def test_show_roller3_json_reports_the_eq9_discrepancy() -> None:
    result = runner.invoke(app, ["profiles", "show", "roller-3", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["kind"] == "roller"
    assert data["profile"]["k_s_pct_N"] == 96.0
    check = data["eq9_check"]
    assert check["tabulated_n"] == 77.0
    assert check["eq9_n"] == pytest.approx(math.sqrt(96.0 / (0.1 * 0.32)))
    assert check["consistent"] is False
    assert data["internal"]["k_inf_per_n"] == pytest.approx(0.0032)


def test_show_roller_table_text() -> None:
    result = runner.invoke(app, ["profiles", "show", "rollers"])
    assert result.exit_code == 0, result.output
    assert "DISAGREES" in result.stdout
    assert result.stdout.count("DISAGREES") == 1  # only roller #3


def test_show_roller3_text() -> None:
    result = runner.invoke(app, ["profiles", "show", "roller-3"])
    assert result.exit_code == 0, result.output
    assert "F_p,min tabulated 77 N" in result.stdout and "54.8 N" in result.stdout


def test_show_setup_resolves_parts() -> None:
    result = runner.invoke(app, ["profiles", "show", "tronvoll2019", "--json"])
    assert result.exit_code == 0, result.output
    parts = json.loads(result.stdout)["parts"]
    assert parts == {"printer": "prusa-i3-mk25", "drive": "hobb-goblin-80n",
                     "roller": "roller-3", "hotend": "e3d-v6-0.4", "material": "pla-4043d",
                     "filament": "pla-4043d-1.75"}


def test_show_klipper_printer_resolved_limits() -> None:
    result = runner.invoke(app, ["profiles", "show", "generic-klipper", "--json"])
    data = json.loads(result.stdout)
    assert data["resolved_limits"]["max_extrude_cross_section_mm2"] == pytest.approx(0.64)
    assert data["pa_smooth_time_s"] == 0.04


def test_show_file(tmp_path: Path) -> None:
    path = tmp_path / "my hotend.toml"
    save_profile(load_builtin("e3d-v6-0.4"), path)
    result = runner.invoke(app, ["profiles", "show", str(path), "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["kind"] == "hotend" and data["source"] == str(path)
    assert data["cone_length_mm"] > 0


def test_show_unknown_name_raises_profile_error() -> None:
    result = runner.invoke(app, ["profiles", "show", "roller-8"])
    assert isinstance(result.exception, ProfileError)
    assert "did you mean" in str(result.exception)


def test_main_exits_2_on_a_bad_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "bad.toml"
    path.write_text('kind = "filament"\nname = "f"\ndiameter_mm = -1.0\ntolerance_mm = 0.1\n')
    with pytest.raises(SystemExit) as info:
        main(["profiles", "show", str(path)])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and "must be > 0" in err and "-1.0" in err
