"""One loop measurement from a burst of real (rendered) frames through the vision pipeline."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from flowtwin.control.loop.burst import measure_burst
from flowtwin.control.simulated.camera import twin_scene
from flowtwin.vision import Frame
from flowtwin.vision.synth import MotionSeries, SyntheticCamera

#: The print-job test's camera: 320×256 px at 50 µm/px, 14.3 fps [003 §2.1].
SCENE = twin_scene(2.85, width_px=320, height_px=256, mm_per_px=0.05)
SPAN_S = 4 / SCENE.fps  # five frames


@pytest.fixture(autouse=True, scope="module")
def _one_opencv_thread() -> None:
    cv2.setNumThreads(1)


def _burst(t: list[float], gear: list[float], fil: list[float]) -> list[Frame]:
    motion = MotionSeries(np.asarray(t), np.asarray(gear), np.asarray(fil),
                          np.full(len(t), 2.85))
    cam = SyntheticCamera(SCENE, motion, duration_s=SPAN_S)
    return [Frame(f.index, f.t_s, f.image) for f in cam.frames()]


@pytest.mark.parametrize(("gear", "slip"), [(2.0, 0.08), (1.2, 0.35), (2.0, 0.6)])
def test_steady_feed_gives_its_slip(gear: float, slip: float) -> None:
    frames = _burst([0.0, SPAN_S], [gear, gear], [gear * (1 - slip)] * 2)
    m, result = measure_burst(frames, SCENE.vision_config(), t_s=12.0,
                              frame_size=(SCENE.width_px, SCENE.height_px))
    assert m.valid and not m.idle and m.t_s == 12.0
    # the pipeline reads constant slip at 50 µm/px within ~0.3 percentage points rms
    # (measured over seeds); 1 point is three standard deviations
    assert m.slip == pytest.approx(slip, abs=0.01)
    assert m.gear_speed_mm_s == pytest.approx(gear, rel=0.01)
    assert len(result.series) == 5


def test_still_gear_is_idle_not_invalid() -> None:
    # what the twin camera assumes when it skips rendering a heater wait
    frames = _burst([0.0, SPAN_S], [0.0, 0.0], [0.0, 0.0])
    m, _ = measure_burst(frames, SCENE.vision_config(), t_s=3.0,
                         frame_size=(SCENE.width_px, SCENE.height_px))
    assert m.idle and not m.valid and math.isnan(m.slip)


def test_burst_over_a_retraction_is_not_a_slip_measurement() -> None:
    # printing at 2 mm/s, then a 16 mm/s retraction inside the burst [003 §3.2]
    t = [0.0, 0.15, 0.1501, SPAN_S]
    frames = _burst(t, [2.0, 2.0, -16.0, -16.0], [1.8, 1.8, -16.0, -16.0])
    m, _ = measure_burst(frames, SCENE.vision_config(), t_s=3.0,
                         frame_size=(SCENE.width_px, SCENE.height_px))
    assert not m.valid and not m.idle and math.isnan(m.slip)
