"""Root finding of the lag integrator (compiled, private): where the commanded speed
changes sign inside a segment, and the start of the Newton search for a turning point of
the column compression.

Called by :func:`flowtwin.dynamics._lag_kernel.integrate_kernel`.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit
from flowtwin.dynamics._expint import dpoly4, poly4

__all__ = ["hermite_root", "speed_roots"]


@njit(cache=True, nogil=True)
def speed_roots(c0: float, c1: float, c2: float, c3: float, t_len: float,
                out: npt.NDArray[np.float64]) -> int:
    """Sign changes of the cubic ``v`` inside ``(0, t_len)``, sorted in ``out[:n]``;
    returns ``n``. ``out`` has length >= 8 (``out[4:8]`` is scratch)."""
    n = 0
    if abs(c0) > t_len * (abs(c1) + t_len * (abs(c2) + t_len * abs(c3))):
        return 0  # |v(0)| exceeds any change over the segment: no sign change
    if c2 == 0.0 and c3 == 0.0:
        if c1 != 0.0:
            r = -c0 / c1
            if 0.0 < r < t_len:
                out[0] = r
                n = 1
        return n
    # split at the turning points of v (roots of v' = c1 + 2 c2 t + 3 c3 t²)
    nc = 1
    out[4] = 0.0
    qa = 3.0 * c3
    qb = 2.0 * c2
    qc = c1
    if qa == 0.0:
        r = -qc / qb
        if 0.0 < r < t_len:
            out[4 + nc] = r
            nc += 1
    else:
        disc = qb * qb - 4.0 * qa * qc
        if disc > 0.0:
            sq = math.sqrt(disc)
            qq = -0.5 * (qb + math.copysign(sq, qb))
            r1 = qq / qa
            r2 = qc / qq if qq != 0.0 else r1
            lo = min(r1, r2)
            hi = max(r1, r2)
            if 0.0 < lo < t_len:
                out[4 + nc] = lo
                nc += 1
            if 0.0 < hi < t_len and hi != lo:
                out[4 + nc] = hi
                nc += 1
    out[4 + nc] = t_len
    for q in range(nc):
        a = out[4 + q]
        b = out[4 + q + 1]
        fa = poly4(c0, c1, c2, c3, a)
        fb = poly4(c0, c1, c2, c3, b)
        if fa == 0.0 or fb == 0.0 or (fa > 0.0) == (fb > 0.0):
            continue
        # safeguarded Newton on a monotone piece, from the regula-falsi point; a step that
        # leaves the bracket is replaced by bisection; to rounding
        m = a + (b - a) * fa / (fa - fb)
        if not (a < m < b):
            m = 0.5 * (a + b)
        for _ in range(200):
            fm = poly4(c0, c1, c2, c3, m)
            if fm == 0.0:
                break
            if (fm > 0.0) == (fa > 0.0):
                a = m
                fa = fm
            else:
                b = m
            mid = 0.5 * (a + b)
            if mid <= a or mid >= b:
                m = mid
                break
            dm = dpoly4(c0, c1, c2, c3, m)
            nm = m - fm / dm if dm != 0.0 else mid
            if not (a < nm < b):
                nm = mid
            elif abs(nm - m) <= 1e-15 * t_len:
                m = nm
                break
            m = nm
        out[n] = m
        n += 1
    return n


@njit(cache=True, nogil=True)
def hermite_root(lo: float, hi: float, ga: float, da: float, gb: float, db: float) -> float:
    """Root in ``(lo, hi)`` of the cubic Hermite interpolant of ``g`` (values ``ga``, ``gb``
    of opposite signs, slopes ``da``, ``db`` at the ends): the start of the Newton search
    for a turning point of ``x`` (``g = x'``), O(h⁴) from the root where the plain
    regula falsi start is O(h²). Safeguarded Newton on the cubic itself (no integration)."""
    span = hi - lo
    # g(lo + s span) = ga + s (span da) + s² q2 + s³ q3 on s ∈ [0, 1]
    p1 = span * da
    q2 = 3.0 * (gb - ga) - 2.0 * p1 - span * db
    q3 = 2.0 * (ga - gb) + p1 + span * db
    a = 0.0
    b = 1.0
    fa = ga
    s = ga / (ga - gb)
    for _ in range(40):
        f = ga + s * (p1 + s * (q2 + s * q3))
        if f == 0.0:
            break
        if (f > 0.0) == (fa > 0.0):
            a = s
            fa = f
        else:
            b = s
        df = p1 + s * (2.0 * q2 + 3.0 * s * q3)
        ns = s - f / df if df != 0.0 else -1.0
        if not (a < ns < b):
            ns = 0.5 * (a + b)
        if abs(ns - s) <= 1e-12:
            s = ns
            break
        s = ns
    return lo + s * span
