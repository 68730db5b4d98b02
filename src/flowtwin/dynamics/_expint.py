"""Compiled building blocks of the lag integrator: exact exponential steps and collocation.

Private module: plain floats and arrays in, floats out, no validation (the callers in
:mod:`flowtwin.dynamics.integrator` validate first).

Exact step of the first-order lag [001 Eq. 10] with a polynomial input
----------------------------------------------------------------------
On an interval of length ``T`` the state ``x`` (column compression, mm) obeys
``x' = a(τ) - x/K`` with ``a(τ) = b0 + b1 τ + b2 τ² + b3 τ³``. Variation of constants::

    x(T)  = e^{-T/K} x0 + ∫_0^T e^{-(T-s)/K} a(s) ds
          = φ0 x0 + Σ_j b_j j! T^{j+1} φ_{j+1}
    ∫_0^T x dt = x0 T φ1 + Σ_j b_j j! T^{j+2} φ_{j+2}

with ``φ_k = φ_k(-T/K) = Σ_{i≥0} (-T/K)^i / (i+k)!`` (the φ-functions of exponential
integrators, since ``∫_0^T e^{-(T-s)/K} s^j ds = j! T^{j+1} φ_{j+1}(-T/K)``). For
``T/K ≤ 2`` the φ's come from the series of φ5 and the stable backward recurrence
``φ_k = 1/k! + x φ_{k+1}``; beyond, from ``φ0 = e^x`` and ``φ_{k+1} = (φ_k - 1/k!)/x``
(error growth ≤ Π(k+1)/|x| < 4). Both are exact to rounding: no internal step.

Gauss–Legendre collocation for the slip loop
---------------------------------------------
With slip [000 Eq. 6/8] the equation is ``x' = α(τ) - β(τ) x`` with
``β = 1/K + v s'(v)/k`` varying in time. It is solved with the 6-stage Gauss collocation
method (order 12, A-stable) on substeps with ``max β · h ≤ stiffness`` (default 1, local
error ≈ 2e-13 relative): the stage values ``X_i`` solve
``(I + h A diag β) X = x0 + h A α``; ``x(h) = x0 + h Σ b_i (α_i - β_i X_i)`` and the
quadratures ``∫x = h Σ b_i X_i``, ``∫γx = h Σ b_i γ_i X_i`` are those of the collocation
polynomial, so filament in = melt out + stored compression holds to rounding.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

__all__ = [
    "FREE",
    "GRIND",
    "LAG",
    "SLIP",
    "gauss_legendre_collocation",
]

#: Regimes of the state equation (SPEC §3.4) on an interval of fixed sign of the feed.
FREE = 0   # Δl ≤ 0: column pulled back from the melt, no output, x' = α
LAG = 1    # Δl > 0, constant coefficient: x' = α - x/K
SLIP = 2   # Δl > 0, feeding forward with force-dependent slip: x' = α - (1/K + v s'/k) x
GRIND = 3  # Δl > 0, drive grinding: no feed, x' = -x/K

#: 1/(i+5)! for i = 0..23 (series of φ5).
_INV_FACT_5 = np.array([1.0 / math.factorial(i + 5) for i in range(24)])


def gauss_legendre_collocation(
    s: int = 6,
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Nodes ``c`` (s,), weights ``b`` (s,) and matrix ``A`` (s, s) of Gauss collocation on [0, 1].

    ``A[i, j] = ∫_0^{c_i} ℓ_j(θ) dθ`` with ``ℓ_j`` the Lagrange basis on the nodes.
    """
    x, w = np.polynomial.legendre.leggauss(s)
    c = 0.5 * (x + 1.0)
    b = 0.5 * w
    a = np.empty((s, s))
    for j in range(s):
        others = np.delete(c, j)
        basis = np.polynomial.Polynomial.fromroots(others) / np.prod(c[j] - others)
        anti = basis.integ()
        a[:, j] = anti(c) - anti(0.0)
    return c, b, a


@njit(cache=True)
def phi_fill(z: float, out: npt.NDArray[np.float64]) -> None:
    """``out[k] = φ_k(-z)`` for ``k = 0..5`` and ``z ≥ 0``."""
    x = -z
    if z <= 2.0:
        # Σ_{i<m} x^i/(i+5)! by Horner; the first term left out, relative to the first
        # (5! z^m/(m+5)!), is < 1e-17 for m = 7 (z <= 0.01), 12 (z <= 0.25), 24 (z <= 2)
        m = 7 if z <= 0.01 else (12 if z <= 0.25 else 24)
        acc = _INV_FACT_5[m - 1]
        for i in range(m - 2, -1, -1):
            acc = acc * x + _INV_FACT_5[i]
        out[5] = acc
        out[4] = 1.0 / 24.0 + x * out[5]
        out[3] = 1.0 / 6.0 + x * out[4]
        out[2] = 0.5 + x * out[3]
        out[1] = 1.0 + x * out[2]
        out[0] = math.exp(x)
    else:
        e = math.exp(x)
        out[0] = e
        out[1] = (e - 1.0) / x
        out[2] = (out[1] - 1.0) / x
        out[3] = (out[2] - 0.5) / x
        out[4] = (out[3] - 1.0 / 6.0) / x
        out[5] = (out[4] - 1.0 / 24.0) / x


@njit(cache=True)
def poly(c: npt.NDArray[np.float64], t: float) -> float:
    """``c0 + c1 t + c2 t² + c3 t³``."""
    return c[0] + t * (c[1] + t * (c[2] + t * c[3]))


