"""The lag step over a segment of constant acceleration [001 Eqs. 5, 10, 15, Fig. 8].

Known answers: the φ-functions against 50-digit decimal arithmetic, :func:`lag_linear`
against the textbook closed form and the step response of [001 Eq. 15], :func:`lag_step`
against a tight numerical integration of ``x' = v − max(x, 0)/K`` and against the
no-backflow crossing time ``K·ln((x0 − v·K)/(−v·K))`` of a retraction.
"""

from __future__ import annotations

import math
from decimal import Decimal, getcontext

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from flowtwin.errors import DataError
from flowtwin.physics.lag import lag_linear, lag_phi, lag_step, step_response_fraction


def _phi_decimal(y: float) -> tuple[float, float, float, float]:
    getcontext().prec = 60
    z = Decimal(-y)
    ez = z.exp()
    return (float(ez), float((ez - 1) / z), float((ez - 1 - z) / (z * z)),
            float((ez - 1 - z - z * z / 2) / (z * z * z)))


@pytest.mark.parametrize("y", [1e-9, 1e-4, 0.01, 0.3, 0.999, 1.0, 1.001, 2.0, 7.5, 40.0])
def test_phi_functions_to_rounding(y: float) -> None:
    got = lag_phi(y)
    for g, r in zip(got, _phi_decimal(y), strict=True):
        assert g == pytest.approx(r, rel=2e-15)
    assert lag_phi(0.0) == (1.0, 1.0, 0.5, 1.0 / 6.0)


def test_linear_equals_the_textbook_closed_form() -> None:
    # x(T) = K(v0 + a(T − K)) + (x0 − K(v0 − aK))e^(−T/K) (exact where T ~ K: no cancellation)
    rng = np.random.default_rng(3)
    for _ in range(200):
        k, x0, v0, a = rng.uniform(0.02, 0.3), rng.uniform(-1, 1), rng.uniform(-20, 20), \
            rng.uniform(-500, 500)
        t = rng.uniform(0.5, 3.0) * k
        x, ix = lag_linear(x0, v0, a, t, k)
        c = x0 - k * (v0 - a * k)
        ref = k * (v0 + a * (t - k)) + c * math.exp(-t / k)
        ref_int = k * (v0 * t + a * (t * t / 2 - k * t)) + c * k * -math.expm1(-t / k)
        scale = abs(x0) + abs(v0) * k + abs(a) * k * k
        assert x == pytest.approx(ref, abs=1e-13 * scale)
        assert ix == pytest.approx(ref_int, abs=1e-13 * scale * t)


def test_linear_feed_step_is_eq15() -> None:
    # a feed step from rest: v*/v = x/(K·v) = 1 − exp(−t/K) [001 Eq. 15]
    k = 0.06
    for t in (1e-6, 0.01, 0.06, 0.3):
        x, _ = lag_linear(0.0, 2.0, 0.0, t, k)
        assert x / (k * 2.0) == pytest.approx(float(step_response_fraction(t, k)), rel=1e-15)


def test_short_segment_has_no_cancellation() -> None:
    # T = 1e-9 K: x(T) = x0 + (v0 − x0/K)T + O(T²) to full precision
    k, t = 0.05, 5e-11
    x, ix = lag_linear(0.3, 4.0, 100.0, t, k)
    assert x == pytest.approx(0.3 + (4.0 - 0.3 / k) * t, rel=1e-15)
    assert ix == pytest.approx(0.3 * t, rel=1e-9)


def _reference(x0: float, v0: float, a: float, t_end: float, k: float) -> tuple[float, float]:
    def rhs(t: float, y: np.ndarray) -> list[float]:
        xp = max(y[0], 0.0)
        return [v0 + a * t - xp / k, xp / k]

    sol = solve_ivp(rhs, (0.0, t_end), [x0, 0.0], method="DOP853", rtol=1e-12, atol=1e-14,
                    max_step=t_end / 400)
    return float(sol.y[0, -1]), float(sol.y[1, -1])


def test_lag_step_against_numerical_integration() -> None:
    # random segments through every case: feed and retraction, gaps closing, ramps that
    # turn around (two crossings of 0)
    rng = np.random.default_rng(11)
    worst = 0.0
    for _ in range(150):
        k = float(rng.uniform(0.02, 0.5))
        x0 = float(rng.uniform(-0.5, 0.5))
        v0 = float(rng.uniform(-10, 10))
        a = float(rng.choice([0.0, rng.uniform(-200, 200)]))
        t = float(rng.uniform(0.01, 1.0))
        step = lag_step(x0, v0, a, t, k)
        ref_x, ref_out = _reference(x0, v0, a, t, k)
        scale = abs(x0) + abs(v0) * t + abs(a) * t * t
        worst = max(worst, abs(step.x_mm - ref_x) / scale, abs(step.out_mm - ref_out) / scale)
        assert step.out_mm >= 0.0                                   # no backflow
        assert step.fed_mm == pytest.approx(v0 * t + a * t * t / 2, abs=1e-15 * scale)
        assert step.fed_mm - step.out_mm == pytest.approx(step.x_mm - x0, abs=1e-13 * scale)
    assert worst < 1e-9


def test_retraction_crossing_in_closed_form() -> None:
    # constant retraction from a compressed column: x reaches 0 at K·ln((x0 − vK)/(−vK)),
    # then follows the gear with nothing out
    k, x0, v = 0.08, 0.2, -5.0
    t0 = k * math.log((x0 - v * k) / (-v * k))
    step = lag_step(x0, v, 0.0, t0 + 0.01, k)
    assert step.x_mm == pytest.approx(v * 0.01, rel=1e-12)
    assert step.out_mm == pytest.approx(v * t0 - 0.0 + x0, rel=1e-12)   # fed − Δx


def test_two_crossings_on_one_ramp() -> None:
    # v from −8 to +8 mm/s: x falls through 0, waits, is pushed back and rises through 0
    k = 0.05
    step = lag_step(0.05, -8.0, 16.0, 1.0, k)
    ref_x, ref_out = _reference(0.05, -8.0, 16.0, 1.0, k)
    assert step.x_mm == pytest.approx(ref_x, rel=1e-9)
    assert step.out_mm == pytest.approx(ref_out, rel=1e-9)
    # the gap: the filament pulled back beyond the crossing is fed again before melt flows
    gap = lag_step(0.0, -8.0, 16.0, 1.0, k)
    assert gap.out_mm == pytest.approx(_reference(0.0, -8.0, 16.0, 1.0, k)[1], rel=1e-9)


def test_gap_feeds_without_output_until_closed() -> None:
    step = lag_step(-1.0, 16.0, 0.0, 0.05, 0.06)      # 0.8 mm forward into a 1 mm gap
    assert step.out_mm == 0.0
    assert step.x_mm == pytest.approx(-0.2)
    free = lag_step(-0.5, -3.0, 0.0, 1.0, 0.06)        # retracting further: nothing flows
    assert (free.x_mm, free.out_mm) == (pytest.approx(-3.5), 0.0)


@pytest.mark.parametrize(("t", "k"), [(-1.0, 0.1), (math.nan, 0.1), (1.0, 0.0), (1.0, math.inf)])
def test_bad_segment_refused(t: float, k: float) -> None:
    with pytest.raises(DataError):
        lag_step(0.0, 1.0, 0.0, t, k)
    with pytest.raises(DataError):
        lag_linear(0.0, 1.0, 0.0, t, k)
