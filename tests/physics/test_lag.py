"""Lag factor K = k·R·A² against [001 Eqs. 2, 5, 15] and the time constant of [002]."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp

from flowtwin.physics.compliance import compliance_mm_per_n
from flowtwin.physics.lag import compression_from_flow_mm, lag_factor_s, step_response_fraction

AREA = np.pi * 1.752 ** 2 / 4
K_COL = 0.0148        # mm/N
R_HYD = 0.70          # MPa·s/mm³


def test_lag_factor_formula() -> None:
    assert float(lag_factor_s(K_COL, R_HYD, AREA)) == pytest.approx(K_COL * R_HYD * AREA ** 2)


def test_lag_factor_equals_002_time_constant() -> None:
    # [002]: V_ext − V_seal = (const·µ·A_fil·l_hot/E_hot)·dV_seal/dt with const·µ = R_hyd,
    # for a column whose compliance is its hot part only.
    l_hot, e_hot = 10.0, 414.0
    k = compliance_mm_per_n(AREA, 0.0, 3500.0, l_hot, e_hot)
    assert float(lag_factor_s(k, R_HYD, AREA)) == pytest.approx(R_HYD * AREA * l_hot / e_hot,
                                                               rel=1e-14)


def test_eq5_compression_equals_eq2_at_steady_flow() -> None:
    # [001 Eq. 5] Δl = K·Q/A must equal [001 Eq. 2] Δl = k·F with F = R·Q·A.
    q = np.array([1.0, 5.0, 12.0])
    lag = lag_factor_s(K_COL, R_HYD, AREA)
    assert_allclose(compression_from_flow_mm(lag, q, AREA), K_COL * R_HYD * q * AREA)


def test_physical_chain_has_first_order_step_response_with_time_constant_k() -> None:
    # Simulate the chain element by element — F = Δl/k, P = F/A, Q = P/R,
    # dΔl/dt = v_in − Q/A — after a feed step and compare with 1 − exp(−t/K) [001 Eq. 15].
    v_in = 0.5

    def rhs(_t: float, y: np.ndarray) -> np.ndarray:
        force = y[0] / K_COL
        q_out = force / AREA / R_HYD
        return np.array([v_in - q_out / AREA])

    lag = float(lag_factor_s(K_COL, R_HYD, AREA))
    t = np.linspace(0.0, 5 * lag, 51)
    sol = solve_ivp(rhs, (0.0, t[-1]), [0.0], t_eval=t, rtol=1e-10, atol=1e-13)
    v_out = sol.y[0] / K_COL / AREA / R_HYD / AREA
    assert_allclose(v_out / v_in, step_response_fraction(t, lag), atol=1e-8)
    assert float(step_response_fraction(lag, lag)) == pytest.approx(1 - np.exp(-1.0))
    assert float(step_response_fraction(-1.0, lag)) == 0.0
