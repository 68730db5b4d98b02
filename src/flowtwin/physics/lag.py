"""The lag factor ``K``: the time constant of the extrusion low-pass [001, 002].

The column shortens by ``Δl = k·F`` [001 Eq. 2]; the force is the melt pressure on the
filament, ``F = ΔP·A_in = R_hyd·Q_out·A_in`` (linear pressure drop); hence
``Δl = k·R_hyd·A_in²·Q_out/A_in``, which is [001 Eq. 5] ``Δl = K·Q_out/A_in`` with

``K = k·R_hyd·A_in²``  (docs/spec.md §3.4).

Mass balance ``v_in − Q_out/A_in = dΔl/dt`` then gives ``v_in = K·dv*_out/dt + v*_out``
[001 Eq. 10], the first-order low-pass ``H(s) = 1/(1 + K·s)`` [001 Eq. 15]. [002] derives the
same filter but prints its time constant as ``const·μ·A_noz·l_hot/E_hot``: its continuity
step is inverted (it should carry the filament area), and the consistent form is
``R_hyd·A_in·l_hot/E_hot`` — about 19× larger for a 0.4 mm nozzle and 1.75 mm filament —
which is ``K`` for a column whose compliance is only its hot part, ``k = l_hot/(E_hot·A_in)``
(a data-check row of ``flowtwin reproduce theory`` shows the difference).

The lag step
------------
:func:`lag_linear` and :func:`lag_step` are the one exact solution of the lag over a
segment of constant acceleration (the commanded feed ``v(τ) = v0 + a·τ``, linear in
time), the primitive every caller builds on; the compiled integrator
(:mod:`flowtwin.dynamics._expint`) and the compensation's kernels inline the same closed
forms and their tests check them against these functions. The derivation is in
docs/physics.md §4.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.errors import DataError
from flowtwin.physics._checks import as_float_array, require_nonnegative, require_positive

__all__ = ["LagStep", "compression_from_flow_mm", "lag_factor_s", "lag_linear", "lag_phi",
           "lag_step", "step_response_fraction"]

FloatArray = npt.NDArray[np.float64]


def lag_factor_s(compliance_mm_per_n: npt.ArrayLike,
                 resistance_mpa_s_per_mm3: npt.ArrayLike,
                 filament_area_mm2: npt.ArrayLike) -> FloatArray:
    """Lag factor ``K = k·R_hyd·A_in²`` (docs/spec.md §3.4; [001 Eq. 5]; time constant of [002]).

    Units: mm/N · MPa·s/mm³ · mm⁴ = mm/N · N·s/mm⁵ · mm⁴ = s.

    Parameters
    ----------
    compliance_mm_per_n
        Column compliance ``k``, mm/N (≥ 0), any shape.
    resistance_mpa_s_per_mm3
        Hydraulic resistance ``R_hyd``, MPa·s/mm³ (≥ 0).
    filament_area_mm2
        Filament cross-section ``A_in``, mm² (> 0).

    Returns
    -------
    ndarray
        ``K``, s, broadcast shape.
    """
    area = require_positive("filament_area_mm2", filament_area_mm2)
    return require_nonnegative("compliance_mm_per_n", compliance_mm_per_n) * \
        require_nonnegative("resistance_mpa_s_per_mm3", resistance_mpa_s_per_mm3) * area * area


def compression_from_flow_mm(lag_s: npt.ArrayLike, q_out_mm3_s: npt.ArrayLike,
                             filament_area_mm2: npt.ArrayLike) -> FloatArray:
    """Steady column compression at output flow ``Q_out``: ``Δl = K·Q_out/A_in`` [001 Eq. 5].

    Parameters
    ----------
    lag_s
        ``K``, s (≥ 0).
    q_out_mm3_s
        Output volume flow, mm³/s, any shape.
    filament_area_mm2
        Filament cross-section, mm² (> 0).

    Returns
    -------
    ndarray
        ``Δl``, mm, broadcast shape.
    """
    return require_nonnegative("lag_s", lag_s) * as_float_array(q_out_mm3_s) / \
        require_positive("filament_area_mm2", filament_area_mm2)


def step_response_fraction(t_s: npt.ArrayLike, lag_s: npt.ArrayLike) -> FloatArray:
    """Output/input velocity after a feed step at ``t = 0``: ``1 − exp(−t/K)`` [001 Eq. 15].

    The inverse Laplace transform of ``H(s)/s`` with ``H(s) = 1/(1 + K·s)``; 0 for ``t < 0``.

    Parameters
    ----------
    t_s
        Time since the step, s, any shape.
    lag_s
        ``K``, s (> 0).

    Returns
    -------
    ndarray
        Fraction in [0, 1), broadcast shape.
    """
    t = as_float_array(t_s)
    k = require_positive("lag_s", lag_s)
    return np.where(t > 0.0, -np.expm1(-np.maximum(t, 0.0) / k), 0.0)


#: Pieces of one lag step: two crossings of 0 in exact arithmetic, room for rounding.
_MAX_PIECES = 8
#: ``1/(i + 3)!`` for ``i = 0 … 19``: the series of ``φ3(−y)`` to below 1e-17 relative at
#: ``y ≤ 1`` (the first term left out is ``1/23! ≈ 4e-23``; the sum is above 1/24).
_INV_FACT_3 = tuple(1.0 / math.factorial(i + 3) for i in range(20))


def lag_phi(y: float) -> tuple[float, float, float, float]:
    """``(φ0, φ1, φ2, φ3)`` at ``−y`` (``y = T/K ≥ 0``): ``φ0 = e^(−y)``,
    ``φ_(k+1)(z) = (φ_k(z) − 1/k!)/z``.

    The φ-functions of exponential integrators, exact to rounding: for ``y ≤ 1`` from the
    series of ``φ3`` and the stable backward recurrence ``φ_k = 1/k! − y·φ_(k+1)``; above,
    from ``φ1 = −expm1(−y)/y`` forward (error growth below 4 for ``y > 1``).

    Parameters
    ----------
    y
        ``T/K``, the segment's length in lag factors (≥ 0).

    Returns
    -------
    tuple of float
        ``φ0(−y) … φ3(−y)``; ``(1, 1, 1/2, 1/6)`` at ``y = 0``.
    """
    if y <= 1.0:
        acc = 0.0
        for c in reversed(_INV_FACT_3):
            acc = acc * -y + c
        p3 = acc
        p2 = 0.5 - y * p3
        p1 = 1.0 - y * p2
        return math.exp(-y), p1, p2, p3
    p1 = -math.expm1(-y) / y
    p2 = (1.0 - p1) / y
    p3 = (0.5 - p2) / y
    return math.exp(-y), p1, p2, p3


def lag_linear(x0_mm: float, v0_mm_s: float, accel_mm_s2: float, duration_s: float,
               lag_s: float) -> tuple[float, float]:
    """The lag over a segment of constant acceleration, backflow allowed: ``x(T)``, ``∫x``.

    The column compression ``x = Δl`` obeys ``dx/dt = v(τ) − x/K`` [001 Eqs. 5, 10] with the
    commanded feed ``v(τ) = v0 + a·τ``; by variation of constants

    ``x(T) = e^(−T/K)·x0 + T·(v0·φ1 + a·T·φ2)``,
    ``∫₀ᵀ x dτ = T·(x0·φ1 + T·(v0·φ2 + a·T·φ3))``

    with ``φ_k = φ_k(−T/K)`` (:func:`lag_phi`), equal to
    ``K·(v0 + a·(T − K)) + (x0 − K·(v0 − a·K))·e^(−T/K)`` without its cancellation at
    ``T ≪ K``. This is the uncorrected lag of [001 Fig. 7] (``x`` may go negative: the melt
    would flow back); :func:`lag_step` adds the no-backflow condition. The melt out is
    ``∫x/K`` (mm of filament).

    Parameters
    ----------
    x0_mm
        Compression at the start, mm.
    v0_mm_s
        Commanded filament speed at the start, mm/s.
    accel_mm_s2
        Its rate of change ``a``, mm/s² (0: constant feed).
    duration_s
        Segment length ``T``, s (≥ 0).
    lag_s
        Lag factor ``K``, s (> 0).

    Returns
    -------
    tuple of float
        ``x(T)`` in mm and ``∫₀ᵀ x dτ`` in mm·s.

    Raises
    ------
    DataError
        ``T`` not ≥ 0 or ``K`` not > 0 (or not finite).
    """
    _check_segment(duration_s, lag_s)
    t = duration_s
    e, p1, p2, p3 = lag_phi(t / lag_s)
    x = e * x0_mm + t * (v0_mm_s * p1 + accel_mm_s2 * t * p2)
    ix = t * (x0_mm * p1 + t * (v0_mm_s * p2 + accel_mm_s2 * t * p3))
    return x, ix


@dataclass(frozen=True, slots=True)
class LagStep:
    """The lag with no backflow over one segment (:func:`lag_step`).

    Attributes
    ----------
    x_mm
        Compression at the end, mm (negative: the filament is pulled back from the melt
        by that much, a gap the feed must close before melt flows again).
    out_mm
        Melt out, ``∫ max(x, 0)/K dτ``, mm of filament (≥ 0).
    fed_mm
        Commanded filament, ``∫ v dτ``, mm; ``fed − out = x_end − x0`` (mass balance).
    """

    x_mm: float
    out_mm: float
    fed_mm: float


def lag_step(x0_mm: float, v0_mm_s: float, accel_mm_s2: float, duration_s: float,
             lag_s: float) -> LagStep:
    """The lag with no backflow over a segment of constant acceleration (exact).

    ``dx/dt = v(τ) − max(x, 0)/K``, ``v(τ) = v0 + a·τ``, out ``max(x, 0)/K``
    [001 Eqs. 5, 10, 15] with no backflow [001 Fig. 8]: the melt never flows back into the
    nozzle, so while ``x ≤ 0`` nothing flows and ``x`` follows the feed, ``dx/dt = v``.
    The segment is split where ``x`` crosses 0 — at most twice, since ``v`` changes sign at
    most once and ``x`` can only fall through 0 while ``v ≤ 0`` and rise through it while
    ``v > 0``. Each piece is closed form (:func:`lag_linear`, or the quadratic ``x`` of a
    piece with no output); a fall through 0 is located in closed form at constant feed
    (``τ0 = K·ln((x0 − v·K)/(−v·K))``) and otherwise by Newton's method on the monotone
    bracket before the minimum of ``x`` (``x`` is convex or concave in ``τ``), to rounding.

    Parameters
    ----------
    x0_mm
        Compression at the start, mm (negative: a gap left by a retraction).
    v0_mm_s
        Commanded filament speed at the start, mm/s (negative retracts).
    accel_mm_s2
        Its rate of change, mm/s².
    duration_s
        Segment length ``T``, s (≥ 0).
    lag_s
        Lag factor ``K``, s (> 0).

    Returns
    -------
    LagStep
        End state, melt out and commanded filament of the segment.

    Raises
    ------
    DataError
        ``T`` not ≥ 0 or ``K`` not > 0 (or not finite).
    """
    _check_segment(duration_s, lag_s)
    k, a = lag_s, accel_mm_s2
    x, v, left = x0_mm, v0_mm_s, duration_s
    out = 0.0
    for _ in range(_MAX_PIECES):
        if left <= 0.0:
            break
        if x > 0.0 or (x == 0.0 and (v > 0.0 or (v == 0.0 and a > 0.0))):
            tau = _fall_time(x, v, a, left, k)
            x_end, ix = lag_linear(x, v, a, tau, k)
            out += ix / k
            x = 0.0 if tau < left else x_end
        else:
            tau = _rise_time(x, v, a, left)
            x = 0.0 if tau < left else x + tau * (v + 0.5 * a * tau)
        v += a * tau
        left -= tau
    else:
        if left > 0.0:
            raise RuntimeError("lag step did not converge (crossings of 0 without end)")
    t = duration_s
    return LagStep(x, out, t * (v0_mm_s + 0.5 * a * t))


def _check_segment(duration_s: float, lag_s: float) -> None:
    if not (duration_s >= 0.0 and math.isfinite(duration_s)):
        raise DataError("a lag segment needs a duration >= 0", field="duration_s",
                        value=duration_s, allowed=">= 0 s, finite")
    if not (lag_s > 0.0 and math.isfinite(lag_s)):
        raise DataError("the lag factor must be > 0", field="lag_s", value=lag_s,
                        allowed="> 0 s, finite")


def _rise_time(x0: float, v0: float, a: float, span: float) -> float:
    """First ``τ`` in ``(0, span)`` where ``x0 + v0·τ + a·τ²/2`` rises through 0 from
    ``x0 ≤ 0``, else ``span``."""
    q = 0.5 * a
    if q == 0.0:
        if v0 > 0.0 and -x0 < v0 * span:
            return -x0 / v0
        return span
    disc = v0 * v0 - 4.0 * q * x0
    if disc < 0.0:
        return span
    root = math.sqrt(disc)
    # both roots without cancellation; the rise is at the root where the slope is > 0
    big = -0.5 * (v0 + math.copysign(root, v0))
    cands = [big / q] + ([x0 / big] if big != 0.0 else [])
    best = span
    for r in cands:
        if 0.0 <= r < best and v0 + a * r > 0.0:
            best = r
    return best


def _fall_time(x0: float, v0: float, a: float, span: float, k: float) -> float:
    """First ``τ`` in ``(0, span)`` where the lag's ``x`` (:func:`lag_linear`) falls to 0
    from ``x0 ≥ 0``, else ``span``."""
    if a == 0.0:
        if v0 >= 0.0 or x0 <= 0.0:
            return span if x0 > 0.0 or v0 >= 0.0 else 0.0
        t0 = k * math.log((x0 - v0 * k) / (-v0 * k))
        return t0 if t0 < span else span
    # x(τ) = K·(v0 + a·(τ − K)) + C·e^(−τ/K), C = x0 − K·(v0 − a·K): x'' has the sign of C
    c = x0 - k * (v0 - a * k)
    hi = span
    if c > 0.0:
        # convex: a minimum where x' = a·K − (C/K)·e^(−τ/K) = 0, if inside
        if v0 - x0 / k >= 0.0:
            return span  # rising from the start
        if a > 0.0:
            t_min = k * math.log(c / (a * k * k))
            hi = min(span, t_min)
    x_hi = lag_linear(x0, v0, a, hi, k)[0]
    if x_hi > 0.0:
        return span  # positive at both ends: concave, or convex and monotone up to hi
    # one crossing in (0, hi]: x > 0 before it, x ≤ 0 after (a start at x0 = 0 rises
    # first: concave); safeguarded Newton from the regula-falsi point
    lo = 0.0
    tau = hi * x0 / (x0 - x_hi) if x0 > 0.0 else 0.5 * hi
    for _ in range(200):
        x = lag_linear(x0, v0, a, tau, k)[0]
        if x > 0.0:
            lo = tau
        else:
            hi = tau
        slope = v0 + a * tau - x / k
        nxt = tau - x / slope if slope != 0.0 else lo - 1.0
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi)
        if abs(nxt - tau) <= 4e-16 * hi or hi - lo <= 4e-16 * hi:
            return nxt
        tau = nxt
    return hi
