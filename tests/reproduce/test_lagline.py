"""The K-factor test line feed and the lag around it [001 Eqs. 7, 10-13, Figs. 7-13]."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowtwin.errors import DataError
from flowtwin.physics.deposition import bead_area_mm2
from flowtwin.reproduce.lagline import (
    KFactorLine,
    advance_feed,
    discrete_advance_feed,
    linear_lag_response,
    respond,
)


def test_line_geometry_and_filament() -> None:
    line = KFactorLine()
    knots = line.phase_times_s()
    # 20 + 40 + 20 mm, at rest at both ends
    assert float(line.position_mm(knots[-1])) == pytest.approx(80.0, rel=1e-12)
    assert float(line.print_speed_mm_s(knots[0])) == 0.0
    assert float(line.print_speed_mm_s(knots[-1])) == pytest.approx(0.0, abs=1e-12)
    assert float(line.print_speed_mm_s(0.5 * (knots[3] + knots[4]))) == 70.0
    # ramps of 500 mm/s²: 20→70 mm/s takes 0.1 s
    assert knots[3] - knots[2] == pytest.approx(0.1)
    # filament per mm: slicer bead 0.48 x 0.2 mm [001 Eq. 7] over the 1.75 mm filament
    assert line.e_per_mm == pytest.approx(
        float(bead_area_mm2(0.48, 0.2)) / (math.pi * 1.75 ** 2 / 4), rel=1e-12)
    feed = line.feed(rest_s=0.0)
    assert float(feed.segment_mm().sum()) == pytest.approx(80.0 * line.e_per_mm, rel=1e-12)


def test_bad_lines_and_parameters() -> None:
    with pytest.raises(DataError, match="cannot reach"):
        KFactorLine(fast_length_mm=5.0)
    with pytest.raises(DataError, match="K_LA"):
        advance_feed(KFactorLine().feed(), -0.1)
    with pytest.raises(DataError, match="step"):
        discrete_advance_feed(KFactorLine(), 0.05, 0.0)


def test_advance_moves_filament_in_time_only() -> None:
    line = KFactorLine()
    feed = line.feed()
    adv = advance_feed(feed, 0.06)
    # the line starts and ends at rest, so ∫K·dv/dt dt = 0: same filament in total
    assert float(adv.segment_mm().sum()) == pytest.approx(float(feed.segment_mm().sum()),
                                                          rel=1e-12)
    disc = discrete_advance_feed(line, 0.06, 0.001)
    assert float(disc.segment_mm().sum()) == pytest.approx(float(feed.segment_mm().sum()),
                                                           rel=1e-9)
    np.testing.assert_array_equal(advance_feed(feed, 0.0).coef, feed.coef)


def test_uncorrected_lag_equals_the_integrator_while_positive() -> None:
    """Without overcompensation the output never goes negative, so the closed-form linear
    lag [001 Eq. 10] and the integrator with no backflow must agree (both exact)."""
    line = KFactorLine()
    feed = line.feed()
    resp = respond(feed, 0.06)
    closed = linear_lag_response(feed, 0.06, resp.t_s)
    assert np.all(closed >= -1e-12)
    np.testing.assert_allclose(closed, resp.v_out_mm_s, rtol=0, atol=1e-12)


def test_line_response_conserves_filament() -> None:
    line = KFactorLine()
    resp = respond(line.feed(rest_s=1.0), 0.09, dt_s=0.0002)
    # trapezoid rule over the sampled output; the smooth output makes it accurate to ~1e-6
    out = float(np.sum(0.5 * (resp.v_out_mm_s[1:] + resp.v_out_mm_s[:-1]) * np.diff(resp.t_s)))
    assert out == pytest.approx(80.0 * line.e_per_mm, rel=1e-5)
