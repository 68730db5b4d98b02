"""Width from the derivative extrema across the filament [003 §2.2] on exact edge images."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from flowtwin.vision.width import expected_width_px, measure_width_px


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


# --- the plausibility model: outer edges of one filament, or a refusal -----------------

def _profile_image(cols: np.ndarray, h: int = 60, blur: float = 0.8,
                   noise: float = 1.0, seed: int = 3) -> np.ndarray:
    """Rows of the same profile (one value per column, DN), blurred and noisy."""
    img = np.repeat(cols[None, :].astype(np.float32), h, axis=0)
    img = cv2.GaussianBlur(img, (0, 0), blur)
    img = img + np.random.default_rng(seed).normal(0.0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def _band(w: int, x0: float, x1: float, level: float, bg: np.ndarray | float
          ) -> np.ndarray:
    """Pixel-area coverage of [x0, x1] painted over ``bg``."""
    x = np.arange(w, dtype=np.float64)
    cover = np.clip(x + 0.5 - x0, 0, 1) * np.clip(x1 - x + 0.5, 0, 1)
    return np.asarray(bg, dtype=np.float64) * (1 - cover) + level * cover


def test_highlight_and_teeth_marks_inside_do_not_move_the_outer_edges() -> None:
    w = 200
    cols = _band(w, 40.3, 150.8, 150.0, 35.0)          # 110.5 px filament
    cols = _band(w, 70.0, 76.0, 250.0, cols)           # a specular stripe
    cols = _band(w, 110.0, 113.0, 95.0, cols)          # a dark tooth mark
    m = measure_width_px(_profile_image(cols), expected_px=((95.0, 125.0),))
    assert m.ok and m.status == "ok"
    assert m.width_px == pytest.approx(110.5, abs=0.15)
    assert m.left_px == pytest.approx(40.3, abs=0.15)


def test_the_bearing_edge_beside_the_filament_is_another_object() -> None:
    # [003]'s rig: the idler bearing's dark rim and its glint right of the filament; the
    # strongest falling edge is the bearing's (the old method read 19 px, 0.39 mm)
    w = 220
    cols = _band(w, 30.2, 150.7, 160.0, 30.0)           # filament, 120.5 px
    cols = _band(w, 158.0, 166.0, 240.0, cols)          # glint on the bearing's rim
    cols = _band(w, 166.0, 220.0, 5.0, cols)            # dark bearing
    m = measure_width_px(_profile_image(cols), expected_px=((100.0, 140.0),))
    assert m.ok and m.width_px == pytest.approx(120.5, abs=0.15)
    # without a nominal width (scale unknown) the same: the glint is a separate object
    m = measure_width_px(_profile_image(cols))
    assert m.ok and m.width_px == pytest.approx(120.5, abs=0.15)


def test_two_plausible_filaments_are_refused_as_ambiguous() -> None:
    w = 260
    cols = _band(w, 20.0, 110.0, 160.0, 30.0)
    cols = _band(w, 150.0, 240.0, 160.0, cols)
    m = measure_width_px(_profile_image(cols), expected_px=((80.0, 100.0),))
    assert not m.ok and m.status == "ambiguous" and math.isnan(m.width_px)
    assert "several plausible edge pairs" in m.reason and len(m.rejected) >= 2


def test_rows_that_disagree_are_refused() -> None:
    # the upper half shows one filament, the lower half another one (a different object
    # entering the ROI): no consistent pair of edges along the rows
    top = _profile_image(_band(240, 20.0, 110.0, 160.0, 30.0), h=40)
    bottom = _profile_image(_band(240, 120.0, 210.0, 160.0, 30.0), h=40, seed=4)
    m = measure_width_px(np.concatenate([top, bottom]), expected_px=((80.0, 100.0),))
    assert not m.ok and m.status == "ambiguous"
    assert "agree in" in m.reason


def test_expected_width_range_and_refusal_outside_it() -> None:
    assert expected_width_px(None) is None
    (lo, hi), = expected_width_px(0.02, 1.75)
    assert lo == pytest.approx(0.95 * 87.5) and hi == pytest.approx(1.05 * 87.5)
    std = expected_width_px(0.02)
    assert std is not None and len(std) == 2
    assert std[1][0] == pytest.approx(0.92 * 142.5) and std[1][1] == pytest.approx(1.08 * 142.5)
    # an 87.5 px band is 1.75 mm at 20 µm/px: refused if 2.85 mm filament is expected
    img = _strip(30.0, 117.5)
    assert measure_width_px(img, expected_px=expected_width_px(0.02, 1.75)).ok
    m = measure_width_px(img, expected_px=expected_width_px(0.02, 2.85))
    assert not m.ok and m.status == "no_edges" and "expected width" in m.reason


def test_a_roi_that_ends_on_the_edges_is_refused() -> None:
    # both edges at the ROI's borders: the background is not resolved
    img = _strip(-0.5, 99.5, w=100)
    m = measure_width_px(img)
    assert not m.ok and math.isnan(m.width_px)
