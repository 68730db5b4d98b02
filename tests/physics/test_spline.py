"""The clamped spline of [004 Eqs. 20–21] against analytic cases and scipy's CubicSpline."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.interpolate import CubicSpline

from flowtwin.errors import DataError
from flowtwin.physics.spline import clamped_spline


def road(x: np.ndarray) -> np.ndarray:
    return x ** 4 + x ** 3 + x ** 2 + x        # [004 Fig. 7c]


def road_slope(x: np.ndarray) -> np.ndarray:
    return 4 * x ** 3 + 3 * x ** 2 + 2 * x + 1


def test_interpolates_nodes_end_slopes_and_is_c2() -> None:
    x = np.linspace(0.0, 1.0, 11)
    s = clamped_spline(x, road(x), dy_start=1.0, dy_end=10.0)
    assert_allclose(s(x), road(x), atol=1e-14)
    assert_allclose(s.derivative(np.array([0.0, 1.0])), [1.0, 10.0], rtol=1e-12)
    eps = 1e-7
    inner = x[1:-1]
    # first derivative continuous at the knots; second derivative = moments
    assert_allclose(s.derivative(inner - eps), s.derivative(inner + eps), atol=1e-5)
    second = (s.derivative(inner + eps) - s.derivative(inner - eps)) / (2 * eps)
    assert_allclose(second, s.moments[1:-1], rtol=1e-4)


@pytest.mark.parametrize("n_knots", [2, 3, 4, 11, 40])
def test_agrees_with_scipy_clamped_spline(n_knots: int) -> None:
    # Random non-uniform knots (seeded); scipy with the same end slopes is the same spline.
    rng = np.random.default_rng(n_knots)
    x = np.sort(np.concatenate([[0.0, 1.0], rng.uniform(0.0, 1.0, n_knots - 2)]))
    y = road(x)
    ours = clamped_spline(x, y, dy_start=1.0, dy_end=10.0)
    ref = CubicSpline(x, y, bc_type=((1, 1.0), (1, 10.0)))
    xq = np.linspace(0.0, 1.0, 501)
    assert_allclose(ours(xq), ref(xq), atol=1e-12)
    assert_allclose(ours.derivative(xq), ref(xq, 1), atol=1e-10)


def test_zero_end_slopes_equal_scipy_bc_clamped() -> None:
    # scipy's bc_type='clamped' means S' = 0 at both ends.
    x = np.linspace(-1.0, 1.0, 9)
    y = np.cos(np.pi * x / 2)
    ours = clamped_spline(x, y, dy_start=0.0, dy_end=0.0)
    xq = np.linspace(-1.0, 1.0, 201)
    assert_allclose(ours(xq), CubicSpline(x, y, bc_type="clamped")(xq), atol=1e-13)


def test_reproduces_a_cubic_exactly() -> None:
    x = np.array([0.0, 0.3, 0.5, 1.2, 2.0])
    f = 2 * x ** 3 - x ** 2 + 0.5 * x - 1
    s = clamped_spline(x, f, dy_start=0.5, dy_end=6 * 4 - 4 + 0.5)
    xq = np.linspace(0.0, 2.0, 101)
    assert_allclose(s(xq), 2 * xq ** 3 - xq ** 2 + 0.5 * xq - 1, atol=1e-12)


def test_rejects_bad_knots() -> None:
    with pytest.raises(DataError, match="strictly increasing"):
        clamped_spline([0.0, 1.0, 1.0], [0.0, 1.0, 2.0], dy_start=0.0, dy_end=0.0)
    with pytest.raises(DataError, match="equal length"):
        clamped_spline([0.0, 1.0], [0.0], dy_start=0.0, dy_end=0.0)
