"""One regime of the state equation over part of a segment, and the events inside it
(compiled, private; used by :mod:`flowtwin.dynamics._lag_kernel`).

:func:`advance` steps ``x = Δl`` through one regime (``_expint`` FREE / LAG / SLIP /
GRIND) exactly (closed forms, φ-functions) or by collocation substeps in the slip regime
with a varying speed; :func:`slope` gives ``x'`` and ``x''``; :func:`event_root` locates a
level crossing or a turning point of ``x`` by safeguarded Newton iteration; :func:`turn_x`
is ``x`` at a turning point. Speed polynomials travel as four floats ``c0..c3``.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit
from flowtwin.dynamics._expint import (
    FREE,
    GRIND,
    LAG,
    SLIP,
    colloc4,
    dpoly4,
    free4,
    lag4,
    poly4,
    shift4,
    slope_factor,
    stages_for,
)

__all__ = ["advance", "constant_speed", "event_root", "slope", "turn_x"]


@njit(cache=True, inline="always")
def constant_speed(c1: float, c2: float, c3: float) -> bool:
    """Whether the speed polynomial is constant."""
    return c1 == 0.0 and c2 == 0.0 and c3 == 0.0


@njit(cache=True, nogil=True)
def advance(regime: int, x0: float, c0: float, c1: float, c2: float, c3: float, ta: float,
            tb: float, ascale: float, k_s: float, kc: float, sa: float, sb: float, sc: float,
            stiffness: float, min_stages: int, ws: npt.NDArray[np.float64]
            ) -> tuple[float, float, float]:
    """``x(tb)``, ``∫x`` and ``∫γx`` from ``x(ta) = x0`` in one regime.

    A collocation substep uses the fewest stages (``>= min_stages``) that meet
    ``_expint.STAGE_TOL``; ``ws`` is the collocation scratch array.
    """
    length = tb - ta
    xe = x0
    ix = 0.0
    igx = 0.0
    if length == 0.0 or (length < 0.0 and regime != SLIP):
        pass
    elif regime == FREE:
        b0, b1, b2, b3 = shift4(c0, c1, c2, c3, ta, ascale)
        xe, ix = free4(x0, b0, b1, b2, b3, length)
    elif regime != SLIP:
        b0, b1, b2, b3 = shift4(c0, c1, c2, c3, ta, ascale)
        xe, ix = lag4(x0, b0, b1, b2, b3, k_s, length)
    elif length > 0.0 and constant_speed(c1, c2, c3):
        # constant speed: constant β = 1/K + γ, the exact exponential step with K' = 1/β
        g = c0 * slope_factor(c0, sa, sb, sc) / kc
        xe, ix = lag4(x0, ascale * c0, 0.0, 0.0, 0.0, 1.0 / (1.0 / k_s + g), length)
        igx = g * ix
    else:
        # collocation substeps (backwards too, for the root search: |β h| stays small)
        b0, b1, b2, b3 = shift4(c0, c1, c2, c3, min(ta, tb), 1.0)
        span = abs(length)
        vbound = abs(b0) + span * (abs(b1) + span * (abs(b2) + span * abs(b3)))
        beta_max = 1.0 / k_s + vbound * (sa + sb) / kc
        n = int(math.ceil(span * beta_max / stiffness))
        if n < 1:
            n = 1
        h = length / n
        # stage count from β·h plus the change of the slip law's terms over a substep
        # (|v'| bounds the rate of v, c|v'| that of exp(-c v), (a + b)|v'|/k that of γ)
        dvb = abs(b1) + span * (2.0 * abs(b2) + 3.0 * span * abs(b3))
        z = abs(h) * (beta_max + dvb * ((sa + sb) / kc + (sc if sb != 0.0 else 0.0)))
        st = stages_for(z, min_stages)
        for m in range(n):
            xe, dix, digx = colloc4(xe, c0, c1, c2, c3, ta + m * h, h, ascale, k_s, kc, sa,
                                    sb, sc, st, ws)
            ix += dix
            igx += digx
    return xe, ix, igx


@njit(cache=True, nogil=True)
def slope(regime: int, c0: float, c1: float, c2: float, c3: float, tau: float, x: float,
          ascale: float, k_s: float, kc: float, sa: float, sb: float, sc: float
          ) -> tuple[float, float]:
    """``x'`` and ``x''`` at ``tau`` given ``x(tau)``."""
    v = poly4(c0, c1, c2, c3, tau)
    dv = dpoly4(c0, c1, c2, c3, tau)
    if regime == FREE:
        return ascale * v, ascale * dv
    if regime == GRIND:
        y = -x / k_s
        return y, -y / k_s
    if regime == LAG:
        y = ascale * v - x / k_s
        return y, ascale * dv - y / k_s
    if sb == 0.0:
        sp = sa
        dsp = 0.0
    else:
        ev = math.exp(-sc * v)
        sp = sa + sb * ev
        dsp = -sc * sb * ev
    beta = 1.0 / k_s + v * sp / kc
    dbeta = dv * (sp + v * dsp) / kc
    y = ascale * v - beta * x
    return y, ascale * dv - dbeta * x - beta * y


