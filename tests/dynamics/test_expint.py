"""Exact exponential steps and the Gauss collocation of the lag integrator."""

from __future__ import annotations

import math
from decimal import Decimal, localcontext

import numpy as np
import pytest

from flowtwin.dynamics._expint import (
    colloc_step,
    gauss_legendre_collocation,
    lag_step,
    phi_fill,
)


def _phi_ref(k: int, z: float) -> float:
    """φ_k(-z) = (e^{-z} - Σ_{i<k} (-z)^i/i!) / (-z)^k in 80-digit decimal arithmetic."""
    with localcontext() as ctx:
        ctx.prec = 80
        x = -Decimal(z)
        if x == 0:
            return 1.0 / math.factorial(k)
        head = sum((x**i / math.factorial(i) for i in range(k)), Decimal(0))
        return float((x.exp() - head) / x**k)


@pytest.mark.parametrize("z", [0.0, 1e-9, 1e-3, 0.01, 0.0101, 0.2, 0.25, 0.26, 0.5, 1.999,
                               2.0, 2.001, 7.0, 60.0, 800.0])
def test_phi_functions_match_their_definition(z):
    out = np.empty(6)
    phi_fill(z, out)
    for k in range(6):
        assert out[k] == pytest.approx(_phi_ref(k, z), rel=4e-15, abs=1e-300)


def test_lag_step_tiny_and_huge_steps():
    # T/K -> 0: x(T) ≈ x0 + (b0 - x0/K) T without cancellation; T/K huge: steady polynomial
    phi = np.empty(6)
    b = np.array([2.0, 30.0, -50.0, 400.0])
    k = 0.05
    t = 1e-9
    x, ix = lag_step(0.1, b, k, t, phi)
    assert x == pytest.approx(0.1 + (2.0 - 0.1 / k) * t, rel=1e-15)
    assert ix == pytest.approx(0.1 * t, rel=1e-7)
    x, _ = lag_step(0.1, np.array([3.0, 0, 0, 0]), k, 100.0, phi)
    assert x == pytest.approx(3.0 * k, rel=1e-15)


def test_collocation_tableau():
    c, b, a = gauss_legendre_collocation(6)
    assert b.sum() == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(a.sum(axis=1), c, atol=1e-14)
    for q in range(1, 7):  # collocation conditions: Σ_j a_ij c_j^{q-1} = c_i^q / q
        np.testing.assert_allclose(a @ c ** (q - 1), c**q / q, atol=1e-14)


def test_collocation_step_constant_coefficient():
    # v constant, s' constant: x' = v(1-kp) - βx with β = 1/K + v s'/k, exact exponential
    gl_c, gl_b, gl_a = gauss_legendre_collocation(6)
    s = gl_c.shape[0]
    scratch = [np.empty((s, s))] + [np.empty(s) for _ in range(4)]
    v, kp, sp, k, kc = 4.0, 0.02, 0.003, 0.05, 0.01
    beta = 1 / k + v * sp / kc
    h = 1.0 / beta  # β h = 1, the default bound
    coef = np.array([v, 0.0, 0.0, 0.0])
    x, ix, igx = colloc_step(0.0, coef, 0.0, h, 1 - kp, k, kc, sp, 0.0, 0.0, gl_c, gl_b, gl_a,
                             *scratch)
    x_inf = v * (1 - kp) / beta
    assert x == pytest.approx(x_inf * (1 - math.exp(-1.0)), rel=1e-12)
    assert ix == pytest.approx(x_inf * (h - (1 - math.exp(-1.0)) / beta), rel=1e-12)
    assert igx == pytest.approx(v * sp / kc * ix, rel=1e-14)
