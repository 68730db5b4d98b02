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
(error growth ≤ Π(k+1)/|x| < 4). Both are exact to rounding: no internal step. This is
the lag step of :mod:`flowtwin.physics.lag` (``lag_linear``) extended to cubic inputs and
inlined for speed; ``tests/dynamics/test_lag_primitive.py`` holds it to that primitive.

Gauss–Legendre collocation for the slip loop
---------------------------------------------
With slip [000 Eq. 6/8] the equation is ``x' = α(τ) - β(τ) x`` with
``β = 1/K + v s'(v)/k`` varying in time. It is solved with the 6-stage Gauss collocation
method (order 12, A-stable) on substeps with ``max β · h ≤ stiffness`` (default 1, local
error ≈ 2e-13 relative): the stage values ``X_i`` solve
``(I + h A diag β) X = x0 + h A α``; ``x(h) = x0 + h Σ b_i (α_i - β_i X_i)`` and the
quadratures ``∫x = h Σ b_i X_i``, ``∫γx = h Σ b_i γ_i X_i`` are those of the collocation
polynomial, so filament in = melt out + stored compression holds to rounding.

Fewer stages on short substeps
------------------------------
The ``s``-stage method is the ``(s, s)`` Padé approximant of ``e^{-z}`` on the
constant-coefficient problem, local error ``C_s z^{2s+1}`` with
``C_s = (s!)² / ((2s)! (2s+1)!)`` (Hairer & Wanner, *Solving ODEs II*, IV.3/IV.5).
:func:`stages_for` picks the fewest stages (2–6) whose bound ``C_s z^{2s+1}`` is below
``STAGE_TOL`` (1e-16 relative), with ``z`` the substep's largest ``β·h`` plus the
variation of the velocity law over it (``c·|Δv|``): 6 stages above ``z ≈ 0.28``, 5 down
to 0.11, 4 to 0.027, 3 to 0.0024, else 2 (6 stages at ``z = 1`` give 1.7e-13, the bound
of the default substep). A cruise (constant speed) has a constant ``β`` and is
solved in closed form instead (``lag_step`` with ``1/β``), exact to rounding.

Speed polynomials, shifted coefficients and φ-values are passed as plain floats (``c0..c3``)
and returned as tuples: the compiled code then creates no array views in its inner loops
(each view or array argument costs numba two atomic reference-count operations, which
otherwise dominate the run time). The collocation's scratch space is one ``(WS_ROWS, 6)``
array and its tableaux one ``(6, 6, 8)`` table (:func:`collocation_table`).

The slip law's ``exp(-c·v)`` is evaluated at every node (``math.exp``: measured faster
than continuing it from the midpoint by a Taylor series, whose divisions form one long
dependency chain).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, cast

import numpy as np
import numpy.typing as npt
from numba import types
from numba.extending import intrinsic

from flowtwin._jit import njit

__all__ = [
    "FREE",
    "GRIND",
    "LAG",
    "MAX_STAGES",
    "SLIP",
    "STAGE_TOL",
    "TAB_A",
    "TAB_B",
    "TAB_C",
    "WS_ALP",
    "WS_BETA",
    "WS_GAM",
    "WS_RHS",
    "WS_ROWS",
    "colloc4",
    "colloc_step",
    "collocation_table",
    "dpoly4",
    "free4",
    "gauss_legendre_collocation",
    "gauss_legendre_tableaux",
    "ipoly4",
    "lag4",
    "lag_step",
    "phi6",
    "phi_fill",
    "poly4",
    "shift4",
    "slope_factor",
    "stages_for",
    "unowned",
]

def _unowned(typingctx: Any, arr: Any) -> Any:  # pragma: no cover - compiled
    """The same array without its memory owner, for scratch arrays passed to compiled
    functions in hot loops (``unowned(a)`` inside ``@njit`` code).

    Numba reference-counts every array argument of a call with two atomic operations
    (``NRT_incref`` / ``NRT_decref``, which skip a null owner); on the 2.1 M-line print
    those were ~25 % of the integrator's samples in ``perf``. The view must not outlive
    ``arr``: pass arrays the Python caller holds for the whole call.
    """
    if not isinstance(arr, types.Array):
        return None
    sig = arr(arr)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        src = context.make_array(signature.args[0])(context, builder, value=args[0])
        dst = context.make_array(signature.return_type)(context, builder)
        context.populate_array(dst, data=src.data, shape=src.shape, strides=src.strides,
                               itemsize=src.itemsize, meminfo=None)
        return dst._getvalue()

    return sig, codegen


