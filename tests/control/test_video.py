"""Video and camera measurement sources: a real video file through OpenCV and the pipeline."""

from __future__ import annotations

import time
from pathlib import Path

import cv2
import pytest

from flowtwin.control.loop.clock import RealClock, SimClock
from flowtwin.control.loop.measurement import Measurement, MeasurementLost, MeasurementSource
from flowtwin.control.loop.video import CameraSource, VideoSource
from flowtwin.control.simulated.camera import twin_scene
from flowtwin.errors import ProfileError, VisionError
from flowtwin.vision.synth import MotionSeries, SyntheticCamera, write_video

SCENE = twin_scene(2.85, width_px=320, height_px=256, mm_per_px=0.05, seed=5)
SLIP = 0.2
N_FRAMES = 22  # 1.47 s at 14.3 fps


@pytest.fixture(autouse=True, scope="module")
def _one_opencv_thread() -> None:
    cv2.setNumThreads(1)


@pytest.fixture(scope="module")
def video(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A lossless recording of a drive feeding at 1.5 mm/s with 20 % slip."""
    duration = (N_FRAMES - 1) / SCENE.fps
    motion = MotionSeries.constant(duration_s=duration, gear_speed_mm_s=1.5, slip=SLIP,
                                   width_mm=2.85)
    frames = SyntheticCamera(SCENE, motion, duration_s=duration).frames()
    return write_video(frames, tmp_path_factory.mktemp("ctl") / "drive.avi", fps=SCENE.fps)


def test_video_replays_on_the_loop_clock(video: Path) -> None:
    clk = SimClock()
    src = VideoSource(video, SCENE.vision_config(), clk, window_frames=5)
    assert isinstance(src, MeasurementSource)
    assert src.read() is None                  # first frame only
    clk.advance(0.25)                          # frames 0-3 are due (70 ms apart)
    assert src.read() is None
    clk.advance(0.05)                          # frame 4 at 0.28 s completes a burst
    m = src.read()
    assert isinstance(m, Measurement) and m.valid
    assert m.t_s == pytest.approx(4 / SCENE.fps, abs=1e-3)
    # lossless video of a constant 20 % slip; 1 point = 3 σ of the pipeline at 50 µm/px
    assert m.slip == pytest.approx(SLIP, abs=0.01)
    got = [m]
    while not src.finished:
        clk.advance(0.1)
        out = src.read()
        if out is not None:
            got.append(out)
        assert clk.now() < 5.0
    assert len(got) == (N_FRAMES - 1) // 4    # bursts share their boundary frame
    assert all(g.valid and abs(g.slip - SLIP) < 0.01 for g in got)
    src.close()


def test_camera_thread_delivers_then_reports_the_end(video: Path) -> None:
    # the camera path (background thread, arrival times on the loop clock), fed by a file
    src = CameraSource(str(video), SCENE.vision_config(), RealClock(), window_frames=6)
    got: list[Measurement] = []
    deadline = time.monotonic() + 30.0
    with pytest.raises(MeasurementLost, match="stream ended"):
        while time.monotonic() < deadline:
            m = src.read()
            if m is not None:
                got.append(m)
            time.sleep(0.01)
    src.close()
    assert got and all(abs(g.slip - SLIP) < 0.01 for g in got if g.valid)
    assert any(g.valid for g in got)


def test_missing_camera_and_bad_options(video: Path, tmp_path: Path) -> None:
    with pytest.raises(VisionError, match="camera could not be opened"):
        CameraSource(57, SCENE.vision_config(), RealClock())
    with pytest.raises(VisionError, match="no such file"):
        VideoSource(tmp_path / "none.avi", SCENE.vision_config(), SimClock())
    with pytest.raises(ProfileError, match="two frames"):
        VideoSource(video, SCENE.vision_config(), SimClock(), window_frames=1)
