"""A sparse convex quadratic program with two-sided linear bounds (primal-dual interior point).

Solves ::

    minimise   ½·xᵀHx + gᵀx
    subject to lo ≤ C·x + d ≤ hi          (lo finite; hi may be +inf)

with ``H`` symmetric positive (semi)definite and ``H + Cᵀ·D·C`` positive definite for
positive diagonals ``D``. Mehrotra's predictor–corrector on the slacks
``s = Cx + d − lo ≥ 0``, ``t = hi − Cx − d ≥ 0`` and their multipliers ``z, w ≥ 0``;
every Newton step solves ``(H + Cᵀ(z/s + w/t)C)·Δx = r``, which keeps the sparsity
(banded for the lag model) and is factorised by SuperLU. Nocedal & Wright, *Numerical
Optimization* (2nd ed.), §16.6.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.sparse.linalg import splu

__all__ = ["solve_box_qp"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class _State:
    """Slacks, multipliers and residuals of one interior-point iteration."""

    s: FloatArray
    t: FloatArray
    z: FloatArray
    w: FloatArray
    r_d: FloatArray
    r_l: FloatArray
    r_u: FloatArray
    finite_hi: npt.NDArray[np.bool_]


def _newton(lu: object, c: sp.csr_matrix, ct: sp.csc_matrix, st: _State, sigma_mu: float,
            ds_corr: FloatArray, dt_corr: FloatArray
            ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """One Newton direction. Complementarity targets ``s·z = σμ − Δs·Δz`` (corrector);
    ``Δs = CΔx + r_l``, ``Δt = −CΔx + r_u``, ``Δz = (−rc_l − zΔs)/s``,
    ``Δw = (−rc_u − wΔt)/t``, and ``Δx`` from the reduced system factorised in ``lu``."""
    f = st.finite_hi
    rc_l = st.s * st.z - sigma_mu + ds_corr
    rc_u = np.where(f, st.t * st.w - sigma_mu + dt_corr, 0.0)
    rhs = -st.r_d + ct @ ((-rc_l - st.z * st.r_l) / st.s
                          - np.where(f, (-rc_u - st.w * st.r_u) / st.t, 0.0))
    dx = lu.solve(rhs)  # type: ignore[attr-defined]
    cdx = c @ dx
    ds = cdx + st.r_l
    dt = np.where(f, -cdx + st.r_u, 0.0)
    dz = (-rc_l - st.z * ds) / st.s
    dw = np.where(f, (-rc_u - st.w * dt) / st.t, 0.0)
    return dx, ds, dt, dz, dw


def _step_to_boundary(v: FloatArray, dv: FloatArray) -> float:
    neg = dv < 0.0
    if not np.any(neg):
        return 1.0
    return float(min(1.0, np.min(-v[neg] / dv[neg])))


def solve_box_qp(h: sp.spmatrix, g: FloatArray, c: sp.spmatrix, d: FloatArray, lo: FloatArray,
                 hi: FloatArray, *, max_iterations: int = 60, tolerance: float = 1e-9,
                 ) -> tuple[FloatArray, int, float]:
    """Solve the program of the module docstring.

    Parameters
    ----------
    h
        Hessian, sparse ``(n, n)``.
    g
        Linear term, ``(n,)``.
    c, d
        Constraint map ``C`` (sparse ``(m, n)``) and offset ``d`` ``(m,)``.
    lo, hi
        Bounds of ``C·x + d``, ``(m,)``; ``lo < hi`` (``hi`` may be ``inf``).
    max_iterations
        Newton steps at most.
    tolerance
        Stop when the duality gap per constraint and the scaled residuals are below it.

    Returns
    -------
    tuple
        ``x`` ``(n,)``, iterations, final mean complementarity.
    """
    n = h.shape[0]
    m = c.shape[0]
    h = sp.csc_matrix(h)
    c = sp.csr_matrix(c)
    ct = sp.csc_matrix(c.T)
    finite_hi = np.isfinite(hi)
    span = np.where(finite_hi, hi - lo, np.inf)
    # start: a point with C·x + d strictly inside the bounds (least squares towards the
    # middle of each interval, or just above lo where hi is infinite)
    target = np.where(finite_hi, lo + 0.5 * span, lo + np.maximum(1.0, np.abs(lo)) * 0.5)
    reg = sp.identity(n, format="csc") * 1e-12
    x = splu(sp.csc_matrix(ct @ c + reg)).solve(ct @ (target - d))
    y = c @ x + d
    s = np.maximum(y - lo, 1e-3 * np.where(finite_hi, span, 1.0))
    t = np.where(finite_hi, np.maximum(hi - y, 1e-3 * np.where(finite_hi, span, 1.0)), 1.0)
    z = np.ones(m)
    w = np.where(finite_hi, 1.0, 0.0)
    scale = max(1.0, float(np.max(np.abs(g))) if g.size else 1.0)
    it = 0
    mu = float(np.mean(s * z + t * w))
    while it < max_iterations:
        it += 1
        y = c @ x + d
        r_d = h @ x + g - ct @ (z - w)           # dual residual
        r_l = y - lo - s                          # primal residuals
        r_u = np.where(finite_hi, hi - y - t, 0.0)
        mu = float(np.sum(s * z + t * w) / max(m + int(np.count_nonzero(finite_hi)), 1))
        if (mu < tolerance and float(np.max(np.abs(r_d), initial=0.0)) < tolerance * scale
                and float(np.max(np.abs(r_l), initial=0.0)) < tolerance * (1 + np.max(np.abs(lo)))):
            break
        dz_s = z / s
        dw_t = np.where(finite_hi, w / t, 0.0)
        kkt = sp.csc_matrix(h + ct @ sp.diags(dz_s + dw_t) @ c)
        lu = splu(kkt)

        zero = np.zeros(m)
        state = _State(s, t, z, w, r_d, r_l, r_u, finite_hi)
        dx, ds, dt, dz, dw = _newton(lu, c, ct, state, 0.0, zero, zero)
        a_p = min(_step_to_boundary(s, ds), _step_to_boundary(t[finite_hi], dt[finite_hi]))
        a_d = min(_step_to_boundary(z, dz), _step_to_boundary(w[finite_hi], dw[finite_hi]))
        n_c = m + int(np.count_nonzero(finite_hi))
        mu_aff = float(np.sum((s + a_p * ds) * (z + a_d * dz))
                       + np.sum(((t + a_p * dt) * (w + a_d * dw))[finite_hi])) / max(n_c, 1)
        sigma = (mu_aff / mu) ** 3 if mu > 0 else 0.0
        dx, ds, dt, dz, dw = _newton(lu, c, ct, state, sigma * mu, ds * dz,
                                     np.where(finite_hi, dt * dw, 0.0))
        eta = 0.995
        a_p = eta * min(_step_to_boundary(s, ds), _step_to_boundary(t[finite_hi], dt[finite_hi]))
        a_d = eta * min(_step_to_boundary(z, dz), _step_to_boundary(w[finite_hi], dw[finite_hi]))
        a_p = min(a_p, 1.0)
        a_d = min(a_d, 1.0)
        x = x + a_p * dx
        s = s + a_p * ds
        t = np.where(finite_hi, t + a_p * dt, 1.0)
        z = z + a_d * dz
        w = np.where(finite_hi, w + a_d * dw, 0.0)
    return x, it, mu