#: :func:`_unowned` as a numba intrinsic (typed for mypy as the identity on arrays).
unowned = cast("Callable[[npt.NDArray[Any]], npt.NDArray[Any]]", intrinsic(_unowned))

#: Regimes of the state equation (docs/spec.md §3.4) on an interval of fixed sign of the feed.
FREE = 0   # Δl ≤ 0: column pulled back from the melt, no output, x' = α
LAG = 1    # Δl > 0, constant coefficient: x' = α - x/K
SLIP = 2   # Δl > 0, feeding forward with force-dependent slip: x' = α - (1/K + v s'/k) x
GRIND = 3  # Δl > 0, drive grinding: no feed, x' = -x/K

#: Most collocation stages used (order 12).
MAX_STAGES = 6
#: Bound on the relative local error of one collocation substep (see the module docstring).
STAGE_TOL = 1e-16
#: Largest ``z`` for ``s`` stages: ``C_s z^{2s+1} <= STAGE_TOL``, index ``s`` (0, 1 unused).
_Z_MAX = np.array([0.0, 0.0] + [
    (STAGE_TOL * math.factorial(2 * s) * math.factorial(2 * s + 1)
     / math.factorial(s) ** 2) ** (1.0 / (2 * s + 1)) for s in range(2, MAX_STAGES + 1)])

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