@njit(cache=True, nogil=True)
def turn_x(regime: int, c0: float, c1: float, c2: float, c3: float, tau: float,
           ascale: float, k_s: float, kc: float, sa: float, sb: float, sc: float) -> float:
    """``x`` at a turning point (``x' = 0``): ``α/β`` of the regime."""
    v = poly4(c0, c1, c2, c3, tau)
    if regime == LAG:
        return k_s * ascale * v
    return ascale * v / (1.0 / k_s + v * slope_factor(v, sa, sb, sc) / kc)


@njit(cache=True, nogil=True)
def event_root(which: int, regime: int, x0: float, c0: float, c1: float, c2: float, c3: float,
               ta: float, lo: float, hi: float, glo: float, ghi: float, level: float, tol: float,
               ascale: float, k_s: float, kc: float, sa: float, sb: float, sc: float,
               stiffness: float, min_stages: int, ws: npt.NDArray[np.float64],
               tau_start: float) -> float:
    """Root in ``[lo, hi]`` of ``g = x - level`` (``which = 0``) or ``g = x'`` (``which = 1``).

    ``glo``, ``ghi`` are ``g`` at the bracket ends (opposite signs); ``x(ta) = x0``.
    Safeguarded Newton from the regula-falsi point: a step leaving the bracket is replaced
    by bisection. Stops when a step is below ``tol`` times the bracket (a turning point
    needs little: ``x`` is stationary there, an error δτ changes it by O(δτ²)).
    ``tau_start`` inside ``(lo, hi)`` replaces the regula-falsi start
    (:func:`flowtwin.dynamics._roots.hermite_root`).
    """
    if glo == 0.0:
        return lo
    if ghi == 0.0:
        return hi
    span = hi - lo
    if lo < tau_start < hi:
        tau = tau_start
    else:
        tau = lo + span * glo / (glo - ghi)
    if not (lo < tau < hi):
        tau = 0.5 * (lo + hi)
    # closed forms are evaluated from ta; collocation steps from the previous iterate
    t_cur = ta
    x_cur = x0
    stepping = regime == SLIP and not constant_speed(c1, c2, c3)
    for _ in range(200):
        x = advance(regime, x_cur, c0, c1, c2, c3, t_cur, tau, ascale, k_s, kc, sa, sb, sc,
                    stiffness, min_stages, ws)[0]
        if stepping:
            t_cur = tau
            x_cur = x
        y, dy = slope(regime, c0, c1, c2, c3, tau, x, ascale, k_s, kc, sa, sb, sc)
        if which == 0:
            g = x - level
            dg = y
        else:
            g = y
            dg = dy
        if g == 0.0:
            return tau
        if (g > 0.0) == (glo > 0.0):
            lo = tau
            glo = g
        else:
            hi = tau
        if hi - lo <= 4e-16 * max(abs(hi), span):
            return 0.5 * (lo + hi)
        step_ok = False
        if dg != 0.0:
            nt = tau - g / dg
            if lo < nt < hi:
                if abs(nt - tau) <= tol * span:
                    return nt
                tau = nt
                step_ok = True
        if not step_ok:
            tau = 0.5 * (lo + hi)
    return 0.5 * (lo + hi)
