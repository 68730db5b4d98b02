"""Measurement equations against their sources: [003 Eqs. 3–5], [000 Eq. 1]."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from flowtwin.errors import VisionError
from flowtwin.vision.flow import (
    gaussian_smooth,
    slip_fraction,
    speed_mm_s,
    surface_speed_mm_s,
    volume_flow_mm3_s,
)
from flowtwin.vision.width import calibration_factor


def test_eq4_calibration_with_the_papers_magnification() -> None:
    # [003 §2.1]: ~20 µm/pixel; a 2.85 mm filament is then 142.5 px wide
    assert calibration_factor(2.85, 142.5) == pytest.approx(0.020, rel=1e-12)
    with pytest.raises(VisionError, match="no filament width"):
        calibration_factor(1.75, math.nan)
    with pytest.raises(VisionError, match="must be positive"):
        calibration_factor(0.0, 80.0)


def test_eq5_speed_from_step_and_the_papers_frame_rate() -> None:
    # [003 §2.1]: 70 ms between frames, 20 µm/px: the "small distances (6–7 pixels)" per
    # frame are 1.7–2.0 mm/s, and the stated 2.5 mm/s limit is 8.75 px per frame
    v = speed_mm_s(np.array([6.0, 7.0, 8.75]), np.full(3, 0.070), 0.020)
    assert_allclose(v, [6 * 0.02 / 0.07, 2.0, 2.5], rtol=1e-12)
    # each step divides by its own capture interval: a doubled interval, same speed
    assert_allclose(speed_mm_s([7.0, 14.0], [0.07, 0.14], 0.02), [2.0, 2.0])


def test_eq3_surface_speed_of_the_papers_gear() -> None:
    # [003 §2]: 8 mm outer diameter gear; at 0.5 rad/s the rim moves at 2 mm/s
    assert_allclose(surface_speed_mm_s([0.5, -1.0], 4.0), [2.0, -4.0])


def test_eq1_slip_fraction_and_undefined_when_gear_stopped() -> None:
    # [000 Eq. 1] s = (ω·r − v_fil)/(ω·r); [003 §3.1] reports ~10 % at 215 °C
    s = slip_fraction([2.0, 2.0, 2.0, 0.0, 0.01, -1.0], [1.8, 2.0, 0.0, 0.0, 0.01, -0.9],
                      min_gear_speed_mm_s=0.02)
    assert_allclose(s[:3], [0.1, 0.0, 1.0], atol=1e-12)
    assert np.isnan(s[3]) and np.isnan(s[4])
    assert s[5] == pytest.approx(0.1)          # retraction: same definition


def test_volume_flow_round_filament() -> None:
    # [003 §3.1]: volume from length and width "assuming perfect roundness"
    q = volume_flow_mm3_s([2.0, 1.0], [2.85, 1.75])
    assert_allclose(q, [2.0 * math.pi * 2.85 ** 2 / 4, math.pi * 1.75 ** 2 / 4])


def test_gaussian_smoothing_preserves_constants_and_ramps_and_skips_nan() -> None:
    t = np.arange(200) / 30.0
    assert_allclose(gaussian_smooth(t, np.full(200, 3.5), 0.2), 3.5, rtol=1e-12)
    ramp = 2.0 * t + 1.0
    # a symmetric window reproduces a ramp away from the ends (±4σ = 0.8 s = 24 samples)
    assert_allclose(gaussian_smooth(t, ramp, 0.2)[30:-30], ramp[30:-30], rtol=1e-9)
    holey = ramp.copy()
    holey[50:60] = np.nan
    out = gaussian_smooth(t, holey, 0.2)
    assert np.all(np.isfinite(out))            # the window bridges the hole
    # uneven sampling (dropped frames): constants stay exact; a ramp is off only by the
    # kernel-regression bias slope·E_w[t_j − t_i]; with at most 3 of the ~15 samples per σ
    # missing on one side that is below slope·σ·(3/15) = 0.08
    keep = np.ones(200, dtype=bool)
    keep[[70, 71, 72, 100, 130, 131]] = False
    assert_allclose(gaussian_smooth(t[keep], np.full(keep.sum(), 2.0), 0.2), 2.0, rtol=1e-12)
    assert_allclose(gaussian_smooth(t[keep], ramp[keep], 0.2)[40:-40], ramp[keep][40:-40],
                    atol=2.0 * 0.2 * 3 / 15)
    # nothing valid within ±4σ: stays NaN, never invented
    gap = ramp.copy()
    gap[80:140] = np.nan
    assert np.isnan(gaussian_smooth(t, gap, 0.2)[110])
    assert gaussian_smooth(np.zeros(0), np.zeros(0), 0.2).size == 0
