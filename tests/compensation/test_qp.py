"""The compiled banded Cholesky factorisation of the interior-point steps."""

from __future__ import annotations

import numpy as np

from flowtwin.compensation._qp import band_cholesky, band_solve


def _band_spd(n: int, b: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    m = np.zeros((n, n))
    for k in range(b + 1):
        v = rng.normal(size=n - k)
        m += np.diag(v, -k) + (np.diag(v, k) if k else 0.0)
    # diagonally dominant: positive definite
    m += np.diag(np.sum(np.abs(m), axis=1) + 1.0)
    return m


def _lower_rows(m: np.ndarray, b: int) -> np.ndarray:
    n = m.shape[0]
    low = np.zeros((n, b + 1))
    for j in range(n):
        for k in range(0, min(b, j) + 1):
            low[j, b - k] = m[j, j - k]
    return low


def test_band_cholesky_matches_numpy() -> None:
    for n, b, seed in [(40, 3, 0), (25, 24, 1), (60, 1, 2), (5, 0, 3)]:
        m = _band_spd(n, b, seed)
        fac = _lower_rows(m, b)
        assert band_cholesky(fac)
        lower = np.linalg.cholesky(m)
        # the factor in lower-row storage equals numpy's dense factor
        np.testing.assert_allclose(fac, _lower_rows(lower, b), rtol=1e-12, atol=1e-12)
        rhs = np.random.default_rng(seed).normal(size=n)
        x = rhs.copy()
        band_solve(fac, x)
        np.testing.assert_allclose(m @ x, rhs, rtol=1e-10, atol=1e-10)


def test_band_cholesky_refuses_an_indefinite_matrix() -> None:
    m = np.array([[1.0, 2.0], [2.0, 1.0]])   # eigenvalues 3 and −1
    assert not band_cholesky(_lower_rows(m, 1))
