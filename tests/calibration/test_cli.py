"""``flowtwin calibrate`` through a typer app that registers only this command group."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from flowtwin.calibration.fits.kfit import kline_for_machine
from flowtwin.calibration.fits.lagmodel import LagParams, lag_model
from flowtwin.calibration.image.twin_render import ImageConditions
from flowtwin.calibration.patterns.kline import KLineParams
from flowtwin.calibration.patterns.pattern import PrintSettings
from flowtwin.cli.calibrate import register
from flowtwin.errors import CalibrationError, DataError, VisionError
from flowtwin.gcode.reader import read_gcode
from flowtwin.physics.strand import tractrix_z_mm
from flowtwin.profiles import load_rollers
from flowtwin.profiles.machine import Machine
from flowtwin.profiles.material import ExponentialViscosity
from flowtwin.teststand import (
    DriveUnderTest,
    Instrument,
    Procedure,
    SlipLaw,
    simulate_campaign,
    write_records_csv,
)

runner = CliRunner()


def _app() -> typer.Typer:
    app = typer.Typer(add_completion=False)

    @app.callback()
    def _root() -> None:
        """Test root."""

    register(app)
    return app


APP = _app()


@pytest.mark.parametrize("command", ["pattern", "fit-viscosity", "fit-strand", "adaptive-pa",
                                     "fit-k", "from-image", "fit-slip"])
def test_help_says_what_to_measure(command: str) -> None:
    result = runner.invoke(APP, ["calibrate", command, "--help"])
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    if command == "pattern":
        for kind in ("kline", "chevron", "tower", "flow", "maxflow", "flowline"):
            assert kind in text
        assert "--no-check" in text
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


# every kind: how to read it, its own options and the shared ones, no other kind's options
_OWN_OPTIONS = {
    "kline": (["--k-start", "--k-end", "--k-step", "--slow-speed", "--fast-speed",
               "--mark-every"], "pick the K"),
    "chevron": (["--k-start", "--k-end", "--k-step", "--speed", "--first-layer-speed",
                 "--walls", "--layers", "--mark-every"], "sharp apex"),
    "tower": (["--k-start", "--k-step-per-mm", "--height", "--size", "--walls", "--speed",
               "--first-layer-speed"], "calipers"),
    "flow": (["--multiplier-start", "--multiplier-end", "--multiplier-step", "--block-size",
              "--layers"], "flat top"),
    "maxflow": (["--flow-start", "--flow-end", "--flow-step"], "maximum volumetric speed"),
    "flowline": (["--flow", "--cycles", "--k-start", "--k-end", "--k-step"], "lag fit"),
}
_ALL_OPTIONS = {o for opts, _ in _OWN_OPTIONS.values() for o in opts}


def test_every_pattern_kind_has_its_command_options_and_help() -> None:
    from flowtwin.calibration.guide import PATTERN_KIND_HELP
    from flowtwin.calibration.patterns.catalog import PATTERN_KINDS
    from flowtwin.cli.calibrate_pattern import _KIND_OPTIONS

    assert set(PATTERN_KINDS) == set(_KIND_OPTIONS) == set(PATTERN_KIND_HELP) == set(
        _OWN_OPTIONS)


@pytest.mark.parametrize("kind", list(_OWN_OPTIONS))
def test_each_pattern_kind_has_only_its_options(kind: str) -> None:
    result = runner.invoke(APP, ["calibrate", "pattern", kind, "--help"],
                           env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    own, how = _OWN_OPTIONS[kind]
    assert how in text
    shown = {w.strip(",") for w in text.split() if w.startswith("--")}
    assert set(own) <= shown and not (_ALL_OPTIONS - set(own)) & shown
    for shared in ("--output", "--firmware", "--accel", "--printer", "--no-check", "--json"):
        assert shared in shown


def test_pattern_option_of_another_kind_is_a_usage_error(tmp_path: Path) -> None:
    result = runner.invoke(APP, ["calibrate", "pattern", "kline", "--speed", "30", "-o",
                                 str(tmp_path / "x.gcode")])
    assert result.exit_code == 2
    assert "No such option: --speed" in result.output
    assert not (tmp_path / "x.gcode").exists()


def test_pattern_defaults_are_the_kinds_defaults(tmp_path: Path) -> None:
    # options left out give the parameter object's defaults (the same file as the API)
    from flowtwin.calibration.patterns.catalog import generate_pattern

    for kind in _OWN_OPTIONS:
        out = tmp_path / f"{kind}.gcode"
        result = runner.invoke(APP, ["calibrate", "pattern", kind, "-o", str(out),
                                     "--no-check", "--json"])
        assert result.exit_code == 0, result.output
        assert out.read_text() == generate_pattern(kind).text()


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


# --- lag and slip fits -------------------------------------------------------------------

def _kline_profile(tmp_path: Path, machine: Machine, k_s: float, seed: int) -> Path:
    """Widths along one K-line printed without advance on ``machine``, as a user's CSV."""
    p = kline_for_machine(machine, PrintSettings(), KLineParams(k_start=0.0, k_end=0.0,
                                                                mark_every=0))
    model = lag_model(p.text().encode(), [p.segments[0].line], machine=machine)
    x = np.arange(0.0, 80.001, 0.25)
    w = model.widths(LagParams(k_s), [x])[0] + np.random.default_rng(seed).normal(
        0.0, 0.01, x.size)
    path = tmp_path / f"profile-{seed}.csv"
    path.write_text("# microscope, 0.25 mm steps\nposition_mm,width_mm\n" + "".join(
        f"{a:.3f},{b:.4f}\n" for a, b in zip(x, w, strict=True) if b == b and b > 0))
    return path


