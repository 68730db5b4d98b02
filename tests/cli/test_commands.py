"""The CLI end to end: one JSON object with --json, clear errors with exit status 2."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from flowtwin.cli.main import app, main
from flowtwin.gcode.generator import PrintSpec, write_print

runner = CliRunner()


@pytest.fixture(scope="module")
def small_gcode(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("cli") / "p.gcode"
    write_print(path, PrintSpec(layers=3))
    return path


def test_plan_json(small_gcode: Path) -> None:
    res = runner.invoke(app, ["plan", str(small_gcode), "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    for key in ("total_time_s", "net_filament_mm", "moves", "layers", "unknown_commands"):
        assert key in out
    assert out["layers"] == 3 and out["total_time_s"] > 0
    assert out["net_filament_mm"]["0"] > 0


def test_plan_marlin_profile_and_klipper_cfg(small_gcode: Path, tmp_path: Path) -> None:
    res = runner.invoke(app, ["plan", str(small_gcode), "--profile", "generic-marlin", "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["firmware"] == "marlin"
    cfg = tmp_path / "printer.cfg"
    steppers = "".join(f"[stepper_{a}]\nposition_endstop: 0\nposition_max: 250\n"
                       for a in "xyz")
    cfg.write_text("[printer]\nkinematics: cartesian\nmax_velocity: 200\nmax_accel: 1000\n"
                   + steppers + "[extruder]\nnozzle_diameter: 0.4\nfilament_diameter: 1.75\n"
                   "[gcode_arcs]\nresolution: 1.0\n")
    res = runner.invoke(app, ["plan", str(small_gcode), "--klipper-config", str(cfg), "--json"])
    assert res.exit_code == 0, res.output
    slow = json.loads(res.stdout)["total_time_s"]
    fast = json.loads(runner.invoke(app, ["plan", str(small_gcode), "--json"]).stdout)
    assert slow > fast["total_time_s"]  # 1000 mm/s² is slower than the generic 3000 mm/s²


def test_simulate_json_and_outputs(small_gcode: Path, tmp_path: Path) -> None:
    out_dir = tmp_path / "out"
    res = runner.invoke(app, ["simulate", str(small_gcode), "--json", "--out", str(out_dir),
                              "--series", str(tmp_path / "s.parquet")])
    assert res.exit_code == 0, res.output
    s = json.loads(res.stdout)
    for key in ("commanded_volume_mm3", "delivered_volume_mm3", "rms_flow_error",
                "max_feed_force_n", "min_force_margin_n", "grinding_events", "ooze_volume_mm3"):
        assert key in s
    assert (out_dir / "report.html").stat().st_size > 100_000
    assert json.loads((out_dir / "summary.json").read_text())["summary"]["moves"] == s["moves"]
    assert (tmp_path / "s.parquet").exists()


def test_demo_writes_its_report(tmp_path: Path) -> None:
    res = runner.invoke(app, ["demo", "--out", str(tmp_path / "d"), "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    for name in ("demo.gcode", "plan.json", "summary.json", "report.html"):
        assert (tmp_path / "d" / name).exists()
    assert out["plan"]["layers"] == 10
    assert out["simulation"]["commanded_volume_mm3"] > 0


def test_bad_gcode_exits_2_with_file_and_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                              ) -> None:
    bad = tmp_path / "bad.gcode"
    bad.write_text("G1 X1\nG1 X10 Y1.2.3\n")
    with pytest.raises(SystemExit) as exc:
        main(["plan", str(bad)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "bad.gcode:2 [Y]" in err and "1.2.3" in err and "Traceback" not in err


def test_missing_file_and_unknown_profile_exit_2(tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(tmp_path / "nope.gcode")])
    assert exc.value.code == 2
    assert "cannot open" in capsys.readouterr().err
    gcode = tmp_path / "ok.gcode"
    gcode.write_text("G1 X1 E1\n")
    with pytest.raises(SystemExit) as exc:
        main(["plan", str(gcode), "--profile", "no-such-printer"])
    assert exc.value.code == 2
    assert "no-such-printer" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [
    ["plan", "x.gcode", "--no-such-option"],
    ["calibrate", "pattern", "kline", "-o", "x.gcode", "--speed", "30"],  # chevron's option
    ["calibrate", "pattern", "spiral", "-o", "x.gcode"],
])
def test_usage_errors_exit_2_with_typers_message(argv: list[str], tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    # typer (>= 0.23) raises its vendored click's exceptions: still usage errors, not
    # internal errors
    with pytest.raises(SystemExit) as exc:
        main([a.replace("x.gcode", str(tmp_path / "x.gcode")) for a in argv])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Usage: " in err and ("No such option" in err or "No such command" in err)
    assert "internal error" not in err and not (tmp_path / "x.gcode").exists()


def test_simulate_stream_equals_whole_simulation(small_gcode: Path) -> None:
    whole = json.loads(runner.invoke(app, ["simulate", str(small_gcode), "--json"]).stdout)
    res = runner.invoke(app, ["simulate", str(small_gcode), "--json", "--stream"])
    assert res.exit_code == 0, res.output
    streamed = json.loads(res.stdout)
    for key in ("commanded_volume_mm3", "delivered_volume_mm3", "total_time_s"):
        assert streamed[key] == pytest.approx(whole[key], rel=1e-9)


def test_simulate_series_at_the_asked_interval(small_gcode: Path, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    import numpy as np

    out = tmp_path / "s.csv"
    res = runner.invoke(app, ["simulate", str(small_gcode), "--json", "--series", str(out),
                              "--series-dt", "0.002"])
    assert res.exit_code == 0, res.output
    data = np.genfromtxt(out, delimiter=",", names=True)
    t = data[data.dtype.names[0]]
    assert np.allclose(np.diff(t), 0.002, rtol=0, atol=1e-7)
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(small_gcode), "--series", str(out), "--series-dt", "-1"])
    assert exc.value.code == 2
    assert "--series-dt" in capsys.readouterr().err
