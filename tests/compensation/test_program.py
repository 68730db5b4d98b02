"""The refinement's program assembled as arrays equals the ``scipy.sparse`` products it
replaced, to the bit (``flowtwin.compensation.program``)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from flowtwin.compensation.program import Chain, Csr


def _chain_inputs(seed: int, n: int = 60, k_y: int = 5):
    rng = np.random.default_rng(seed)
    alpha = rng.uniform(0.2, 1.0, n)
    alpha[rng.choice(n, 8, replace=False)] = 0.0  # relaxed run starts couple nothing
    e_p = rng.uniform(0.5, 1.0, n)
    b_p = rng.uniform(0.01, 3.0, n)
    pre = np.sort(rng.choice(np.flatnonzero(alpha == 0.0), k_y, replace=False))
    grp = np.sort(rng.integers(0, n // 3, n))
    grp = np.unique(grp, return_inverse=True)[1].astype(np.int64)  # no empty group
    l_p = rng.uniform(0.0, 2.0, n)
    return alpha, e_p, b_p, pre, grp, l_p


def _scipy_matrices(alpha, e_p, b_p, pre, grp, l_p):
    """C, R and the Hessian as refine_qp built them before (scipy.sparse products)."""
    n, k_y, m = alpha.size, pre.size, int(grp.max()) + 1
    idx = np.arange(n)
    c_mat = sp.csr_matrix((np.concatenate((1.0 / b_p, -(e_p[1:] * alpha[1:]) / b_p[1:])),
                           (np.concatenate((idx, idx[1:])), np.concatenate((idx, idx[1:] - 1)))),
                          shape=(n, n))
    p_mat = sp.csr_matrix((alpha[1:], (idx[1:], idx[1:] - 1)), shape=(n, n))
    g_mat = sp.csr_matrix((np.ones(n), (grp, idx)), shape=(m, n))
    first = np.concatenate(([True], grp[1:] != grp[:-1]))
    last = np.concatenate((grp[1:] != grp[:-1], [True]))
    s_last = sp.csr_matrix((np.ones(int(last.sum())), (grp[last], idx[last])), shape=(m, n))
    s_first = sp.csr_matrix((np.ones(int(first.sum())), (grp[first], idx[first])),
                            shape=(m, n))
    y_idx = np.arange(k_y)
    y_x = sp.csr_matrix((np.ones(k_y), (pre, y_idx)), shape=(n, k_y))
    c_y = sp.csr_matrix((-e_p[pre] / b_p[pre], (pre, y_idx)), shape=(n, k_y))
    c_mat = sp.hstack([c_mat, c_y], format="csr")
    p_mat = sp.hstack([p_mat, y_x], format="csr")
    s_last = sp.hstack([s_last, sp.csr_matrix((m, k_y))], format="csr")
    r_mat = sp.csr_matrix(g_mat @ sp.diags(l_p) @ c_mat - s_last + s_first @ p_mat)
    return c_mat, r_mat


def _dense(a: Csr, shape: tuple[int, int]) -> np.ndarray:
    out = np.zeros(shape)
    rows = np.repeat(np.arange(shape[0]), np.diff(a.ptr))
    assert np.all(a.val != 0.0)  # no stored zero
    for i in range(shape[0]):  # columns ascending in every row
        assert np.all(np.diff(a.col[a.ptr[i]:a.ptr[i + 1]]) > 0)
    out[rows, a.col] = a.val
    return out


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_chain_matrices_equal_the_scipy_products_bit_for_bit(seed: int) -> None:
    alpha, e_p, b_p, pre, grp, l_p = _chain_inputs(seed)
    n, k_y, m = alpha.size, pre.size, int(grp.max()) + 1
    c_ref, r_ref = _scipy_matrices(alpha, e_p, b_p, pre, grp, l_p)
    chain = Chain.of(alpha, e_p, b_p, pre)
    size = n + k_y
    c_ref_d = c_ref.toarray()
    assert np.array_equal(_dense(chain.matrix(), (n, size)), c_ref_d)
    assert np.array_equal(_dense(chain.outputs(grp, m, l_p, alpha), (m, size)),
                          r_ref.toarray())
    order = chain.order
    assert np.array_equal(_dense(chain.box_rows(), (n, size)), c_ref_d[:, order])
    # the ratio steps c_p − c_(p−1)
    step = np.arange(1, n, 2)
    sel = sp.csr_matrix((np.ones(step.size), (np.arange(step.size), step)), shape=(step.size, n))
    prev = sp.csr_matrix((np.ones(step.size), (np.arange(step.size), step - 1)),
                         shape=(step.size, n))
    d_ref = ((sel - prev) @ c_ref).toarray()
    assert np.array_equal(_dense(chain.step_rows(step), (step.size, size)), d_ref[:, order])
    # the Hessian Cᵀ·V·C + diag(0, v_y): upper triangle in the solver's order, and its
    # diagonal in the variables' own
    rng = np.random.default_rng(seed + 10)
    v = rng.uniform(0.1, 2.0, n)
    v_y = rng.uniform(0.1, 2.0, k_y)
    h_ref = sp.csr_matrix(c_ref.T @ sp.diags(v) @ c_ref
                          + sp.csr_matrix((v_y, (n + np.arange(k_y), n + np.arange(k_y))),
                                          shape=(size, size)))
    upper, diag = chain.hessian(v, v_y)
    h_perm = h_ref.toarray()[np.ix_(order, order)]
    assert np.array_equal(_dense(upper, (size, size)), np.triu(h_perm))
    assert np.array_equal(diag, h_ref.diagonal())


def test_products_add_their_terms_as_scipy_does() -> None:
    alpha, e_p, b_p, pre, grp, l_p = _chain_inputs(4)
    n, k_y = alpha.size, pre.size
    c_ref, _r = _scipy_matrices(alpha, e_p, b_p, pre, grp, l_p)
    chain = Chain.of(alpha, e_p, b_p, pre)
    x = np.random.default_rng(5).normal(size=n + k_y)
    y = np.random.default_rng(6).normal(size=c_ref.shape[0])
    assert np.array_equal(chain.matrix().matvec(x), c_ref @ x)
    assert np.array_equal(chain.matrix().rmatvec(y, n + k_y), c_ref.T @ y)
