"""``flowtwin vision synth | measure | inspect | calibrate`` end to end."""

from __future__ import annotations

import json

import pyarrow.parquet as pq
import pytest
import typer
from typer.testing import CliRunner

from flowtwin.cli import vision as cli
from flowtwin.cli.main import main


def _app() -> typer.Typer:
    app = typer.Typer()
    cli.register(app)

    @app.callback()
    def _root() -> None:
        """flowtwin (test)."""

    return app


@pytest.fixture(scope="module")
def clip(tmp_path_factory: pytest.TempPathFactory):
    tmp = tmp_path_factory.mktemp("cli")
    video, toml = tmp / "clip.avi", tmp / "clip.toml"
    r = CliRunner().invoke(_app(), ["vision", "synth", str(video), "--speed", "2.5",
                                    "--slip", "0.12", "--duration", "1.0", "--seed", "3",
                                    "--fourcc", "MJPG", "--config-out", str(toml), "--json"])
    assert r.exit_code == 0, r.output
    truth = json.loads(r.stdout)
    assert truth["filament_speed_mm_s"] == pytest.approx(2.2)
    return tmp, video, toml, truth


def test_measure_json_and_files(clip) -> None:
    tmp, video, toml, _ = clip
    r = CliRunner().invoke(_app(), [
        "vision", "measure", str(video), "-c", str(toml), "--json",
        "--csv", str(tmp / "s.csv"), "--parquet", str(tmp / "s.parquet"),
        "--plot", str(tmp / "s.png")])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)                 # exactly one JSON object
    for key in ("gear_speed_mm_s", "filament_speed_mm_s", "slip", "width_mm", "frames",
                "valid_frames"):
        assert key in out
    assert out["gear_speed_mm_s"] == pytest.approx(2.5, rel=0.01)
    assert out["filament_speed_mm_s"] == pytest.approx(2.2, rel=0.01)
    assert out["slip"] == pytest.approx(0.12, abs=0.005)
    assert out["slip_pct"] == pytest.approx(12.0, abs=0.5)
    assert out["frames"] == 31 and out["valid_frames"] == 30
    assert pq.read_table(tmp / "s.parquet").num_rows == 31
    assert (tmp / "s.png").stat().st_size > 10_000 and (tmp / "s.csv").is_file()
    # ROIs and scale on the command line instead of the file; human-readable table
    rois = [f"{name}={','.join(map(str, v))}" for name, v in
            (("gear", [88, 90, 205, 300]), ("before", [374, 4, 112, 144]),
             ("after", [393, 299, 74, 177]))]
    args = ["vision", "measure", str(video), "--mm-per-px", "0.02", "--gear-center",
            "190.25,240"]
    for text in rois:
        args += ["--roi", text]
    r = CliRunner().invoke(_app(), args)
    assert r.exit_code == 0, r.output
    assert "slip" in r.stdout and "rotation" in r.stdout


def test_inspect_and_calibrate(clip) -> None:
    tmp, video, toml, _ = clip
    r = CliRunner().invoke(_app(), ["vision", "inspect", str(video), "-c", str(toml),
                                    "--out", str(tmp / "i.png"), "--json"])
    assert r.exit_code == 0, r.output
    rep = json.loads(r.stdout)
    assert rep["problems"] == [] and (tmp / "i.png").is_file()
    r = CliRunner().invoke(_app(), ["vision", "calibrate", str(video), "-c", str(toml),
                                    "--width-mm", "1.75", "--json"])
    assert r.exit_code == 0, r.output
    cal = json.loads(r.stdout)
    # the clip's filament varies ±20 µm around 1.75 mm and the shading bias is ~0.3 %
    assert cal["mm_per_px"] == pytest.approx(0.02, rel=0.01)
    assert cal["frames_used"] == cal["frames"] == 31


def test_user_errors_exit_2_with_a_clear_message(clip, capsys) -> None:
    tmp, video, toml, _ = clip
    with pytest.raises(SystemExit) as exc:
        main(["vision", "measure", str(video), "-c", str(toml), "--roi",
              "after=600,100,100,50"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "ROI 'after' extends beyond the 640×480 frame" in err and "x + w = 700" in err
    with pytest.raises(SystemExit) as exc:
        main(["vision", "measure", str(video), "--roi", "gear=1,2,3"])
    assert exc.value.code == 2 and "four numbers" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["vision", "measure", str(tmp / "clip.toml"), "-c", str(toml)])
    assert exc.value.code == 2 and "cannot open the video" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["vision", "measure", str(video), "-c", str(toml), "--mm-per-px", "0.02",
              "--calib-width-mm", "1.75"])
    assert exc.value.code == 2 and "either as --mm-per-px" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main(["vision", "inspect", str(video), "--roi", "after=600,100,100,50", "--out",
              str(tmp / "bad.png")])
    assert exc.value.code == 1 and "extends beyond" in capsys.readouterr().err