def gauss_legendre_tableaux(max_stages: int = MAX_STAGES) -> tuple[
        npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Tableaux of 1..``max_stages`` stages, zero padded.

    Returns ``c (m, m)``, ``b (m, m)``, ``A (m, m, m)`` with row ``s - 1`` holding the
    ``s``-stage method of :func:`gauss_legendre_collocation` (``m = max_stages``).
    """
    m = max_stages
    cs = np.zeros((m, m))
    bs = np.zeros((m, m))
    a_s = np.zeros((m, m, m))
    for s in range(1, m + 1):
        # one stage: the implicit midpoint rule
        c, b, a = ((np.array([0.5]), np.array([1.0]), np.array([[0.5]])) if s == 1
                   else gauss_legendre_collocation(s))
        cs[s - 1, :s] = c
        bs[s - 1, :s] = b
        a_s[s - 1, :s, :s] = a
    return cs, bs, a_s


#: Columns of :func:`collocation_table`: node, weight, then the row of ``A``.
TAB_C = 0
TAB_B = 1
TAB_A = 2
#: Rows of the collocation scratch array (``(WS_ROWS, MAX_STAGES)``): ``0..5`` the matrix.
WS_RHS = 6
WS_BETA = 7
WS_GAM = 8
WS_ALP = 9
WS_ROWS = 10


def collocation_table(max_stages: int = MAX_STAGES) -> npt.NDArray[np.float64]:
    """All tableaux in one table ``(m, m, m + 2)``: ``[s - 1, i]`` is stage ``i`` of the
    ``s``-stage method, ``[c_i, b_i, A_i0 .. A_i(m-1)]`` (zero padded)."""
    cs, bs, a_s = gauss_legendre_tableaux(max_stages)
    m = max_stages
    tab = np.zeros((m, m, m + 2))
    tab[:, :, TAB_C] = cs
    tab[:, :, TAB_B] = bs
    tab[:, :, TAB_A:] = a_s
    return tab


#: The tableaux as a compile-time constant of the compiled code (read only).
TABLE = collocation_table()


@njit(cache=True, nogil=True)
def stages_for(z: float, min_stages: int) -> int:
    """Fewest stages (``>= min_stages``, ``<= MAX_STAGES``) whose error bound meets
    :data:`STAGE_TOL` at ``z = β·h`` (+ the velocity-law variation)."""
    s = min_stages
    while s < MAX_STAGES and z > _Z_MAX[s]:
        s += 1
    return s


@njit(cache=True, nogil=True)
def phi6(z: float) -> tuple[float, float, float, float, float, float]:
    """``(φ_0(-z), ..., φ_5(-z))`` for ``z ≥ 0``."""
    x = -z
    if z <= 2.0:
        # Σ_{i<m} x^i/(i+5)! by Horner; the first term left out, relative to the first
        # (5! z^m/(m+5)!), is < 1e-17 for m = 7 (z <= 0.01), 8 (0.05), 9 (0.1), 12 (0.25),
        # 13 (0.5), 16 (1), 24 (2)
        if z <= 0.1:
            m = 7 if z <= 0.01 else (8 if z <= 0.05 else 9)
        elif z <= 0.5:
            m = 12 if z <= 0.25 else 13
        else:
            m = 16 if z <= 1.0 else 24
        acc = _INV_FACT_5[m - 1]
        for i in range(m - 2, -1, -1):
            acc = acc * x + _INV_FACT_5[i]
        p5 = acc
        p4 = 1.0 / 24.0 + x * p5
        p3 = 1.0 / 6.0 + x * p4
        p2 = 0.5 + x * p3
        p1 = 1.0 + x * p2
        p0 = math.exp(x)
    else:
        p0 = math.exp(x)
        p1 = (p0 - 1.0) / x
        p2 = (p1 - 1.0) / x
        p3 = (p2 - 0.5) / x
        p4 = (p3 - 1.0 / 6.0) / x
        p5 = (p4 - 1.0 / 24.0) / x
    return p0, p1, p2, p3, p4, p5


@njit(cache=True, nogil=True)
def phi_fill(z: float, out: npt.NDArray[np.float64]) -> None:
    """``out[k] = φ_k(-z)`` for ``k = 0..5`` and ``z ≥ 0``."""
    out[0], out[1], out[2], out[3], out[4], out[5] = phi6(z)


@njit(cache=True, nogil=True)
def poly4(c0: float, c1: float, c2: float, c3: float, t: float) -> float:
    """``c0 + c1 t + c2 t² + c3 t³``."""
    return c0 + t * (c1 + t * (c2 + t * c3))


@njit(cache=True, nogil=True)
def dpoly4(c0: float, c1: float, c2: float, c3: float, t: float) -> float:
    """Derivative of :func:`poly4`."""
    return c1 + t * (2.0 * c2 + t * 3.0 * c3)


@njit(cache=True, nogil=True)
def ipoly4(c0: float, c1: float, c2: float, c3: float, t: float) -> float:
    """``∫_0^t poly4 ds``."""
    return t * (c0 + t * (0.5 * c1 + t * (c2 / 3.0 + t * 0.25 * c3)))


@njit(cache=True, nogil=True)
def shift4(c0: float, c1: float, c2: float, c3: float, s: float, scale: float
           ) -> tuple[float, float, float, float]:
    """Coefficients of ``scale · poly4(s + τ)`` in ``τ`` (Taylor shift)."""
    return (scale * poly4(c0, c1, c2, c3, s), scale * dpoly4(c0, c1, c2, c3, s),
            scale * (c2 + 3.0 * c3 * s), scale * c3)


@njit(cache=True, nogil=True)
def lag4(x0: float, b0: float, b1: float, b2: float, b3: float, k_s: float, t: float
         ) -> tuple[float, float]:
    """Exact ``x(t)`` and ``∫_0^t x`` of ``x' = b(τ) - x/K`` (module docstring)."""
    p0, p1, p2, p3, p4, p5 = phi6(t / k_s)
    t2 = t * t
    t3 = t2 * t
    t4 = t3 * t
    xt = p0 * x0 + b0 * t * p1 + b1 * t2 * p2 + 2.0 * b2 * t3 * p3 + 6.0 * b3 * t4 * p4
    ix = (x0 * t * p1 + b0 * t2 * p2 + b1 * t3 * p3 + 2.0 * b2 * t4 * p4
          + 6.0 * b3 * t4 * t * p5)
    return xt, ix


@njit(cache=True, nogil=True)
def lag_step(x0: float, b: npt.NDArray[np.float64], k_s: float, t: float,
             phi: npt.NDArray[np.float64]) -> tuple[float, float]:
    """Exact ``x(t)`` and ``∫_0^t x`` of ``x' = b(τ) - x/K``; also fills ``phi``."""
    phi_fill(t / k_s, phi)
    return lag4(x0, b[0], b[1], b[2], b[3], k_s, t)


@njit(cache=True, nogil=True)
def free4(x0: float, b0: float, b1: float, b2: float, b3: float, t: float
          ) -> tuple[float, float]:
    """Exact ``x(t)`` and ``∫_0^t x`` of ``x' = b(τ)`` (no output, Δl ≤ 0)."""
    xt = x0 + t * (b0 + t * (0.5 * b1 + t * (b2 / 3.0 + t * 0.25 * b3)))
    ix = x0 * t + t * t * (0.5 * b0 + t * (b1 / 6.0 + t * (b2 / 12.0 + t * b3 / 20.0)))
    return xt, ix


@njit(cache=True, nogil=True)
def slope_factor(v: float, sa: float, sb: float, sc: float) -> float:
    """Slip gradient ``s'(v) = a + b·exp(-c·v)`` (1/N) [000 Eq. 8]; ``b = 0`` gives Eq. 6."""
    if sb == 0.0:
        return sa
    return sa + sb * math.exp(-sc * v)


@njit(cache=True, nogil=True)
def colloc4(x0: float, c0: float, c1: float, c2: float, c3: float, tau0: float, h: float,
            alpha_scale: float, k_s: float, kc: float, sa: float, sb: float, sc: float,
            s: int, ws: npt.NDArray[np.float64]) -> tuple[float, float, float]:
    """One ``s``-stage Gauss collocation step of ``x' = α - β x`` over ``[tau0, tau0 + h]``.

    The tableau is row ``s - 1`` of :data:`TABLE`; ``ws``: scratch ``(WS_ROWS, >= s)``. Returns
    ``x(tau0 + h)``, ``∫x`` and ``∫γx`` with ``γ = v s'(v)/k`` (the slip term).
    """
    r = s - 1
    tab = TABLE
    inv_k = 1.0 / k_s
    inv_kc = 1.0 / kc
    for i in range(s):
        v = poly4(c0, c1, c2, c3, tau0 + tab[r, i, TAB_C] * h)
        sp = sa
        if sb != 0.0:
            sp = sa + sb * math.exp(-sc * v)
        g = v * sp * inv_kc
        ws[WS_GAM, i] = g
        ws[WS_BETA, i] = inv_k + g
        ws[WS_ALP, i] = alpha_scale * v
    for i in range(s):
        acc = 0.0
        for j in range(s):
            hij = h * tab[r, i, TAB_A + j]
            ws[i, j] = hij * ws[WS_BETA, j]
            acc += hij * ws[WS_ALP, j]
        ws[i, i] += 1.0
        ws[WS_RHS, i] = x0 + acc
    # Gaussian elimination without pivoting: I + hβA is a small perturbation of the
    # identity for |β h| <= stiffness <= 4 (the poles of the (s,s) Padé stability function
    # lie further out), so the pivots stay near 1.
    for col in range(s):
        inv = 1.0 / ws[col, col]
        for q in range(col + 1, s):
            f = ws[q, col] * inv
            for u in range(col + 1, s):
                ws[q, u] -= f * ws[col, u]
            ws[WS_RHS, q] -= f * ws[WS_RHS, col]
    for q in range(s - 1, -1, -1):
        acc = ws[WS_RHS, q]
        for u in range(q + 1, s):
            acc -= ws[q, u] * ws[WS_RHS, u]
        ws[WS_RHS, q] = acc / ws[q, q]
    dx = 0.0
    ix = 0.0
    igx = 0.0
    for i in range(s):
        w = tab[r, i, TAB_B]
        xi = ws[WS_RHS, i]
        dx += w * (ws[WS_ALP, i] - ws[WS_BETA, i] * xi)
        ix += w * xi
        igx += w * ws[WS_GAM, i] * xi
    return x0 + h * dx, h * ix, h * igx


def colloc_step(x0: float, c: npt.NDArray[np.float64], tau0: float, h: float,
                alpha_scale: float, k_s: float, kc: float, sa: float, sb: float, sc: float,
                gl_c: npt.NDArray[np.float64], gl_b: npt.NDArray[np.float64],
                gl_a: npt.NDArray[np.float64], *scratch: npt.NDArray[np.float64]
                ) -> tuple[float, float, float]:
    """One Gauss collocation step with the ``s``-stage tableau ``gl_c, gl_b, gl_a``
    (:func:`gauss_legendre_collocation`, ``s <= MAX_STAGES``; checked against
    :data:`TABLE`, which :func:`colloc4` uses), as :func:`colloc4` (``scratch`` unused)."""
    s = int(gl_c.shape[0])
    if not (np.array_equal(TABLE[s - 1, :s, TAB_C], gl_c)
            and np.array_equal(TABLE[s - 1, :s, TAB_B], gl_b)
            and np.array_equal(TABLE[s - 1, :s, TAB_A:TAB_A + s], gl_a)):
        raise ValueError("colloc_step needs a tableau of gauss_legendre_collocation")
    ws = np.zeros((WS_ROWS, MAX_STAGES))
    out: tuple[float, float, float] = colloc4(
        float(x0), float(c[0]), float(c[1]), float(c[2]), float(c[3]), float(tau0),
        float(h), float(alpha_scale), float(k_s), float(kc), float(sa), float(sb), float(sc),
        s, ws)
    return out
