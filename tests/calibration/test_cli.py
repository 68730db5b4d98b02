"""``flowtwin calibrate`` through a typer app that registers only this command group."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from flowtwin.cli.calibrate import register
from flowtwin.errors import CalibrationError, DataError
from flowtwin.gcode.reader import read_gcode
from flowtwin.physics.strand import tractrix_z_mm
from flowtwin.profiles.material import ExponentialViscosity

runner = CliRunner()


def _app() -> typer.Typer:
    app = typer.Typer(add_completion=False)

    @app.callback()
    def _root() -> None:
        """Test root."""

    register(app)
    return app


APP = _app()


@pytest.mark.parametrize("command", ["pattern", "fit-viscosity", "fit-strand", "adaptive-pa"])
def test_help_says_what_to_measure(command: str) -> None:
    result = runner.invoke(APP, ["calibrate", command, "--help"])
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    if command == "pattern":
        for kind in ("kline:", "chevron:", "tower:", "flow:", "maxflow:", "flowline:"):
            assert kind in text
        assert "pick the K" in text
    else:
        assert "What to measure" in text


def test_pattern_json_and_file(tmp_path: Path) -> None:
    out = tmp_path / "k.gcode"
    result = runner.invoke(APP, ["calibrate", "pattern", "kline", "--firmware", "marlin",
                                 "--k-end", "0.05", "-o", str(out), "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["kind"] == "kline" and data["firmware"] == "marlin"
    assert data["values"] == pytest.approx([0.0, 0.01, 0.02, 0.03, 0.04, 0.05])
    assert data["check"]["ok"] is True and data["check"]["printer"] == "generic-marlin"
    table = read_gcode(out)
    ks = [e.params["K"] for e in table.events if e.code == "M900"]
    assert ks == pytest.approx(data["values"])


def test_pattern_text_warns_about_unreached_speeds(tmp_path: Path) -> None:
    out = tmp_path / "m.gcode"
    result = runner.invoke(APP, ["calibrate", "pattern", "maxflow", "--firmware", "marlin",
                                 "--flow-start", "16", "--flow-end", "20", "--flow-step", "2",
                                 "--printer", "prusa-i3-mk25", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert "test speeds reached" in result.stdout
    assert "reaches 200.0 of" in result.stderr
    assert out.exists()


def test_pattern_option_that_does_not_apply(tmp_path: Path) -> None:
    result = runner.invoke(APP, ["calibrate", "pattern", "kline", "--speed", "30", "-o",
                                 str(tmp_path / "x.gcode")])
    assert isinstance(result.exception, CalibrationError)
    assert "--speed does not apply to the kline pattern" in str(result.exception)
    assert not (tmp_path / "x.gcode").exists()


def test_fit_viscosity_writes_a_valid_fragment(tmp_path: Path) -> None:
    rng = np.random.default_rng(12)
    temps = np.repeat(np.arange(190.0, 231.0, 10.0), 2)
    mu = 2.6718e7 * np.exp(-0.053648 * temps) * np.exp(rng.normal(0.0, 0.02, temps.size))
    data = tmp_path / "sweep.csv"
    data.write_text("# viscometer sweep\ntemp_c,viscosity_pa_s\n" + "".join(
        f"{t},{float(m)!r}\n" for t, m in zip(temps, mu, strict=True)))
    frag = tmp_path / "visc.toml"
    result = runner.invoke(APP, ["calibrate", "fit-viscosity", str(data), "-o", str(frag),
                                 "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert out["law"] == "exponential" and out["n_points"] == 10
    assert abs(out["params"]["b_per_c"] - 0.053648) <= 3 * out["stderr"]["b_per_c"]
    table = tomllib.loads(frag.read_text())["viscosity"]
    ExponentialViscosity.model_validate(table)
    assert table["b_per_c"] == pytest.approx(out["params"]["b_per_c"], rel=1e-6)
    assert "± " in frag.read_text()


def test_fit_viscosity_from_force_needs_flow(tmp_path: Path) -> None:
    data = tmp_path / "f.csv"
    data.write_text("temp_c,feed_force_n\n200,5\n210,4\n220,3\n")
    result = runner.invoke(APP, ["calibrate", "fit-viscosity", str(data)])
    assert isinstance(result.exception, DataError)
    assert "[flow_mm3_s]" in str(result.exception)


def test_fit_strand_json(tmp_path: Path) -> None:
    x = np.linspace(0.0, 2.0, 30)
    z = tractrix_z_mm(x, 0.3) + np.random.default_rng(1).normal(0.0, 0.002, x.size)
    data = tmp_path / "strand.csv"
    data.write_text("x_mm,z_mm\n" + "".join(f"{float(a)!r},{max(float(b), 0.0)!r}\n"
                                            for a, b in zip(x, z, strict=True)))
    frag = tmp_path / "strand.toml"
    result = runner.invoke(APP, ["calibrate", "fit-strand", str(data), "--height-mm", "0.3",
                                 "-o", str(frag), "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert out["model"] == "tractrix"
    assert abs(out["params"]["r_mm"] - 0.3) <= 3 * out["stderr"]["r_mm"]
    parsed = tomllib.loads(frag.read_text())["strand"]
    assert parsed["model"] == "tractrix" and math.isfinite(parsed["lag_mm"])


def test_adaptive_pa_table_and_queries(tmp_path: Path) -> None:
    data = tmp_path / "pa.csv"
    data.write_text("k_s,flow_mm3_s,accel_mm_s2\n0.04,3.96,3000\n0.033,3.96,10000\n"
                    "0.029,7.91,3000\n0.026,7.91,10000\n")
    out = tmp_path / "table.txt"
    result = runner.invoke(APP, ["calibrate", "adaptive-pa", str(data), "-o", str(out),
                                 "--at", "3.96,3000", "--at", "100,100000", "--json"])
    assert result.exit_code == 0, result.output
    res = json.loads(result.stdout)
    assert [q["k_s"] for q in res["queries"]] == pytest.approx([0.04, 0.026])
    assert out.read_text().splitlines() == res["table"] == [
        "0.04,3.96,3000", "0.029,7.91,3000", "0.033,3.96,10000", "0.026,7.91,10000"]
    assert res["warnings"] == []


def test_adaptive_pa_bad_query(tmp_path: Path) -> None:
    data = tmp_path / "pa.csv"
    data.write_text("k_s,flow_mm3_s,accel_mm_s2\n0.04,3.96,3000\n")
    result = runner.invoke(APP, ["calibrate", "adaptive-pa", str(data), "-o",
                                 str(tmp_path / "t.txt"), "--at", "5"])
    assert isinstance(result.exception, CalibrationError)
    assert "--at takes FLOW,ACCEL" in str(result.exception)
