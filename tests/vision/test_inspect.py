"""The set-up check: annotated frame and what it reports."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from flowtwin.errors import VisionError
from flowtwin.vision import Roi, annotate_frame, inspect_source
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


@pytest.fixture(scope="module")
def moving(tmp_path_factory: pytest.TempPathFactory):
    scene = SceneSpec(seed=15)
    frames = render(scene, MotionSeries.constant(duration_s=29 / 30, gear_speed_mm_s=2.0,
                                                 slip=0.1))
    return scene, write_video(frames, tmp_path_factory.mktemp("insp2") / "m.avi", fps=30,
                              fourcc="FFV1")


def test_inspect_draws_edges_tracks_and_the_estimated_axis(tmp_path: Path, moving) -> None:
    scene, path = moving
    rois = {r.name: r for r in scene.suggested_rois()}
    out = tmp_path / "window.png"
    rep = inspect_source(path, rois, out, frame_index=0, frames=30,
                         mm_per_px=scene.mm_per_px, diameter_mm=1.75)
    assert rep.problems == [] and rep.frames_used == 30 and rep.frame == 29
    # the gear axis, estimated from the motion in the gear ROI
    assert rep.gear_axis_source == "estimated"
    cx, cy = scene.gear_center_px
    assert abs(rep.gear_axis_px[0] - cx) < 1.0 and abs(rep.gear_axis_px[1] - cy) < 1.0
    assert rep.contact_radius_px * scene.mm_per_px == pytest.approx(scene.drive_radius_mm,
                                                                     abs=0.03)
    assert rep.tracks_kept["gear"] >= 6 and rep.tracks_kept["after"] >= 6
    assert rep.width_status == "ok"
    img = cv2.imread(str(out))
    before = rois["before"]
    crop = img[before.y:before.y1, before.x:before.x1]
    # the used edge points and the fitted edge lines are drawn in yellow (BGR 0,230,255)
    yellow = np.all(crop == (0, 230, 255), axis=2)
    assert yellow.sum() >= 1.5 * before.h
    cols = np.flatnonzero(yellow.any(axis=0))
    assert cols.min() < 0.25 * before.w and cols.max() > 0.75 * before.w
    # kept tracks of the after ROI are drawn as filled dots in its colour
    after = rois["after"]
    blue = np.all(img[after.y:after.y1, after.x:after.x1] == (255, 140, 40), axis=2)
    assert blue.sum() >= 6 * 5


def test_inspect_shows_a_refused_width_and_competing_edges() -> None:
    # two filament-like bands of a plausible width side by side: refused as ambiguous,
    # the problem is listed and both competing pairs are drawn (magenta)
    frame = np.full((200, 400), 30, np.uint8)
    frame[:, 60:150] = 170
    frame[:, 220:310] = 170
    frame = cv2.GaussianBlur(frame, (0, 0), 0.8)
    rois = {"before": Roi("before", 20, 40, 340, 100)}
    img, rep = annotate_frame(frame, rois, mm_per_px=0.02, diameter_mm=1.75)
    assert rep.width_status == "ambiguous" and rep.filament_width_px is None
    assert any("width refused (ambiguous)" in p for p in rep.problems)
    magenta = np.all(img[40:140] == (255, 0, 255), axis=2)
    cols = set(np.flatnonzero(magenta.any(axis=0)).tolist())
    for edge in (60, 150, 220, 310):
        assert any(abs(c - edge) <= 2 for c in cols), edge
