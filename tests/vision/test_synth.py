"""The synthetic camera: exact motion integrals, defects, and that the rendered images
really move and measure as the truth says (checked by methods independent of LK)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from flowtwin.errors import VisionError
from flowtwin.vision.synth import (
    MotionSeries,
    SceneSpec,
    SyntheticCamera,
    integrate_piecewise_linear,
    render_from_series,
)
from flowtwin.vision.width import measure_width_px


def test_piecewise_linear_integral_is_exact() -> None:
    t = np.array([0.0, 1.0, 3.0])
    v = np.array([2.0, 4.0, 0.0])
    # ∫0^1 (2 + 2t) = 3; ∫1^2 (4 - 2(t-1)) = 3; held after the end, extrapolated before
    got = integrate_piecewise_linear(t, v, [0.0, 0.5, 1.0, 2.0, 3.0, 4.0, -1.0])
    np.testing.assert_allclose(got, [0.0, 1.25, 3.0, 6.0, 7.0, 7.0, -2.0], atol=1e-12)


def test_motion_series_validation() -> None:
    with pytest.raises(VisionError, match="increase strictly"):
        MotionSeries(np.array([0.0, 0.0]), np.ones(2), np.ones(2), np.ones(2))
    with pytest.raises(VisionError, match="differ in length"):
        MotionSeries(np.array([0.0, 1.0]), np.ones(3), np.ones(2), np.ones(2))
    with pytest.raises(VisionError, match="width must be positive"):
        MotionSeries(np.array([0.0, 1.0]), np.ones(2), np.ones(2), np.zeros(2))
    with pytest.raises(VisionError, match="NaN"):
        MotionSeries(np.array([0.0, 1.0]), np.array([1.0, np.nan]), np.ones(2), np.ones(2))
    m = MotionSeries.constant(duration_s=2.0, gear_speed_mm_s=3.0, slip=0.2)
    assert m.filament_distance_mm(2.0) == pytest.approx(4.8)
    with pytest.raises(VisionError, match="out of range"):
        SceneSpec(noise_dn=-1.0)


def test_defects_dropped_duplicate_blank_and_determinism() -> None:
    scene = SceneSpec(dropped_frames=(3, 4), duplicate_frames=(6,), blank_frames=(8,))
    motion = MotionSeries.constant(duration_s=10 / 30, gear_speed_mm_s=2.0, slip=0.1)
    frames = list(SyntheticCamera(scene, motion).frames())
    assert [f.index for f in frames] == [0, 1, 2, 5, 6, 7, 8, 9, 10]
    assert frames[4].kind == "duplicate" and np.array_equal(frames[4].image, frames[3].image)
    assert frames[6].kind == "blank" and float(frames[6].image.std()) < 4.0
    assert frames[3].t_s == pytest.approx(5 / 30)
    again = list(SyntheticCamera(scene, motion).frames())
    assert all(np.array_equal(a.image, b.image) for a, b in zip(frames, again, strict=True))


def test_rendered_filament_moves_by_the_true_length() -> None:
    """Where the true shift is a whole number of pixels the image rows must match exactly."""
    # 1.5 mm/s = 2.5 px per frame at 20 µm/px and 30 fps: frames 0 and 2 differ by 5 px
    scene = SceneSpec(noise_dn=0.0, shot_noise=False, exposure_s=0.0, width_variation_mm=0.0)
    motion = MotionSeries.constant(duration_s=4 / 30, gear_speed_mm_s=1.5)
    frames = list(SyntheticCamera(scene, motion).frames())
    roi = scene.suggested_rois().after
    shift = (frames[2].filament_distance_mm - frames[0].filament_distance_mm) / scene.mm_per_px
    assert shift == pytest.approx(5.0, abs=1e-9)
    a = frames[0].image[roi.y:roi.y1 - 5, roi.x + 8:roi.x1 - 8].astype(int)
    b = frames[2].image[roi.y + 5:roi.y1, roi.x + 8:roi.x1 - 8].astype(int)
    c = frames[2].image[roi.y + 4:roi.y1 - 1, roi.x + 8:roi.x1 - 8].astype(int)
    # rounding to 8 bits: equal to within 1 DN; one pixel off differs by ~5 DN on average
    assert np.abs(a - b).max() <= 1
    assert np.abs(a - c).mean() > 3


def test_rendered_gear_turns_by_the_true_angle() -> None:
    """Turning frame 0 by candidate angles: the best match is at the true angle (no LK)."""
    scene = SceneSpec(noise_dn=0.0, shot_noise=False, exposure_s=0.0)
    motion = MotionSeries.constant(duration_s=8 / 30, gear_speed_mm_s=3.0)
    frames = list(SyntheticCamera(scene, motion).frames())
    cx, cy = scene.gear_center_px
    truth = frames[8].gear_angle_rad
    assert truth == pytest.approx(3.0 * 8 / 30 / scene.drive_radius_mm)
    y, x = np.mgrid[0:scene.height_px, 0:scene.width_px]
    ring = (np.hypot(x - cx, y - cy) > 60) & (np.hypot(x - cx, y - cy) < 170)
    a = frames[0].image.astype(np.float32)
    b = frames[8].image.astype(np.float32)
    deltas = np.linspace(-3e-3, 3e-3, 7)
    ssd = []
    for d in deltas:
        th = truth + d
        m = cv2.getRotationMatrix2D((cx, cy), -math.degrees(th), 1.0)
        turned = cv2.warpAffine(a, m, (scene.width_px, scene.height_px), flags=cv2.INTER_CUBIC)
        ssd.append(float(np.mean((turned[ring] - b[ring]) ** 2)))
    best = -np.polyfit(deltas, ssd, 2)[1] / (2 * np.polyfit(deltas, ssd, 2)[0])
    # 1e-4 rad is 0.017 px at the 170 px outer radius of the compared ring
    assert abs(best) < 1e-4
    assert min(ssd) == ssd[3]


def test_rendered_width_matches_truth_without_shading() -> None:
    """With a flat (backlit-like) filament the edge method sees the true silhouette."""
    scene = SceneSpec(shading=0.0, width_variation_mm=0.04, width_wavelength_mm=5.0)
    motion = MotionSeries.constant(duration_s=6 / 30, gear_speed_mm_s=2.0)
    roi = scene.suggested_rois().before
    for f in SyntheticCamera(scene, motion).frames():
        m = measure_width_px(f.image[roi.slices])
        # 2 µm = 0.1 px: parabola fit and 8-bit noise on a blurred edge
        assert m.ok and m.width_px * scene.mm_per_px == pytest.approx(f.width_mm, abs=0.002)


def test_render_from_series_follows_a_twin_time_series() -> None:
    t = np.linspace(0.0, 0.5, 6)
    gear = np.array([0.0, 1.0, 2.0, 2.0, 2.0, 2.0])
    fil = gear * 0.9
    width = np.array([1.75, 1.75, 1.80, 1.80, 1.80, 1.80])
    scene = SceneSpec(fps=20.0, width_variation_mm=0.0)
    frames = render_from_series(t, gear, fil, width, scene=scene)
    assert len(frames) == 11 and frames[-1].t_s == pytest.approx(0.5)
    expected = integrate_piecewise_linear(t, gear, [0.5])[0]
    assert frames[-1].gear_distance_mm == pytest.approx(expected)
    assert frames[-1].filament_distance_mm == pytest.approx(0.9 * expected)
    # the material at the centre row of the before ROI at time t has the series' width
    cam = SyntheticCamera(scene, MotionSeries(t, gear, fil, width))
    y_ref_mm = scene.suggested_rois().before.center[1] * scene.mm_per_px
    for tk, wk in zip(t, width, strict=True):
        m = y_ref_mm - float(cam.motion.filament_distance_mm(tk))
        assert float(cam.width_of_material(m)) == pytest.approx(wk, abs=1e-3)
    # the ROI mean mixes filament that passed before and after the change
    assert 1.75 < frames[-1].width_mm < 1.80
