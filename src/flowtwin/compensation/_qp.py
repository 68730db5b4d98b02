"""A sparse convex quadratic program with two-sided linear bounds (primal-dual interior point).

Solves ::

    minimise   ½·xᵀHx + gᵀx
    subject to lo ≤ C·x + d ≤ hi          (lo finite; hi may be +inf)

with ``H`` symmetric positive (semi)definite and ``H + Cᵀ·D·C`` positive definite for
positive diagonals ``D``. Mehrotra's predictor–corrector on the slacks
``s = Cx + d − lo ≥ 0``, ``t = hi − Cx − d ≥ 0`` and their multipliers ``z, w ≥ 0``;
every Newton step solves ``(H + Cᵀ(z/s + w/t)C)·Δx = r``, which keeps the sparsity
(banded for the lag model): a banded Cholesky factorisation (LAPACK ``pbtrf``, with BLAS
held to one thread: on narrow bands a threaded BLAS ran 1000× slower on a busy machine),
or SuperLU when the band is wide. Nocedal & Wright, *Numerical
Optimization* (2nd ed.), §16.6.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.sparse as sp
from scipy.linalg import LinAlgError, cho_solve_banded, cholesky_banded
from scipy.sparse.linalg import splu
from threadpoolctl import threadpool_limits

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


class _Kkt:
    """Factorisations of ``H + Cᵀ·diag(D)·C`` for changing ``D``.

    When the band is narrow the matrix is assembled straight into LAPACK's upper band
    storage (``ab[b − k, j] = M[j − k, j]``) from precomputed index pairs of ``C``'s rows,
    and factorised by banded Cholesky (``pbtrf``); otherwise by SuperLU.
    """

    def __init__(self, h: sp.csc_matrix, c: sp.csr_matrix) -> None:
        self.h = h
        self.c = c
        self.ct = sp.csc_matrix(c.T)
        n = h.shape[0]
        hc = h.tocoo()
        cc = c.tocoo()
        # pairs (i ≤ j) of columns sharing a row of C
        order = np.argsort(cc.row, kind="stable")
        rows, cols, vals = cc.row[order], cc.col[order], cc.data[order]
        starts = np.flatnonzero(np.concatenate(([True], rows[1:] != rows[:-1])))
        counts = np.diff(np.append(starts, rows.size))
        pr: list[npt.NDArray[np.int64]] = []
        pi: list[npt.NDArray[np.int64]] = []
        pj: list[npt.NDArray[np.int64]] = []
        pv: list[FloatArray] = []
        for width in np.unique(counts).tolist():
            sel = starts[counts == width]
            for u in range(width):
                for v in range(width):
                    ii = cols[sel + u]
                    jj = cols[sel + v]
                    keep = ii <= jj
                    pr.append(rows[sel + u][keep])
                    pi.append(ii[keep])
                    pj.append(jj[keep])
                    pv.append((vals[sel + u] * vals[sel + v])[keep])
        self.p_row = np.concatenate(pr) if pr else np.zeros(0, dtype=np.int64)
        p_i = np.concatenate(pi) if pi else np.zeros(0, dtype=np.int64)
        p_j = np.concatenate(pj) if pj else np.zeros(0, dtype=np.int64)
        self.p_val = np.concatenate(pv) if pv else np.zeros(0)
        upper = hc.row <= hc.col
        band_h = int(np.max(hc.col[upper] - hc.row[upper], initial=0))
        band_c = int(np.max(p_j - p_i, initial=0))
        self.b = max(band_h, band_c)
        self.n = n
        self.banded = self.b * self.b * n <= 1e9 and self.b < n // 2 + 1
        if self.banded:
            b = self.b
            self.h_band = np.zeros((b + 1) * n)
            np.add.at(self.h_band, (b - (hc.col[upper] - hc.row[upper])) * n + hc.col[upper],
                      hc.data[upper])
            self.p_index = (b - (p_j - p_i)) * n + p_j

    def factor(self, dd: FloatArray) -> object:
        """Factorise ``H + Cᵀ·diag(dd)·C + δ·I``; ``δ`` (1e-13 of the largest diagonal,
        raised if needed) only guards against round-off making the matrix indefinite."""
        if self.banded:
            band = self.h_band + np.bincount(self.p_index, weights=dd[self.p_row] * self.p_val,
                                             minlength=self.h_band.size)
            ab = band.reshape(self.b + 1, self.n)  # LAPACK's upper band storage
            delta = 1e-13 * float(np.max(np.abs(ab[self.b])))
            for _ in range(4):
                reg = ab.copy()
                reg[self.b] += delta
                try:
                    with threadpool_limits(limits=1, user_api="blas"):
                        return _BandedFactor(cholesky_banded(reg, lower=False,
                                                             check_finite=False))
                except LinAlgError:  # not positive definite after round-off
                    delta *= 1e3
        m = sp.csc_matrix(self.h + self.ct @ sp.diags(dd) @ self.c)
        return splu(m + sp.identity(self.n, format="csc")
                    * (1e-13 * float(np.max(np.abs(m.diagonal())))))


class _BandedFactor:
    def __init__(self, factor: FloatArray) -> None:
        self.factor = factor

    def solve(self, rhs: FloatArray) -> FloatArray:
        with threadpool_limits(limits=1, user_api="blas"):
            return np.asarray(cho_solve_banded((self.factor, False), rhs,
                                               check_finite=False))


def _step_to_boundary(v: FloatArray, dv: FloatArray) -> float:
    neg = dv < 0.0
    if not np.any(neg):
        return 1.0
    return float(min(1.0, np.min(-v[neg] / dv[neg])))


def solve_box_qp(h: sp.spmatrix, g: FloatArray, c: sp.spmatrix, d: FloatArray, lo: FloatArray,
                 hi: FloatArray, *, max_iterations: int = 60, tolerance: float = 1e-9,
                 x0: FloatArray | None = None) -> tuple[FloatArray, int, float]:
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
        Bounds of ``C·x + d``, ``(m,)``; ``lo < hi``; either may be infinite (a row with
        both infinite is ignored).
    max_iterations
        Newton steps at most.
    tolerance
        Stop when the duality gap per constraint and the scaled residuals are below it.
    x0
        Starting point (default: least squares towards the middle of the bounds); the
        slacks start at least 0.1 % of each bound interval inside.

    Returns
    -------
    tuple
        ``x`` ``(n,)``, iterations, final mean complementarity.
    """
    n = h.shape[0]
    c = sp.csr_matrix(c)
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    d = np.asarray(d, dtype=np.float64)
    # rows bounded above only: negate them (−hi ≤ −C·x − d); unbounded rows: drop
    upper_only = ~np.isfinite(lo) & np.isfinite(hi)
    keep = np.isfinite(lo) | upper_only
    if np.any(upper_only) or not np.all(keep):
        sign = np.where(upper_only, -1.0, 1.0)
        c = sp.csr_matrix(sp.diags(sign) @ c)[keep]
        d = (sign * d)[keep]
        lo, hi = np.where(upper_only, -hi, lo)[keep], np.where(upper_only, np.inf, hi)[keep]
    m = c.shape[0]
    h = sp.csc_matrix(h)
    ct = sp.csc_matrix(c.T)
    finite_hi = np.isfinite(hi)
    span = np.where(finite_hi, hi - lo, np.inf)
    # start: a point with C·x + d strictly inside the bounds (least squares towards the
    # middle of each interval, or just above lo where hi is infinite)
    target = np.where(finite_hi, lo + 0.5 * span, lo + np.maximum(1.0, np.abs(lo)) * 0.5)
    if x0 is not None:
        x = np.asarray(x0, dtype=np.float64).copy()
    else:
        reg = sp.identity(n, format="csc") * 1e-12
        x = splu(sp.csc_matrix(ct @ c + reg)).solve(ct @ (target - d))
    y = c @ x + d
    s = np.maximum(y - lo, 1e-3 * np.where(finite_hi, span, 1.0))
    t = np.where(finite_hi, np.maximum(hi - y, 1e-3 * np.where(finite_hi, span, 1.0)), 1.0)
    z = np.ones(m)
    w = np.where(finite_hi, 1.0, 0.0)
    kkt = _Kkt(h, c)
    scale = max(1.0, float(np.max(np.abs(g))) if g.size else 1.0)
    it = 0
    mu = float(np.mean(s * z + t * w))
    mu0 = max(mu, 1e-300)
    while it < max_iterations:
        it += 1
        y = c @ x + d
        r_d = h @ x + g - ct @ (z - w)           # dual residual
        r_l = y - lo - s                          # primal residuals
        r_u = np.where(finite_hi, hi - y - t, 0.0)
        mu = float(np.sum(s * z + t * w) / max(m + int(np.count_nonzero(finite_hi)), 1))
        primal_ok = (float(np.max(np.abs(r_l), initial=0.0))
                     < tolerance * (1.0 + float(np.max(np.abs(lo)))))
        dual = float(np.max(np.abs(r_d), initial=0.0))
        if primal_ok and (mu < tolerance or mu < 1e-12 * mu0):
            # converged; with barrier terms spanning many decades the dual residual of the
            # last Newton steps only reaches the accuracy of the factorisation
            if dual < tolerance * scale or (mu < 1e-3 * tolerance and dual < 1e-3 * scale):
                break
        dz_s = z / s
        dw_t = np.where(finite_hi, w / t, 0.0)
        dd = dz_s + dw_t
        try:
            lu = kkt.factor(dd)
        except (RuntimeError, np.linalg.LinAlgError):  # numerically singular: done
            break

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
