"""Nozzle trajectories of [004 Eqs. 9–21] and the Fig. 7 simulation."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from flowtwin.errors import DataError
from flowtwin.physics.nozzle_path import (
    SplineMethod,
    circle_nozzle_phase_rad,
    circle_nozzle_radius_mm,
    nozzle_positions_mm,
    nozzle_trajectory_for_graph_road,
    unit_tangents_from_slope,
)

H, L = 0.012, 0.06          # [004 Fig. 7]


def road(x: np.ndarray) -> np.ndarray:
    return x ** 4 + x ** 3 + x ** 2 + x


def road_slope(x: np.ndarray) -> np.ndarray:
    return 4 * x ** 3 + 3 * x ** 2 + 2 * x + 1


def test_straight_line_eqs_10_11() -> None:
    theta, v = np.radians(35.0), 20.0
    t = np.linspace(0.0, 2.0, 9)
    road_xy = np.column_stack([v * t * np.cos(theta), v * t * np.sin(theta)])      # Eq. 8
    tangent = np.tile([np.cos(theta), np.sin(theta)], (t.size, 1))
    nozzle = nozzle_positions_mm(road_xy, tangent, lag_mm=L, height_mm=H)
    expected = np.column_stack([(L + v * t) * np.cos(theta), (L + v * t) * np.sin(theta),
                                np.full(t.size, H)])                               # Eq. 10
    assert_allclose(nozzle, expected, atol=1e-14)


def test_circle_road_eq15() -> None:
    r = 1.0
    alpha = np.linspace(0.0, 2 * np.pi, 73)
    road_xy = r * np.column_stack([np.cos(alpha), np.sin(alpha)])                  # Eq. 12
    tangent = np.column_stack([-np.sin(alpha), np.cos(alpha)])   # counter-clockwise travel
    nozzle = nozzle_positions_mm(road_xy, tangent, lag_mm=L, height_mm=H)
    radius = np.hypot(nozzle[:, 0], nozzle[:, 1])
    assert_allclose(radius, np.sqrt(r ** 2 + L ** 2), rtol=1e-14)
    assert float(circle_nozzle_radius_mm(r, L)) == pytest.approx(np.sqrt(r ** 2 + L ** 2))
    phase = np.unwrap(np.arctan2(nozzle[:, 1], nozzle[:, 0]))
    assert_allclose(phase - alpha, circle_nozzle_phase_rad(r, L), atol=1e-14)
    assert_allclose(nozzle[:, 2], H)


def test_eq19_offset_is_l_along_the_tangent() -> None:
    x = np.linspace(0.0, 1.0, 101)
    tangent = unit_tangents_from_slope(road_slope(x))
    assert_allclose(tangent[:, 1] / tangent[:, 0], road_slope(x), rtol=1e-14)    # Eq. 17
    nozzle = nozzle_positions_mm(np.column_stack([x, road(x)]), tangent, lag_mm=L,
                                 height_mm=H)
    assert_allclose(np.hypot(nozzle[:, 0] - x, nozzle[:, 1] - road(x)), L, rtol=1e-13)


def test_fig7c_paper_and_scipy_splines_agree_and_converge() -> None:
    xs = np.linspace(0.0, 1.0, 1001)
    exact = nozzle_positions_mm(np.column_stack([xs, road(xs)]),
                                unit_tangents_from_slope(road_slope(xs)), lag_mm=L,
                                height_mm=H)
    errors = []
    for n in (6, 11, 21, 41):
        xn = np.linspace(0.0, 1.0, n)
        paper, scipy = (nozzle_trajectory_for_graph_road(
            xn, road(xn), dy_start=1.0, dy_end=10.0, lag_mm=L, height_mm=H, x_samples=xs,
            method=method) for method in (SplineMethod.PAPER, SplineMethod.SCIPY))
        assert_allclose(paper.nozzle_xyz_mm, scipy.nozzle_xyz_mm, atol=1e-12)
        errors.append(float(np.max(np.abs(paper.nozzle_xyz_mm - exact))))
    # The slope of a clamped cubic spline converges as O(h³): each halving of the knot
    # spacing must cut the nozzle error by more than 6 (8 asymptotically).
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all(ratios > 6.0), ratios
    # With 11 knots the nozzle path is within 1e-5 mm of the exact one.
    assert errors[1] < 1e-5


def test_bad_tangents_raise() -> None:
    with pytest.raises(DataError, match="zero"):
        nozzle_positions_mm(np.zeros((2, 2)), np.array([[1.0, 0.0], [0.0, 0.0]]),
                            lag_mm=L, height_mm=H)
    with pytest.raises(DataError, match=r"\(n, 2\)"):
        nozzle_positions_mm(np.zeros((2, 3)), np.zeros((2, 3)), lag_mm=L, height_mm=H)
