"""The banded Cholesky factorisation of the interior-point steps (LAPACK, one BLAS thread)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from flowtwin.compensation._qp import _BandedFactor, _Kkt


def _band_spd(n: int, b: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    m = np.zeros((n, n))
    for k in range(b + 1):
        v = rng.normal(size=n - k)
        m += np.diag(v, -k) + (np.diag(v, k) if k else 0.0)
    # diagonally dominant: positive definite
    m += np.diag(np.sum(np.abs(m), axis=1) + 1.0)
    return m


def test_banded_step_matrix_solves_like_numpy() -> None:
    """``H + Cᵀ·diag(d)·C`` (band ``b``, C = identity) factorised in band storage solves
    like numpy's dense solve, and numpy's factor is what LAPACK returns."""
    for n, b, seed in [(40, 3, 0), (25, 11, 1), (60, 1, 2), (5, 0, 3)]:
        m = _band_spd(n, b, seed)
        d = np.random.default_rng(seed + 10).uniform(0.5, 2.0, size=n)
        kkt = _Kkt(sp.csc_matrix(m), sp.csr_matrix(sp.identity(n)))
        assert kkt.banded and kkt.b == b
        fac = kkt.factor(d)
        assert isinstance(fac, _BandedFactor)
        full = m + np.diag(d)
        upper = np.linalg.cholesky(full).T
        for k in range(b + 1):  # LAPACK upper band storage: ab[b − k, j] = U[j − k, j]
            np.testing.assert_allclose(fac.factor[b - k, k:], np.diag(upper, k),
                                       rtol=1e-9, atol=1e-9)
        rhs = np.random.default_rng(seed).normal(size=n)
        np.testing.assert_allclose(full @ fac.solve(rhs), rhs, rtol=1e-10, atol=1e-10)


def test_indefinite_step_matrix_is_not_factorised_as_banded() -> None:
    m = np.array([[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]])  # eigenvalue −1
    kkt = _Kkt(sp.csc_matrix(m), sp.csr_matrix(sp.identity(3)))
    assert kkt.banded
    fac = kkt.factor(np.zeros(3))
    assert not isinstance(fac, _BandedFactor)  # the LU fallback takes it
    rhs = np.array([1.0, 2.0, 3.0])
    np.testing.assert_allclose(m @ fac.solve(rhs), rhs, rtol=1e-9)
