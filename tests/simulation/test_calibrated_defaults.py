"""The default twin reproduces the seeds' magnitudes (docs/spec.md §4), through the profiles."""

from __future__ import annotations

import itertools
import math

import pytest

from flowtwin.profiles import load_machine
from flowtwin.simulation.parameters import operating_point

# [001 Table II]: K at 0.1 / 0.2 / 0.3 mm layers (acceleration and deceleration averaged
# to the paper's quoted 0.09 / 0.06 / 0.045 s); the issue asks ±15 % from one fitted
# parameter of the layer-height model, and K = 0.06 s at 0.2 mm is the calibration point.
TABLE_II = {0.1: 0.09, 0.2: 0.06, 0.3: 0.045}


def test_tronvoll_lag_factor_at_0_2_mm_is_0_06_s() -> None:
    op = operating_point(load_machine("tronvoll2019"), feed_mm_s=1.0, layer_height_mm=0.2)
    assert op.lag_k_s == pytest.approx(0.06, rel=0.02)


@pytest.mark.parametrize(("layer_mm", "k_paper_s"), sorted(TABLE_II.items()))
def test_lag_factor_follows_table_ii(layer_mm: float, k_paper_s: float) -> None:
    op = operating_point(load_machine("tronvoll2019"), feed_mm_s=1.0, layer_height_mm=layer_mm)
    assert op.lag_k_s == pytest.approx(k_paper_s, rel=0.15)


def test_lag_factor_is_independent_of_feed() -> None:
    """A linear pressure drop makes K a property of the set-up, not of the flow [001 Eq. 5]."""
    m = load_machine("tronvoll2019")
    a = operating_point(m, feed_mm_s=0.5, layer_height_mm=0.2).lag_k_s
    b = operating_point(m, feed_mm_s=4.0, layer_height_mm=0.2).lag_k_s
    assert a == pytest.approx(b, rel=1e-12)


def test_greeff_slip_is_about_10_percent_at_215_c_and_2_mm_s() -> None:
    # [003 Fig. 6] reads ≈ 10 % at 215 °C and 2 mm/s; ±2 percentage points is the reading
    # accuracy of that figure
    op = operating_point(load_machine("greeff2017"), feed_mm_s=2.0, temperature_c=215.0)
    assert op.slip == pytest.approx(0.10, abs=0.02)
    assert op.nominal_force_n < op.max_feed_force_n  # no grinding at the reference point


def test_greeff_slip_rises_as_temperature_falls_and_feed_rises() -> None:
    m = load_machine("greeff2017")
    temps = [235.0, 225.0, 215.0, 205.0, 195.0]
    by_temp = [operating_point(m, feed_mm_s=2.0, temperature_c=t).slip for t in temps]
    assert all(b > a for a, b in itertools.pairwise(by_temp))
    feeds = [0.5, 1.0, 2.0, 3.0]
    by_feed = [operating_point(m, feed_mm_s=f, temperature_c=215.0).slip for f in feeds]
    assert all(b > a for a, b in itertools.pairwise(by_feed))
    assert all(0.0 < s < 1.0 and math.isfinite(s) for s in by_temp + by_feed)
