"""The compiled envelope LDLᵀ of the interior-point steps, and the independent blocks."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from flowtwin.compensation._qp import envelope_ldl, envelope_ldl_solve, qp_blocks
from flowtwin.compensation._qp_sparse import solve_box_qp


def _band_spd(n: int, b: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    m = np.zeros((n, n))
    for k in range(b + 1):
        v = rng.normal(size=n - k)
        m += np.diag(v, -k) + (np.diag(v, k) if k else 0.0)
    # diagonally dominant: positive definite
    m += np.diag(np.sum(np.abs(m), axis=1) + 1.0)
    return m


def _envelope(m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = m.shape[0]
    first = np.array([int(np.flatnonzero(m[i, :i + 1])[0]) for i in range(n)])
    ptr = np.concatenate(([0], np.cumsum(np.arange(n) - first + 1)))
    vals = np.concatenate([m[i, first[i]:i + 1] for i in range(n)])
    return first, ptr, vals


def _ldl(m: np.ndarray, sign: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray,
                                                   np.ndarray]:
    first, ptr, vals = _envelope(m)
    out = np.empty_like(vals)
    assert envelope_ldl(first, ptr, vals, sign.astype(np.int8), out)
    return first, ptr, vals, out


def test_envelope_ldl_is_numpys_cholesky_and_solves() -> None:
    for n, b, seed in [(40, 3, 0), (25, 11, 1), (60, 1, 2), (5, 0, 3)]:
        m = _band_spd(n, b, seed)
        # an envelope that is not a band: one dense block of rows in the middle
        if n > 20:
            m[15:20, 5:15] = 0.01
            m[5:15, 15:20] = 0.01
            m += np.diag(np.full(n, 1.0))
        first, ptr, _vals, out = _ldl(m, np.ones(n))
        lower = np.linalg.cholesky(m)
        d = np.diag(lower) ** 2
        for i in range(n):  # L·D^½ is the Cholesky factor
            row = out[ptr[i]:ptr[i + 1]].copy()
            row[-1] = 1.0
            np.testing.assert_allclose(row * np.sqrt(d[first[i]:i + 1]),
                                       lower[i, first[i]:i + 1], rtol=1e-10, atol=1e-12)
            np.testing.assert_allclose(out[ptr[i + 1] - 1], d[i], rtol=1e-10)
        rhs = np.random.default_rng(seed).normal(size=n)
        x = np.empty(n)
        envelope_ldl_solve(first, ptr, out, rhs, x)
        np.testing.assert_allclose(m @ x, rhs, rtol=1e-10, atol=1e-10)


def test_envelope_ldl_solves_a_quasi_definite_system() -> None:
    """``[[A, Rᵀ], [R, −W⁻¹]]`` with one extra row per row of ``R`` after its last column
    (the interior-point steps' order): the solution's first part solves
    ``(A + Rᵀ·W·R)·x = b``."""
    rng = np.random.default_rng(7)
    n = 30
    a = _band_spd(n, 1, 4)
    groups = [(0, 6), (5, 13), (12, 30)]
    r = np.zeros((len(groups), n))
    for k, (g0, g1) in enumerate(groups):
        r[k, g0:g1] = rng.normal(size=g1 - g0)
    w = np.array([3.0, 0.2, 50.0])
    order = []  # variables, each squared row after its last variable
    for i in range(n):
        order.append(i)
        order.extend(n + k for k, (_g0, g1) in enumerate(groups) if g1 - 1 == i)
    big = np.zeros((n + 3, n + 3))
    big[:n, :n] = a
    big[n:, :n] = r
    big[:n, n:] = r.T
    big[n:, n:] = -np.diag(1.0 / w)
    perm = big[np.ix_(order, order)]
    sign = np.where(np.array(order) < n, 1, -1)
    first, ptr, _vals, out = _ldl(perm, sign)
    assert np.all(ptr[1:] - ptr[:-1] <= 20)  # no row spans more than its group
    b = rng.normal(size=n)
    rhs = np.concatenate((b, np.zeros(3)))[order]
    sol = np.empty(n + 3)
    envelope_ldl_solve(first, ptr, out, rhs, sol)
    x = np.empty(n + 3)
    x[order] = sol
    np.testing.assert_allclose((a + r.T @ np.diag(w) @ r) @ x[:n], b, rtol=1e-9, atol=1e-9)


def test_wrong_pivot_signs_are_refused() -> None:
    first, ptr, vals = _envelope(np.array([[1.0, 2.0], [2.0, 1.0]]))  # eigenvalue −1
    assert not envelope_ldl(first, ptr, vals, np.ones(2, dtype=np.int8), np.empty_like(vals))
    assert envelope_ldl(first, ptr, vals, np.array([1, -1], dtype=np.int8),
                        np.empty_like(vals))


def test_blocks_split_where_nothing_couples() -> None:
    # H couples 0-1 and 3-4; a constraint row spans 5..7
    starts, ends = qp_blocks(9, np.array([0, 3, 2]), np.array([1, 4, 2]), np.array([5]),
                             np.array([7]))
    assert list(zip(starts.tolist(), ends.tolist(), strict=True)) == [
        (0, 2), (2, 3), (3, 5), (5, 8), (8, 9)]


def test_blocks_solve_like_the_whole() -> None:
    """Two independent least-squares problems with bounds, solved as one program, give
    each its own solution."""
    rng = np.random.default_rng(3)
    sols = []
    blocks = []
    for n in (7, 12):
        a = rng.normal(size=(n + 5, n))
        b = rng.normal(size=n + 5)
        lo = np.full(n, -0.2)
        blocks.append((a.T @ a, -a.T @ b, lo))
        x, _, _ = solve_box_qp(sp.csc_matrix(a.T @ a), -a.T @ b, sp.identity(n, format="csr"),
                               np.zeros(n), lo, np.full(n, np.inf))
        sols.append(x)
    h = sp.block_diag([b[0] for b in blocks], format="csc")
    g = np.concatenate([b[1] for b in blocks])
    lo = np.concatenate([b[2] for b in blocks])
    x, _, _ = solve_box_qp(h, g, sp.identity(19, format="csr"), np.zeros(19), lo,
                           np.full(19, np.inf))
    np.testing.assert_allclose(x, np.concatenate(sols), atol=1e-8)


def test_interior_optimum_of_a_run_start_is_found() -> None:
    """A pre-charge and the state after the first piece of a run (taken from the
    Cura 5.9.1 program): the optimum lies inside both bounds; separate primal and dual
    steps made the iterates bounce between the ends of the ratio box for ever."""
    h = sp.csc_matrix([[4.28434073, -1.64674685], [-1.64674685, 2.67874924]])
    g = np.array([-2684.34185396, -4701.88793697])
    c = sp.csr_matrix([[-6.84788816, 7.57871162], [1.0, 0.0]])
    lo = np.array([166.48459478867323, 0.0])
    hi = np.array([22063.07752258329, 3368.0392026014647])
    x, it, _ = solve_box_qp(h, g, c, np.zeros(2), lo, hi, max_iterations=150,
                            x0=np.array([0.0, 439.34801342]))
    np.testing.assert_allclose(x, np.linalg.solve(h.toarray(), -g), rtol=1e-9)
    assert it < 40


def test_squared_rows_solve_like_their_product() -> None:
    """``H + Rᵀ·diag(w)·R`` given as rows (the refinement's moves, each reading a run of
    pieces) gives the solution of the program with the product formed, bounds active."""
    rng = np.random.default_rng(12)
    n = 60
    h = sp.diags([np.full(n, 0.5), np.full(n - 1, -0.1)], [0, 1], format="csr")
    h = h + h.T
    starts = [0, 9, 10, 31, 45]
    ends = [10, 10, 32, 46, 60]  # overlapping by a variable, one of a single variable
    r = sp.lil_matrix((len(starts), n))
    for k, (a, b) in enumerate(zip(starts, ends, strict=True)):
        r[k, a:b] = rng.normal(size=b - a)
    r = sp.csr_matrix(r)
    w = rng.uniform(0.1, 20.0, len(starts))
    g = rng.normal(size=n) * 5.0
    lo = np.full(n, -0.3)
    hi = np.where(np.arange(n) % 4 == 0, 0.4, np.inf)
    c = sp.identity(n, format="csr")
    full, _, _ = solve_box_qp(h + r.T @ sp.diags(w) @ r, g, c, np.zeros(n), lo, hi,
                              max_iterations=100)
    rows, it, _ = solve_box_qp(h, g, c, np.zeros(n), lo, hi, max_iterations=100,
                               squares=(r, w))
    assert np.any(np.abs(full - lo) < 1e-6) and np.any(np.abs(full - hi) < 1e-6)
    np.testing.assert_allclose(rows, full, atol=1e-8)
    assert it < 60
    a = h.toarray() + r.T.toarray() @ np.diag(w) @ r.toarray()
    bounded = lsq_box(a, g, lo, hi)
    np.testing.assert_allclose(rows, bounded, atol=1e-6)


def lsq_box(a: np.ndarray, g: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """``min ½xᵀAx + gᵀx`` over the box by scipy (``A = LLᵀ``: a bounded least squares)."""
    from scipy.optimize import lsq_linear

    low = np.linalg.cholesky(a)
    return lsq_linear(low.T, -np.linalg.solve(low, g), bounds=(lo, hi), tol=1e-12).x
