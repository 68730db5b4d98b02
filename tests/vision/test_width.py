"""Width from the derivative extrema across the filament [003 §2.2] on exact edge images."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from flowtwin.vision.width import measure_width_px


def _strip(xl: float, xr: float, *, h: int = 60, w: int = 140, tilt_rad: float = 0.0,
           fil: float = 180.0, bg: float = 40.0, blur: float = 0.8,
           noise: float = 0.0, seed: int = 0) -> np.ndarray:
    """A filament between xl and xr (at the middle row), exact pixel-area coverage."""
    y = np.arange(h, dtype=np.float64)[:, None]
    x = np.arange(w, dtype=np.float64)[None, :]
    shift = (y - (h - 1) / 2) * math.tan(tilt_rad)
    half = 0.5 * (xr - xl) / math.cos(tilt_rad)      # horizontal half-width of a tilted band
    mid = 0.5 * (xl + xr) + shift
    cover = np.clip(x + 0.5 - (mid - half), 0, 1) * np.clip((mid + half) - x + 0.5, 0, 1)
    img = bg + (fil - bg) * cover
    img = cv2.GaussianBlur(img.astype(np.float32), (0, 0), blur)
    if noise:
        img = img + np.random.default_rng(seed).normal(0.0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("offset", [0.0, 0.13, 0.37, 0.5, 0.71, 0.94])
def test_subpixel_width_of_a_sharp_band(offset: float) -> None:
    # 87.5 px = 1.75 mm at 20 µm/px [003 §2.1]; quantisation to 8 bits and the parabola
    # fit leave < 0.05 px (1 µm) whatever the sub-pixel phase of the edges
    m = measure_width_px(_strip(30.0 + offset, 117.5 + offset * 0.3))
    assert m.ok
    assert m.width_px == pytest.approx(87.5 - 0.7 * offset, abs=0.05)
    assert m.left_px == pytest.approx(30.0 + offset, abs=0.05)


def test_tilted_filament_reports_perpendicular_width() -> None:
    tilt = math.radians(4.0)
    m = measure_width_px(_strip(30.0, 110.0, tilt_rad=tilt, h=80))
    assert m.ok and m.tilt_rad == pytest.approx(tilt, abs=2e-3)
    # each row sees 80/cos(4°) = 80.2 px; the measurement corrects it back to 80
    assert m.width_px == pytest.approx(80.0, abs=0.05)


def test_dark_filament_on_bright_background_and_noise() -> None:
    m = measure_width_px(_strip(25.25, 100.75, fil=30.0, bg=200.0, noise=3.0, seed=1))
    assert m.ok and m.width_px == pytest.approx(75.5, abs=0.1)


def test_missing_edges_are_reported_not_guessed() -> None:
    flat = np.full((40, 100), 120, np.uint8)
    m = measure_width_px(flat)
    assert not m.ok and math.isnan(m.width_px) and "no pair of filament edges" in m.reason
    one_edge = _strip(50.0, 400.0, w=100)         # right edge outside the ROI
    m = measure_width_px(one_edge)
    assert not m.ok and math.isnan(m.width_px)
    faint = _strip(30.0, 90.0, fil=41.0, bg=40.0, noise=2.0)
    assert not measure_width_px(faint).ok
