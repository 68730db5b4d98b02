"""Helpers for the vision tests: render synthetic recordings and their ground truth."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import pytest

from flowtwin.vision.readings import Quality, VisionResult
from flowtwin.vision.synth import MotionSeries, SceneSpec, SyntheticCamera, SyntheticFrame


@dataclass
class Truth:
    """Ground truth per delivered frame, aligned with the rows of a measurement."""

    t_s: np.ndarray
    gear_speed_mm_s: np.ndarray       # over the step ending at the row (NaN if skipped)
    filament_speed_mm_s: np.ndarray
    width_mm: np.ndarray


def render(scene: SceneSpec, motion: MotionSeries) -> list[SyntheticFrame]:
    """All delivered frames of a synthetic recording."""
    return list(SyntheticCamera(scene, motion).frames())


def truth_for(frames: list[SyntheticFrame], result: VisionResult) -> Truth:
    """Step speeds between the frames the measurement actually processed."""
    flags = result.series.flags
    assert len(frames) == len(flags)
    skipped = (flags & int(Quality.BLANK | Quality.DUPLICATE)) != 0
    t = np.array([f.t_s for f in frames])
    g = np.array([f.gear_distance_mm for f in frames])
    s = np.array([f.filament_distance_mm for f in frames])
    gs = np.full(len(frames), np.nan)
    fs = np.full(len(frames), np.nan)
    last = None
    for i in range(len(frames)):
        if skipped[i]:
            continue
        if last is not None:
            gs[i] = (g[i] - g[last]) / (t[i] - t[last])
            fs[i] = (s[i] - s[last]) / (t[i] - t[last])
        last = i
    return Truth(t - t[0], gs, fs, np.array([f.width_mm for f in frames]))


@pytest.fixture(autouse=True, scope="session")
def _one_opencv_thread() -> None:
    """The tests share two cores with other work: keep OpenCV to one thread."""
    cv2.setNumThreads(1)
