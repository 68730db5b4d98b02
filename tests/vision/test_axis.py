"""The gear axis from the tracked motion (flowtwin.vision.axis) and rotation mode without
``--gear-center``."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from flowtwin.errors import VisionError
from flowtwin.vision import Roi, RoiSet, estimate_gear_axis, fit_rotation_axis, measure_frames
from flowtwin.vision.synth import MotionSeries, SceneSpec

from .conftest import render, truth_for


def _turned(c: np.ndarray, p0: np.ndarray, theta: float) -> np.ndarray:
    co, si = math.cos(theta), math.sin(theta)
    r = p0 - c
    return c + np.stack([co * r[:, 0] - si * r[:, 1], si * r[:, 0] + co * r[:, 1]], 1)


def test_fit_recovers_a_known_axis_and_tells_rotation_from_translation() -> None:
    rng = np.random.default_rng(5)
    c = np.array([151.3, 222.7])
    p0s, p1s, gs = [], [], []
    for g, theta in enumerate(np.linspace(0.03, 0.25, 12)):
        # a narrow strip on the rim: 200 px from the axis, ±10 px radially
        ang = rng.uniform(-1.9, -1.3, 40)
        rad = 200.0 + rng.uniform(-10, 10, 40)
        p0 = c + np.stack([rad * np.cos(ang), rad * np.sin(ang)], 1)
        p1 = _turned(c, p0, theta) + rng.normal(0, 0.05, p0.shape)
        p0s.append(p0)
        p1s.append(p1)
        gs.append(np.full(40, g))
    p0, p1, grp = np.concatenate(p0s), np.concatenate(p1s), np.concatenate(gs)
    est = fit_rotation_axis(p0, p1, grp)
    assert est.is_rotation and est.moved
    assert np.hypot(*(np.asarray(est.center_px) - c)) < 0.3
    assert est.rms_rotation_px < 0.1 < est.rms_translation_px
    # a fifth of the points slid onto the static background: rejected as outliers
    p1_bad = p1.copy()
    p1_bad[::5] = p0[::5]
    est = fit_rotation_axis(p0, p1_bad, grp)
    assert est.is_rotation and np.hypot(*(np.asarray(est.center_px) - c)) < 0.3
    # a filament: one shift for all points is a translation, not a rotation
    shift = p0 + np.array([0.0, 7.0]) + rng.normal(0, 0.05, p0.shape)
    est = fit_rotation_axis(p0, shift, grp)
    assert not est.is_rotation and est.moved
    # nothing moved
    est = fit_rotation_axis(p0, p0 + rng.normal(0, 0.05, p0.shape), grp)
    assert not est.is_rotation and not est.moved and "did not move" in est.reason


@pytest.fixture(scope="module")
def clip():
    scene = SceneSpec(seed=8)
    motion = MotionSeries.constant(duration_s=59 / 30, gear_speed_mm_s=2.0, slip=0.12)
    return scene, render(scene, motion)


def test_axis_from_tracks_on_the_projects_renderer(clip) -> None:
    scene, frames = clip
    images = [f.image for f in frames]
    cx, cy = scene.gear_center_px
    r_tip = scene.gear_tip_radius_mm / scene.mm_per_px
    rois = {"face": scene.suggested_rois().gear,
            "rim strip": Roi("gear", int(cx - 70), int(cy - r_tip + 2), 140, 24),
            "rim box": Roi("gear", int(cx + 0.5 * r_tip), int(cy - 0.8 * r_tip), 40, 40)}
    for name, roi in rois.items():
        est = estimate_gear_axis(images, roi)
        assert est.is_rotation, (name, est.reason)
        assert np.hypot(est.center_px[0] - cx, est.center_px[1] - cy) < 1.5, name
    # the filament moves in parallel: no axis
    est = estimate_gear_axis(images, Roi("gear", int(scene.filament_x_px - 20), 300, 40, 150))
    assert not est.is_rotation and est.moved


def test_rotation_mode_without_the_gear_centre(clip) -> None:
    """A narrow strip on the gear rim, as a user may draw it, and no --gear-center: the
    axis comes from the motion and the gear speed from the rotation (the tangential
    method of [003] was valid in 1 of 240 steps on such a strip)."""
    scene, frames = clip
    cx, cy = scene.gear_center_px
    r_tip = scene.gear_tip_radius_mm / scene.mm_per_px
    strip = Roi("gear", int(cx - 70), int(cy - r_tip + 2), 140, 24)
    base = scene.vision_config(rotation=None)
    cfg = dataclasses.replace(base, rois=RoiSet(strip, base.rois.before, base.rois.after))
    seq = [f for f in frames]
    res = measure_frames(seq, cfg, frame_size=(640, 480))
    s = res.summary
    assert s.gear_mode == "rotation" and s.gear_axis_source == "estimated from the motion"
    assert s.gear_valid_frames >= 55 and s.warnings == ()
    truth = truth_for(frames, res)
    ok = np.isfinite(res.series.gear_speed_mm_s) & np.isfinite(truth.gear_speed_mm_s)
    ratio = np.sum(res.series.gear_speed_mm_s[ok]) / np.sum(truth.gear_speed_mm_s[ok])
    assert abs(ratio - 1) <= 0.01
    assert abs(s.slip - 0.12) <= 0.005
    # asked for rotation where the motion is a translation: an error, not a guess
    wrong = dataclasses.replace(cfg, gear_method="rotation", rois=RoiSet(
        Roi("gear", int(scene.filament_x_px - 20), 300, 40, 150), cfg.rois.before,
        cfg.rois.after))
    with pytest.raises(VisionError, match="no gear axis could be estimated"):
        measure_frames(seq, wrong, frame_size=(640, 480))
