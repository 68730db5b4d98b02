"""The coarse-grid wide filters against OpenCV's own, and against what they must mean."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from flowtwin.calibration.image.smooth import (
    COARSE_RADIUS_PX,
    COARSE_SIGMA_PX,
    local_max,
    wide_gaussian,
)


def _photo_like(h: int = 700, w: int = 1100, seed: int = 3, pitch: int = 50) -> np.ndarray:
    """Thin light lines ``pitch`` px apart on a textured, unevenly lit sheet (float32,
    0-255)."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    img = 40.0 + 30.0 * xx / w + 20.0 * np.sin(yy / 170.0)
    img += rng.normal(0.0, 6.0, (h, w))
    for y0 in range(30, h - 30, pitch):
        x0, x1 = 80 + 3 * y0 % 40, w - 60 - y0 % 70
        img[y0:y0 + 5, x0:x1] += 150.0 * (0.6 + 0.4 * xx[y0:y0 + 5, x0:x1] / w)
    return np.clip(img, 0, 255).astype(np.float32)


@pytest.mark.parametrize("sigma", [25.0, 50.0, 100.0])
def test_wide_gaussian_is_opencvs_within_a_percent_of_the_range(sigma: float) -> None:
    img = _photo_like()
    exact = cv2.GaussianBlur(img, (0, 0), sigma)
    coarse = wide_gaussian(img, sigma)
    assert coarse.shape == img.shape and coarse.dtype == np.float32
    m = int(3 * sigma)
    inner = np.abs(coarse - exact)[m:-m, m:-m]
    assert inner.max() <= 0.01 * np.ptp(img)
    # up to the borders, where the two pad the image differently: within 2 %
    assert np.abs(coarse - exact).max() <= 0.02 * np.ptp(img)


def test_narrow_filters_are_opencvs_own() -> None:
    img = _photo_like(300, 400)
    sigma = 3 * COARSE_SIGMA_PX - 0.5
    assert np.array_equal(wide_gaussian(img, sigma), cv2.GaussianBlur(img, (0, 0), sigma))
    r = int(2 * COARSE_RADIUS_PX) - 1
    se = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    assert np.array_equal(local_max(img, r, 10.0),
                          cv2.GaussianBlur(cv2.dilate(img, se), (0, 0), 10.0))


@pytest.mark.parametrize("radius", [64, 100, 150])
def test_local_max_is_opencvs_disc_dilation_within_a_percent(radius: int) -> None:
    """As the line reader uses it: a disc of two pitches, a Gaussian of one."""
    img = _photo_like(pitch=radius // 2)
    se = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
    exact = cv2.GaussianBlur(cv2.dilate(img, se), (0, 0), radius / 2)
    coarse = local_max(img, radius, radius / 2)
    assert coarse.shape == img.shape and coarse.dtype == np.float32
    assert np.percentile(np.abs(coarse - exact), 99) <= 0.01 * np.ptp(img)
    assert np.abs(coarse - exact).max() <= 0.025 * np.ptp(img)


def test_local_max_reaches_its_radius_from_a_point() -> None:
    """One bright pixel: before the smoothing, the set it lights is a disc of the radius;
    with a narrow Gaussian, the half level lies on that circle to within a block."""
    h = w = 601
    img = np.zeros((h, w), np.float32)
    img[300, 300] = 100.0
    radius = 128
    out = local_max(img, radius, 2.0)
    f = int(radius // COARSE_RADIUS_PX)
    for dy, dx in [(0, 1), (1, 0), (0, -1), (-1, 0), (1, 1), (-1, 1)]:
        n = np.hypot(dy, dx)
        ray = [out[int(round(300 + dy * s / n)), int(round(300 + dx * s / n))]
               for s in range(0, 200)]
        edge = next(s for s, v in enumerate(ray) if v < 50.0)
        assert abs(edge - radius) <= f + 1, (dy, dx, edge)
    assert out[300, 300] == pytest.approx(100.0, rel=1e-6)
    assert out[0, 0] == 0.0


def test_a_constant_image_stays_constant() -> None:
    img = np.full((333, 517), 87.5, np.float32)
    assert np.allclose(wide_gaussian(img, 80.0), 87.5, rtol=0, atol=1e-3)
    assert np.allclose(local_max(img, 90, 40.0), 87.5, rtol=0, atol=1e-3)