def test_fit_k_json_fragment_and_adaptive_rows(tmp_path: Path, tronvoll: Machine) -> None:
    frag = tmp_path / "pa.toml"
    measured = tmp_path / "measured.csv"
    for seed, k in ((1, 0.05), (2, 0.05)):
        result = runner.invoke(APP, ["calibrate", "fit-k", str(_kline_profile(
            tmp_path, tronvoll, k, seed)), "-o", str(frag), "--append-to", str(measured),
            "--json"])
        assert result.exit_code == 0, result.output
        out = json.loads(result.stdout)
        assert abs(out["k_s"] - k) <= 3 * out["k_err_s"]
        assert out["fitted"] == ["k_s"] and out["lines"][0]["advance_k_s"] == 0.0
    assert tomllib.loads(frag.read_text())["pressure_advance"]["k_s"] == pytest.approx(
        out["k_s"], abs=1e-6)
    assert len(measured.read_text().splitlines()) == 3
    table = tmp_path / "orca.txt"
    result = runner.invoke(APP, ["calibrate", "adaptive-pa", str(measured), "-o", str(table),
                                 "--json"])
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["points"] == 1      # two repeats at one flow, averaged


def test_fit_k_text_and_errors(tmp_path: Path, tronvoll: Machine) -> None:
    profile = _kline_profile(tmp_path, tronvoll, 0.05, 3)
    result = runner.invoke(APP, ["calibrate", "fit-k", str(profile), "--fit-gain"])
    assert result.exit_code == 0, result.output
    assert "K (lag)" in result.stdout and "[pressure_advance]" in result.stdout
    result = runner.invoke(APP, ["calibrate", "fit-k", str(profile), "--gcode-line", "34"])
    assert isinstance(result.exception, CalibrationError)
    assert "need the G-code file" in str(result.exception)
    bad = tmp_path / "bad.csv"
    bad.write_text("position_mm,width_mm\n1,0.5\n2,abc\n3,0.5\n")
    result = runner.invoke(APP, ["calibrate", "fit-k", str(bad)])
    assert isinstance(result.exception, DataError)
    assert "bad.csv:3 [width_mm]" in str(result.exception)


def test_from_image_json(tmp_path: Path, render_kline7: Any) -> None:
    img = render_kline7(0.05, ImageConditions(px_per_mm=10.0, rotation_deg=2.0, blur_px=1.0,
                                              noise_dn=4.0, seed=8))
    path = tmp_path / "scan.png"
    assert cv2.imwrite(str(path), img.image)
    frag = tmp_path / "pa.toml"
    result = runner.invoke(APP, ["calibrate", "from-image", str(path), "--k-start", "0.02",
                                 "--k-end", "0.08", "-o", str(frag), "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert abs(out["lag"]["k_s"] - 0.05) <= 3 * out["lag"]["k_err_s"]
    assert out["k_best_line_s"] == pytest.approx(0.05) and len(out["lines"]) == 7
    assert tomllib.loads(frag.read_text())["pressure_advance"]["k_s"] == pytest.approx(
        out["lag"]["k_s"], abs=1e-6)
    result = runner.invoke(APP, ["calibrate", "from-image", str(path), "--dpi", "300",
                                 "--mm-per-px", "0.1"])
    assert isinstance(result.exception, CalibrationError)
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((200, 300), 240, np.uint8))
    result = runner.invoke(APP, ["calibrate", "from-image", str(blank)])
    assert isinstance(result.exception, VisionError)
    assert "blank" in str(result.exception)


def test_fit_slip_json(tmp_path: Path) -> None:
    drive = DriveUnderTest.from_roller(load_rollers()[3], law=SlipLaw.PINCH, k_p=0.0063)
    records = tmp_path / "stand.csv"
    write_records_csv(records, simulate_campaign(
        drive, seed=4, procedure=Procedure(pinch_forces_n=(40.0, 80.0, 120.0, 150.0),
                                           speeds_mm_s=(1.0, 5.0, 15.0), repeats=1),
        instrument=Instrument(sample_rate_hz=25.0)))
    frag = tmp_path / "drive.toml"
    result = runner.invoke(APP, ["calibrate", "fit-slip", str(records), "-o", str(frag),
                                 "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert out["roller_id"] == "3" and out["records"] == 12
    parsed = tomllib.loads(frag.read_text())
    assert parsed["slip_overrides"]["k_s_pct_N"] == pytest.approx(
        out["slip_overrides"]["k_s_pct_N"], rel=1e-6)
    assert abs(out["slip_overrides"]["k_inf_pct_per_N"] - 0.32) <= 3 * out["errors"][
        "k_inf_pct_per_N"]
