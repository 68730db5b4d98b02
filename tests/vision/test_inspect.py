"""The set-up check: annotated frame and what it reports."""

from __future__ import annotations

from pathlib import Path

import cv2
import pytest

from flowtwin.errors import VisionError
from flowtwin.vision import Roi, inspect_source
from flowtwin.vision.synth import MotionSeries, SceneSpec, write_video

from .conftest import render


@pytest.fixture(scope="module")
def video(tmp_path_factory: pytest.TempPathFactory):
    scene = SceneSpec(seed=14)
    frames = render(scene, MotionSeries.constant(duration_s=4 / 30, gear_speed_mm_s=2.0))
    # lossless: JPEG smooths pixel noise into blotches that pass for corners (the
    # measurement's match and agreement checks reject them; the count here would not)
    return scene, write_video(frames, tmp_path_factory.mktemp("insp") / "c.avi", fps=30,
                              fourcc="FFV1")


def test_inspect_draws_and_reports(tmp_path: Path, video) -> None:
    scene, path = video
    rois = {r.name: r for r in scene.suggested_rois()}
    out = tmp_path / "check.png"
    rep = inspect_source(path, rois, out, frame_index=2, gear_center_px=scene.gear_center_px,
                         mm_per_px=scene.mm_per_px)
    img = cv2.imread(str(out))
    assert img.shape == (480, 640, 3)
    assert rep.frame == 2 and rep.problems == []
    assert rep.features["gear"] >= 20 and rep.features["after"] >= 20
    assert rep.filament_width_mm == pytest.approx(1.75, abs=0.03)
    # contact radius: gear axis to the near filament edge = the drive radius
    assert rep.contact_radius_px * scene.mm_per_px == pytest.approx(scene.drive_radius_mm,
                                                                     abs=0.03)


def test_inspect_lists_problems(tmp_path: Path, video) -> None:
    _, path = video
    rois = {"gear": Roi("gear", 600, 100, 100, 50),            # leaves the frame
            "after": Roi("after", 560, 200, 60, 80)}           # on the smooth bearing
    rep = inspect_source(path, rois, tmp_path / "p.png")
    text = " | ".join(rep.problems)
    assert "ROI 'before' is not set" in text
    assert "ROI 'gear' extends beyond the 640×480 frame" in text
    assert "ROI 'after' has 0 trackable features" in text
    with pytest.raises(VisionError, match="fewer frames than requested"):
        inspect_source(path, rois, tmp_path / "q.png", frame_index=50)
