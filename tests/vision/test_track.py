"""Feature tracking on exactly moved textures: translation, rotation, no texture."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowtwin.vision.config import TrackingParams
from flowtwin.vision.features import (
    detect_features,
    min_eigenvalue_at,
    min_eigenvalue_map,
    noise_sigma_dn,
    robust_mean,
)
from flowtwin.vision.roi import Roi
from flowtwin.vision.track import RoiTracker


def test_robust_mean_drops_outliers_and_weights_by_lever() -> None:
    vals = np.array([1.00, 1.02, 0.98, 1.01, 0.99, 5.0, -3.0])
    mean, inl = robust_mean(vals)
    assert mean == pytest.approx(1.0, abs=1e-9) and inl.tolist() == [True] * 5 + [False] * 2
    # angles with lever arms: weighted by r², so the mean is the least-squares rotation
    ang = np.array([0.010, 0.012])
    mean, _ = robust_mean(ang, np.array([100.0, 200.0]), floor=1.0)
    assert mean == pytest.approx((0.010 * 1e4 + 0.012 * 4e4) / 5e4)
    assert math.isnan(robust_mean(np.zeros(0))[0])


def test_min_eigenvalue_of_a_known_pattern() -> None:
    # I = A cos(kx) + A cos(ky) with k = 2π/7: over a 7×7 block the Sobel/8 structure
    # tensor is diag(A² sin²k / 2, A² sin²k / 2) exactly, so λ_min = A² sin²(k)/2
    k, a = 2 * math.pi / 7, 20.0
    y, x = np.mgrid[0:70, 0:70]
    img = np.rint(120 + a * np.cos(k * x) + a * np.cos(k * y)).astype(np.uint8)
    lam = min_eigenvalue_map(img)[10:-10, 10:-10]
    # 8-bit rounding of the image (±0.5 DN) changes λ by well under 2 %
    assert np.median(lam) == pytest.approx(a * a * math.sin(k) ** 2 / 2, rel=0.02)
    ramp = np.tile(np.arange(70, dtype=np.uint8) * 3, (70, 1))      # one direction only
    assert float(np.max(min_eigenvalue_map(ramp)[10:-10, 10:-10])) < 1e-3
    # at points only (what detect_features uses): the map's values, borders included
    rng = np.random.default_rng(3)
    xy = np.column_stack([rng.uniform(-0.5, 69.4, 300), rng.uniform(-0.5, 69.4, 300)])
    noisy = np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)
    full = min_eigenvalue_map(noisy)
    at = min_eigenvalue_at(noisy, xy)
    assert np.allclose(at, full[np.rint(xy[:, 1]).astype(int), np.rint(xy[:, 0]).astype(int)],
                       rtol=1e-5, atol=1e-4)


def test_noise_estimate_and_no_features_in_pure_noise() -> None:
    rng = np.random.default_rng(7)
    img = np.clip(np.rint(128 + rng.normal(0, 3.0, (200, 200))), 0, 255).astype(np.uint8)
    # 8-bit rounding adds 1/12 DN² of variance: sqrt(9 + 1/12) = 3.014
    assert noise_sigma_dn(img) == pytest.approx(3.014, rel=0.03)
    assert len(detect_features(img, TrackingParams())) == 0


def _texture(size: int, rng: np.random.Generator) -> np.ndarray:
    """Periodic band-limited texture and its 2-D spectrum (for exact sub-pixel shifts)."""
    white = rng.standard_normal((size, size))
    f = np.fft.fftfreq(size)
    transfer = np.exp(-2 * (math.pi * 1.6) ** 2 * (f[:, None] ** 2 + f[None, :] ** 2))
    return np.fft.fft2(white) * transfer


def _shifted(spec: np.ndarray, dx: float, dy: float, noise: float,
             rng: np.random.Generator) -> np.ndarray:
    size = spec.shape[0]
    f = np.fft.fftfreq(size)
    phase = np.exp(-2j * math.pi * (f[None, :] * dx + f[:, None] * dy))
    img = np.real(np.fft.ifft2(spec * phase))
    img = 128 + 30 * img / img.std() + rng.normal(0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def test_translation_tracker_follows_exact_subpixel_motion() -> None:
    rng = np.random.default_rng(3)
    spec = _texture(256, rng)
    steps = [0.37] * 12 + [6.2] * 6 + [-2.5] * 4       # slow, fast, reversing
    roi = Roi("after", 90, 60, 70, 130)
    tracker = RoiTracker(roi, (256, 256), TrackingParams(), axis=(0.0, 1.0), inset_px=7)
    pos, measured = 0.0, []
    assert tracker.update(_shifted(spec, 0.1, pos, 1.0, rng), 1 / 30) is None
    for step in steps:
        pos += step
        est = tracker.update(_shifted(spec, 0.1, pos, 1.0, rng), 1 / 30)
        assert est is not None and est.valid and not est.low_texture
        measured.append(est.value)
    # per step: LK noise ~0.01 px with 1 DN noise and >= 6 tracks; 0.05 px is 5 SE
    np.testing.assert_allclose(measured, steps, atol=0.05)
    # the distance telescopes within a keyframe: far better than per-step errors add up
    assert sum(measured) == pytest.approx(sum(steps), abs=0.05)


def test_rotation_tracker_follows_exact_rotation() -> None:
    rng = np.random.default_rng(5)
    n = 60
    kvec = rng.normal(0, 0.35, (n, 2))
    phase = rng.uniform(0, 2 * math.pi, n)
    size, c = 240, (119.5, 119.5)
    y, x = np.mgrid[0:size, 0:size].astype(np.float64)

    def frame(theta: float) -> np.ndarray:
        # texture fixed to the body: evaluate at the body coordinates R(-θ)(p - c)
        co, si = math.cos(theta), math.sin(theta)
        bx = co * (x - c[0]) + si * (y - c[1])
        by = -si * (x - c[0]) + co * (y - c[1])
        img = np.zeros_like(x)
        for (kx, ky), ph in zip(kvec, phase, strict=True):
            img += np.cos(kx * bx + ky * by + ph)
        img = 128 + 35 * img / img.std() + rng.normal(0, 1.0, img.shape)
        return np.clip(np.rint(img), 0, 255).astype(np.uint8)

    roi = Roi("gear", 30, 30, 180, 180)
    tracker = RoiTracker(roi, (size, size), TrackingParams(), mode="rotation", center_px=c)
    steps = [0.004] * 8 + [0.03] * 6 + [-0.01] * 3
    theta = 0.0
    assert tracker.update(frame(theta), 1 / 30) is None
    got = []
    for step in steps:
        theta += step
        est = tracker.update(frame(theta), 1 / 30)
        assert est is not None and est.valid
        got.append(est.value)
    # 0.05 px at the ~60 px typical lever arm
    np.testing.assert_allclose(got, steps, atol=0.05 / 60)
    assert sum(got) == pytest.approx(sum(steps), abs=0.05 / 60)


def test_textureless_roi_is_flagged_not_tracked() -> None:
    rng = np.random.default_rng(1)
    roi = Roi("after", 20, 20, 60, 100)
    tracker = RoiTracker(roi, (120, 160), TrackingParams())
    for _ in range(4):
        img = np.clip(np.rint(150 + rng.normal(0, 2.0, (160, 120))), 0, 255).astype(np.uint8)
        est = tracker.update(img, 1 / 30)
    assert est is not None and not est.valid and est.low_texture and math.isnan(est.value)
