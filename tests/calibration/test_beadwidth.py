"""Bead width across a straightened strip: area and edge methods on analytic bars."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from flowtwin.calibration.image.beadwidth import (
    Strip,
    area_widths,
    dark_level,
    edge_widths,
    sample_strip,
    window_widths,
)

BG, DARK = 210.0, 60.0


def _bar(width_px: float, *, rows: int = 81, cols: int = 40, blur: float = 0.0,
         centre: float = 40.3) -> np.ndarray:
    """A dark bar across the rows, exact area coverage per pixel (box pixels)."""
    r = np.arange(rows, dtype=np.float64)
    lo, hi = centre - width_px / 2, centre + width_px / 2
    cover = np.clip(np.minimum(r + 0.5, hi) - np.maximum(r - 0.5, lo), 0.0, 1.0)
    img = np.repeat((BG - (BG - DARK) * cover)[:, None], cols, axis=1).astype(np.float32)
    if blur:
        return np.asarray(cv2.GaussianBlur(img, (0, 0), sigmaX=blur, sigmaY=blur,
                                           borderType=cv2.BORDER_REPLICATE), dtype=np.float32)
    return img


@pytest.mark.parametrize("width_px", [3.3, 6.0, 11.7])
@pytest.mark.parametrize("blur", [0.0, 1.5])
def test_area_width_is_exact_and_blur_invariant(width_px: float, blur: float) -> None:
    strip = Strip(_bar(width_px, blur=blur), 0.05, 4, np.zeros(10))
    w = area_widths(strip, DARK)
    # a Gaussian blur moves grey across the edges but keeps the integral: only float32
    # rounding of 81 summed rows remains (~1e-5 px)
    np.testing.assert_allclose(w, width_px * 0.05, rtol=1e-4)


def test_dark_level_of_wide_beads() -> None:
    strips = [Strip(_bar(w, blur=0.8), 0.05, 4, np.zeros(10)) for w in (8.0, 10.0, 12.0)]
    # wide beads keep their core at the bead's grey level despite the blur
    assert dark_level(strips) == pytest.approx(DARK, abs=1.0)


def test_edge_width_on_a_blurred_wide_bar() -> None:
    strip = Strip(_bar(12.4, blur=1.5), 0.05, 4, np.zeros(10))
    w = edge_widths(strip, smooth_px=2.0)
    # the derivative extrema of a symmetric blur of a wide bar sit on its edges; the
    # parabola through three samples errs by a few hundredths of a sample
    np.testing.assert_allclose(w, 12.4 * 0.05, atol=0.1 * 0.05)


def test_edges_need_a_bead() -> None:
    flat = Strip(np.full((60, 20), BG, dtype=np.float32), 0.05, 4, np.zeros(5))
    assert np.all(np.isnan(edge_widths(flat)))
    assert np.all(np.isnan(area_widths(flat, BG)))      # no contrast: no width


def test_window_widths_drop_windows_touching_a_gap() -> None:
    cols = np.array([0.5, 0.5, 0.52, 0.48, 0.5, 0.05, 0.5, 0.5, np.nan, 0.5, 0.5, 0.5])
    w = window_widths(cols, 4, min_width_mm=0.1)
    assert w[0] == pytest.approx(0.5)
    assert math.isnan(w[1]) and math.isnan(w[2])


def test_sample_strip_straightens_a_rotated_bead() -> None:
    """A bead drawn at 30° in the image is horizontal in the strip, its width in mm."""
    scale = 10.0                        # px/mm
    th = math.radians(30.0)
    hom = np.array([[scale * math.cos(th), -scale * math.sin(th), 100.0],
                    [scale * math.sin(th), scale * math.cos(th), 60.0], [0.0, 0.0, 1.0]])
    rows, cols = np.mgrid[0:400, 0:500].astype(np.float64)
    inv = np.linalg.inv(hom)
    x = inv[0, 0] * cols + inv[0, 1] * rows + inv[0, 2]
    y = inv[1, 0] * cols + inv[1, 1] * rows + inv[1, 2]
    # bead along bed y = 5 from x = 0 to 30, 0.6 mm wide (edges antialiased over 1 px)
    dist = np.abs(y - 5.0) * scale
    inside = (x > -1.0) & (x < 31.0)
    cover = np.where(inside, np.clip(0.3 * scale - dist + 0.5, 0.0, 1.0), 0.0)
    img = (BG - (BG - DARK) * cover).astype(np.float32)
    strip = sample_strip(img, hom, np.array([0.0, 5.0]), np.array([30.0, 5.0]),
                         step_mm=0.5, half_span_mm=1.5, dv_mm=0.05)
    assert strip.positions_mm[0] == pytest.approx(0.25) and strip.per == 10
    w = window_widths(area_widths(strip, DARK), strip.per, min_width_mm=0.1)
    # the 1 px antialiasing ramp is exact for a straight edge; bilinear resampling keeps
    # the area to well under 1 % of a pixel
    np.testing.assert_allclose(w, 0.6, atol=0.004)
