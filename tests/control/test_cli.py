"""``flowtwin control`` on the twin (accelerated time): JSON summary, CSV log, errors."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from flowtwin.cli import control as control_cli
from flowtwin.control.loop.log import COLUMNS
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


def test_twin_camera_prints_the_polygon_in_simulated_time(app: typer.Typer,
                                                          tmp_path: Path) -> None:
    log = tmp_path / "job.csv"
    r = CliRunner().invoke(app, ["control", "--printer", "twin?delay=0.5", "--twin-camera",
                                 "--layers-per-set", "1", "--sim-time", "--json",
                                 "--log", str(log)])
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    for key in ("samples", "mean_slip", "multiplier_min_pct", "multiplier_max_pct",
                "faults", "final_multiplier_restored"):
        assert key in s
    assert s["final_multiplier_restored"] is True and s["faults"] == []
    assert s["samples"] >= 8 and 0.0 < s["mean_slip"] < 0.6
    assert s["multiplier_min_pct"] < 100.0 == s["multiplier_max_pct"]
    job = s["job"]
    assert job["done"] is True and 0.0 < job["mass_g"] < job["commanded_mass_g"]
    assert job["wait_s"] > 60.0                        # two M109 R waits
    events = [row["event"] for row in csv.DictReader(log.open())]
    assert "idle" in events and events[-4:] == ["done", "restore", "read", "end"]


def test_video_source_ends_with_the_recording(app: typer.Typer, tmp_path: Path) -> None:
    import cv2

    from flowtwin.control.simulated.camera import twin_scene
    from flowtwin.vision.synth import (
        MotionSeries,
        SyntheticCamera,
        write_config_toml,
        write_video,
    )

    cv2.setNumThreads(1)
    scene = twin_scene(2.85, width_px=320, height_px=256, mm_per_px=0.05, seed=2)
    duration = 24 / scene.fps
    motion = MotionSeries.constant(duration_s=duration, gear_speed_mm_s=1.5, slip=0.25,
                                   width_mm=2.85)
    video = write_video(SyntheticCamera(scene, motion, duration_s=duration).frames(),
                        tmp_path / "drive.avi", fps=scene.fps)
    cfg = write_config_toml(scene.vision_config(), tmp_path / "vision.toml")
    r = CliRunner().invoke(app, ["control", "--printer", "twin", "--video", str(video),
                                 "--vision-config", str(cfg), "--window-frames", "5",
                                 "--sim-time", "--period", "0.1", "--json"])
    assert r.exit_code == 0, r.output
    s = json.loads(r.stdout)
    # 24 steps in bursts of 4; a poll that finds more than a burst measures the newest 4
    # steps only, so one burst may be skipped
    assert 5 <= s["samples"] <= 6 and s["faults"] == []
    assert abs(s["mean_slip"] - 0.25) < 0.01            # 3 σ of the pipeline at 50 µm/px
    assert s["duration_s"] < 2.5 and s["final_multiplier_restored"] is True


@pytest.mark.parametrize(("args", "match"), [
    (["--printer", "moonraker://127.0.0.1:9", "--twin-camera"], "only applies to the twin"),
    (["--printer", "twin", "--synthetic", "--twin-camera"], "more than one"),
    (["--printer", "twin", "--video", "x.avi"], "needs a vision configuration"),
    (["--printer", "twin", "--sim-time", "--gcode", "nope.gcode", "--synthetic"],
     "nope.gcode"),
])
def test_source_errors(app: typer.Typer, args: list[str], match: str) -> None:
    r = CliRunner().invoke(app, ["control", *args])
    assert isinstance(r.exception, FlowtwinError)
    assert match in str(r.exception)


def test_missing_camera_is_a_user_error(app: typer.Typer, tmp_path: Path) -> None:
    from flowtwin.control.simulated.camera import twin_scene
    from flowtwin.vision.synth import write_config_toml

    cfg = write_config_toml(twin_scene(2.85).vision_config(), tmp_path / "v.toml")
    r = CliRunner().invoke(app, ["control", "--printer", "twin", "--camera", "57",
                                 "--vision-config", str(cfg), "--duration", "1"])
    assert isinstance(r.exception, FlowtwinError)
    assert "camera could not be opened" in str(r.exception)