@njit(cache=True)
def dpoly(c: npt.NDArray[np.float64], t: float) -> float:
    """Derivative of :func:`poly`."""
    return c[1] + t * (2.0 * c[2] + t * 3.0 * c[3])


@njit(cache=True)
def ipoly(c: npt.NDArray[np.float64], t: float) -> float:
    """``∫_0^t poly(c, s) ds``."""
    return t * (c[0] + t * (0.5 * c[1] + t * (c[2] / 3.0 + t * 0.25 * c[3])))


@njit(cache=True)
def shift(c: npt.NDArray[np.float64], s: float, scale: float,
          out: npt.NDArray[np.float64]) -> None:
    """Coefficients of ``scale · poly(c, s + τ)`` in ``τ`` (Taylor shift)."""
    out[0] = scale * poly(c, s)
    out[1] = scale * dpoly(c, s)
    out[2] = scale * (c[2] + 3.0 * c[3] * s)
    out[3] = scale * c[3]


@njit(cache=True)
def lag_step(x0: float, b: npt.NDArray[np.float64], k_s: float, t: float,
             phi: npt.NDArray[np.float64]) -> tuple[float, float]:
    """Exact ``x(t)`` and ``∫_0^t x`` of ``x' = b(τ) - x/K`` (module docstring)."""
    phi_fill(t / k_s, phi)
    t2 = t * t
    t3 = t2 * t
    t4 = t3 * t
    xt = (phi[0] * x0 + b[0] * t * phi[1] + b[1] * t2 * phi[2]
          + 2.0 * b[2] * t3 * phi[3] + 6.0 * b[3] * t4 * phi[4])
    ix = (x0 * t * phi[1] + b[0] * t2 * phi[2] + b[1] * t3 * phi[3]
          + 2.0 * b[2] * t4 * phi[4] + 6.0 * b[3] * t4 * t * phi[5])
    return xt, ix


@njit(cache=True)
def free_step(x0: float, b: npt.NDArray[np.float64], t: float) -> tuple[float, float]:
    """Exact ``x(t)`` and ``∫_0^t x`` of ``x' = b(τ)`` (no output, Δl ≤ 0)."""
    xt = x0 + t * (b[0] + t * (0.5 * b[1] + t * (b[2] / 3.0 + t * 0.25 * b[3])))
    ix = x0 * t + t * t * (0.5 * b[0] + t * (b[1] / 6.0 + t * (b[2] / 12.0 + t * b[3] / 20.0)))
    return xt, ix


@njit(cache=True)
def slope_factor(v: float, sa: float, sb: float, sc: float) -> float:
    """Slip gradient ``s'(v) = a + b·exp(-c·v)`` (1/N) [000 Eq. 8]; ``b = 0`` gives Eq. 6."""
    if sb == 0.0:
        return sa
    return sa + sb * math.exp(-sc * v)


@njit(cache=True)
def colloc_step(x0: float, c: npt.NDArray[np.float64], tau0: float, h: float,
                alpha_scale: float, k_s: float, kc: float, sa: float, sb: float, sc: float,
                gl_c: npt.NDArray[np.float64], gl_b: npt.NDArray[np.float64],
                gl_a: npt.NDArray[np.float64],
                mat: npt.NDArray[np.float64], rhs: npt.NDArray[np.float64],
                beta: npt.NDArray[np.float64], gam: npt.NDArray[np.float64],
                alp: npt.NDArray[np.float64]) -> tuple[float, float, float]:
    """One Gauss collocation step of ``x' = α - β x`` over ``[tau0, tau0 + h]``.

    Returns ``x(tau0 + h)``, ``∫x`` and ``∫γx`` with ``γ = v s'(v)/k`` (the slip term).
    ``mat``, ``rhs``, ``beta``, ``gam``, ``alp`` are scratch arrays of the stage count.
    """
    s = gl_c.shape[0]
    inv_k = 1.0 / k_s
    for i in range(s):
        v = poly(c, tau0 + gl_c[i] * h)
        g = v * slope_factor(v, sa, sb, sc) / kc
        gam[i] = g
        beta[i] = inv_k + g
        alp[i] = alpha_scale * v
    for i in range(s):
        acc = 0.0
        for j in range(s):
            hij = h * gl_a[i, j]
            mat[i, j] = hij * beta[j]
            acc += hij * alp[j]
        mat[i, i] += 1.0
        rhs[i] = x0 + acc
    # Gaussian elimination without pivoting: I + hβA is a small perturbation of the
    # identity for |β h| <= stiffness <= 4 (the poles of the (6,6) Padé stability function
    # lie further out), so the pivots stay near 1.
    for col in range(s):
        inv = 1.0 / mat[col, col]
        for r in range(col + 1, s):
            f = mat[r, col] * inv
            for q in range(col + 1, s):
                mat[r, q] -= f * mat[col, q]
            rhs[r] -= f * rhs[col]
    for r in range(s - 1, -1, -1):
        acc = rhs[r]
        for q in range(r + 1, s):
            acc -= mat[r, q] * rhs[q]
        rhs[r] = acc / mat[r, r]
    dx = 0.0
    ix = 0.0
    igx = 0.0
    for i in range(s):
        dx += gl_b[i] * (alp[i] - beta[i] * rhs[i])
        ix += gl_b[i] * rhs[i]
        igx += gl_b[i] * gam[i] * rhs[i]
    return x0 + h * dx, h * ix, h * igx
