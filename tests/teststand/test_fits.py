"""Fits of Eq. 6, Eq. 8, Eq. 9 and the maximum-force curve over record results [000]."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowtwin.errors import CalibrationError
from flowtwin.physics.drive import min_pinch_force_n
from flowtwin.teststand import (
    RecordKey,
    RecordResult,
    SlipRegression,
    fit_max_feed_force,
    fit_pinch_law,
    fit_velocity_law,
    r_squared_histogram,
)


def _result(fp: float, v: float, gradient: float, fmax: float = 50.0, se: float = 1e-5,
            r2: float = 0.95, rep: int = 0) -> RecordResult:
    return RecordResult(RecordKey("t", fp, v, rep), fmax,
                        SlipRegression(gradient, se, gradient, 0.0, r2, 500))


def test_pinch_law_exact_and_eq9() -> None:
    k_s, k_inf = 0.96, 0.0032  # roller #3 of [000 Table 3] as fractions
    rng = np.random.default_rng(0)
    results = [_result(fp, v, k_s / fp ** 2 + k_inf + 1e-6 * rng.standard_normal())
               for fp in (10.0, 20.0, 40.0, 80.0, 150.0) for v in (1.0, 5.0)]
    fit = fit_pinch_law(results)
    assert fit.k_s_n == pytest.approx(k_s, rel=1e-3)
    assert fit.k_inf_per_n == pytest.approx(k_inf, rel=1e-3)
    # Eq. 9 with k_s = 96 %N, k_inf = 0.32 %/N: sqrt(3000) = 54.8 N (docs/spec.md §3.1)
    assert fit.fp_min_n == pytest.approx(math.sqrt(3000.0), rel=1e-3)
    assert fit.fp_min_n == pytest.approx(float(min_pinch_force_n(fit.k_s_n, fit.k_inf_per_n)))
    # propagated error: numerical derivative of Eq. 9 against the analytic Jacobian
    eps = 1e-7
    d_ks = (float(min_pinch_force_n(fit.k_s_n + eps, fit.k_inf_per_n)) - fit.fp_min_n) / eps
    d_ki = (float(min_pinch_force_n(fit.k_s_n, fit.k_inf_per_n + eps * 1e-3)) - fit.fp_min_n) \
        / (eps * 1e-3)
    jac = np.array([d_ks, d_ki])
    assert fit.fp_min_err_n == pytest.approx(math.sqrt(jac @ fit.covariance @ jac), rel=1e-4)


def test_pinch_law_is_balanced_over_speeds() -> None:
    """A velocity term with zero mean over the speeds does not move k_inf, even when the
    records of one speed are far more precise than the others."""
    speeds = (0.5, 2.0, 15.0)
    term = {0.5: 0.0005, 2.0: 0.0, 15.0: -0.0005}
    se = {0.5: 1e-4, 2.0: 1e-5, 15.0: 1e-6}
    results = [_result(fp, v, 1.0 / fp ** 2 + 0.003 + term[v], se=se[v])
               for fp in (10.0, 30.0, 60.0, 100.0, 150.0) for v in speeds]
    fit = fit_pinch_law(results)
    assert fit.k_inf_per_n == pytest.approx(0.003, rel=1e-9)
    assert fit.k_s_n == pytest.approx(1.0, rel=1e-9)


def test_pinch_law_needs_three_pinch_forces() -> None:
    results = [_result(fp, 1.0, 0.003) for fp in (50.0, 100.0) for _ in range(3)]
    with pytest.raises(CalibrationError, match="three or more pinch forces") as info:
        fit_pinch_law(results)
    assert info.value.field == "pinch_force_set_n"


def test_velocity_law_exact() -> None:
    a, b, c = 0.0024, 0.0018, 0.32  # roller #3 [000 Table 3]
    rng = np.random.default_rng(1)
    results = [_result(fp, v, a + b * math.exp(-c * v) + 2e-6 * rng.standard_normal(), se=2e-6)
               for fp in (80.0, 100.0, 130.0) for v in (0.5, 1.0, 2.0, 5.0, 10.0, 15.0)]
    fit = fit_velocity_law(results)
    assert fit.velocity_dependent, fit.reason
    assert fit.a_per_n == pytest.approx(a, abs=4 * fit.a_err_per_n)
    assert fit.b_per_n == pytest.approx(b, abs=4 * (fit.b_err_per_n or 0))
    assert fit.c_s_per_mm == pytest.approx(c, abs=4 * (fit.c_err_s_per_mm or 0))
    assert fit.p_value < 1e-6


def test_velocity_law_without_dependence_is_a_constant_with_reason() -> None:
    """Rollers #6, #7: 'b -> inf, c -> inf' / 'b -> 0' in Table 3 mean s' = a."""
    rng = np.random.default_rng(2)
    results = [_result(fp, v, 0.0043 + 1e-5 * rng.standard_normal())
               for fp in (80.0, 100.0, 130.0) for v in (0.5, 1.0, 2.0, 5.0, 10.0, 15.0)]
    fit = fit_velocity_law(results)
    assert not fit.velocity_dependent
    assert fit.b_per_n is None and fit.c_s_per_mm is None
    assert fit.a_per_n == pytest.approx(0.0043, abs=4 * fit.a_err_per_n)
    assert fit.reason  # says why
    # only records at 80-130 N count
    outside = [_result(20.0, v, 0.05) for v in (0.5, 15.0)]
    assert fit_velocity_law(results + outside).a_per_n == pytest.approx(fit.a_per_n)


def test_velocity_law_needs_records_in_range() -> None:
    with pytest.raises(CalibrationError, match="80-130 N"):
        fit_velocity_law([_result(20.0, 1.0, 0.003)])
    few = fit_velocity_law([_result(100.0, v, 0.003) for v in (1.0, 2.0)])
    assert not few.velocity_dependent and "fewer than 4" in few.reason


def test_max_force_fit_recovers_a_figure_curve() -> None:
    c0, c1, c2 = 7.5, 1.52, -6.03e-3  # [000 Fig. 6]
    rng = np.random.default_rng(3)
    results = [RecordResult(RecordKey("t", fp, v, 0),
                            c0 + c1 * fp + c2 * fp * fp + 0.5 * rng.standard_normal(), None,
                            "no slip needed")
               for fp in np.arange(10.0, 151.0, 10.0) for v in (0.5, 15.0)]
    fit = fit_max_feed_force(results)
    for got, want, err in zip(fit.coeffs, (c0, c1, c2), fit.errors, strict=True):
        assert got == pytest.approx(want, abs=4 * err)
    fp = np.array([10.0, 80.0, 150.0])
    assert np.all(fit.stderr_n(fp) > 0)
    assert np.all(np.abs(fit.max_feed_force_n(fp) - (c0 + c1 * fp + c2 * fp * fp))
                  < 4 * fit.stderr_n(fp))


def test_max_force_fit_needs_three_pinch_forces() -> None:
    with pytest.raises(CalibrationError, match="three or more pinch forces"):
        fit_max_feed_force([_result(fp, 1.0, 0.003) for fp in (50.0, 100.0, 50.0, 100.0)])


def test_r_squared_histogram() -> None:
    results = [_result(80.0, 1.0, 0.003, r2=r) for r in (0.05, 0.5, 0.95, 0.99, 1.0)]
    counts, edges = r_squared_histogram(results, bins=10)
    assert counts.sum() == 5 and edges[0] == 0.0 and edges[-1] == 1.0
    assert counts[-1] == 3  # 0.95, 0.99, 1.0
