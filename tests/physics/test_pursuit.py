"""The inverse of [004]: the road a nozzle path lays when the strand pursues the nozzle."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.optimize import brentq

from flowtwin.physics.nozzle_path import (
    circle_nozzle_radius_mm,
    nozzle_positions_mm,
    unit_tangents_from_slope,
)
from flowtwin.physics.pursuit import laid_road, polyline_distance_mm

L = 0.06


def test_straight_path_lays_the_same_line_l_behind() -> None:
    path = np.array([[0.0, 0.0], [3.0, 4.0]])
    out = laid_road(path, lag_mm=L, samples_per_segment=10)
    u = np.array([0.6, 0.8])
    assert_allclose(out.road_xy_mm, out.nozzle_xy_mm - L * u, atol=1e-15)   # Eq. 11 inverted


def test_distance_to_nozzle_stays_l_on_any_polyline() -> None:
    rng = np.random.default_rng(11)
    path = np.cumsum(rng.normal(0.0, 0.1, (40, 2)), axis=0)
    out = laid_road(path, lag_mm=L, samples_per_segment=8)
    gap = np.hypot(*(out.nozzle_xy_mm - out.road_xy_mm).T)
    assert_allclose(gap, L, rtol=1e-12)


def test_square_corner_rounding_matches_tractrix_analysis() -> None:
    # 90° left turn at the origin. Analytically (docs/physics.md), after the turn
    # R − C = (s − L·tanh σ)·n̂ − L·sech σ·û with σ = s/L: the road passes the corner vertex
    # at min |R − C| (where σ·tanh σ = 1) and strays furthest from the commanded path where
    # sech σ = σ − tanh σ.
    sigma_v = brentq(lambda s: s * np.tanh(s) - 1.0, 0.5, 2.0)
    vertex = np.hypot(sigma_v - np.tanh(sigma_v), 1 / np.cosh(sigma_v))
    sigma_d = brentq(lambda s: 1 / np.cosh(s) - (s - np.tanh(s)), 0.5, 3.0)
    deviation = 1 / np.cosh(sigma_d)
    assert vertex == pytest.approx(0.6627, abs=1e-4)
    assert deviation == pytest.approx(0.4823, abs=1e-4)

    path = np.array([[-10 * L, 0.0], [0.0, 0.0], [0.0, 10 * L]])
    out = laid_road(path, lag_mm=L, samples_per_segment=100_000)
    # sample spacing 1e-4·L: the discrete minima match to 1e-6 relative
    assert np.hypot(*out.road_xy_mm.T).min() / L == pytest.approx(vertex, rel=1e-6)
    commanded = np.vstack([[-11 * L, 0.0], path[1:]])  # the road starts L behind the path
    stray = polyline_distance_mm(out.road_xy_mm, commanded).max() / L
    # the maximum sits on a kink of min(d_old, d_new), slopes <= 1: error <= spacing 1e-4·L
    assert stray == pytest.approx(deviation, abs=1e-4)


def test_round_trip_recovers_fig7_road() -> None:
    # Forward [004 Eq. 19] with the exact tangent, then pursue: the road comes back.
    x = np.linspace(0.0, 1.0, 2001)
    road = np.column_stack([x, x ** 4 + x ** 3 + x ** 2 + x])
    tangent = unit_tangents_from_slope(4 * x ** 3 + 3 * x ** 2 + 2 * x + 1)
    nozzle = nozzle_positions_mm(road, tangent, lag_mm=L, height_mm=0.012)
    out = laid_road(nozzle[:, :2], lag_mm=L, initial_direction=tangent[0],
                    samples_per_segment=1)
    # the polyline nozzle path differs from the smooth one by < 1e-7 mm between samples
    assert np.max(np.abs(out.road_xy_mm - road)) < 1e-6


def test_circle_nozzle_lays_circle_of_radius_r() -> None:
    r = 1.0
    big = float(circle_nozzle_radius_mm(r, L))
    phi = np.linspace(0.0, 4 * np.pi, 40001)
    nozzle = big * np.column_stack([np.cos(phi), np.sin(phi)])
    out = laid_road(nozzle, lag_mm=L, samples_per_segment=1)
    second_turn = out.nozzle_s_mm > 2 * np.pi * big
    # converged after one turn; chord error of the 20000-gon ~ R·Δφ²/8 ≈ 1e-8 mm
    assert_allclose(np.hypot(*out.road_xy_mm[second_turn].T), r, atol=1e-6)
