"""Searches of a scalar function on a bracket: a root, a minimum.

Both stand in for ``scipy.optimize`` (``brentq``, ``minimize_scalar(method="bounded")``) on
the paths every ``flowtwin simulate`` runs: importing ``scipy.optimize`` costs 0.2-0.6 s of
start-up (it parses ~280 docstrings), more than a whole simulation of a small file.
``tests/core/test_scalar_search.py`` checks both against scipy.

:func:`bracketed_root` is regula falsi with the Illinois modification (Dowell & Jarratt,
"A modified regula falsi method for computing the root of an equation", BIT 11 (1971)
168-174: superlinear, order ~1.44) and a bisection step whenever two steps in a row did
not halve the bracket, so it converges as fast as the secant near a simple root and never
slower than bisection.

:func:`bounded_minimum` is the golden-section search (Kiefer, "Sequential minimax search for
a maximum", Proc. AMS 4 (1953) 502-506) of a unimodal function on an interval.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from flowtwin.errors import DataError

__all__ = ["bounded_minimum", "bracketed_root"]

#: 1/φ, the golden section's shrink factor per evaluation.
_INV_PHI = (math.sqrt(5.0) - 1.0) / 2.0


def bracketed_root(fn: Callable[[float], float], lo: float, hi: float, *,
                   xtol: float = 1e-12, rtol: float = 1e-12, maxiter: int = 400) -> float:
    """A root of ``fn`` in ``[lo, hi]``, where ``fn(lo)`` and ``fn(hi)`` differ in sign.

    Parameters
    ----------
    fn
        Continuous scalar function.
    lo, hi
        The bracket (either order).
    xtol, rtol
        Stop when the bracket is narrower than ``xtol + rtol·|x|`` (or ``fn`` is exactly 0).
    maxiter
        Evaluations at most (bisection alone needs ~ log2(width / xtol)).

    Returns
    -------
    float
        The root, to within the tolerance.

    Raises
    ------
    DataError
        When ``fn`` has the same sign at both ends, is not finite there, or does not converge.
    """
    a, b = float(lo), float(hi)
    fa, fb = float(fn(a)), float(fn(b))
    if not (math.isfinite(fa) and math.isfinite(fb)):
        raise DataError(f"root search: f({a:g}) = {fa}, f({b:g}) = {fb}: not finite")
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    if (fa > 0.0) == (fb > 0.0):
        raise DataError(f"root search: f({a:g}) = {fa:g} and f({b:g}) = {fb:g} have the same "
                        "sign: no bracketed root")
    side = 0  # which end was kept last step: -1 the a end, +1 the b end
    width = abs(b - a)
    slow = 0
    for _ in range(maxiter):
        if slow >= 2:  # two steps without halving the bracket: bisect
            x = 0.5 * (a + b)
            slow = 0
        else:
            x = (a * fb - b * fa) / (fb - fa)
            if not (min(a, b) < x < max(a, b)):
                x = 0.5 * (a + b)
        fx = float(fn(x))
        if not math.isfinite(fx):
            raise DataError(f"root search: f({x:g}) = {fx}: not finite")
        if fx == 0.0:
            return x
        if (fx > 0.0) == (fb > 0.0):  # root in [a, x]: x replaces b
            b, fb = x, fx
            if side == -1:
                fa *= 0.5  # Illinois: the end kept twice is weighted down
            side = -1
        else:  # root in [x, b]: x replaces a
            a, fa = x, fx
            if side == +1:
                fb *= 0.5
            side = +1
        new_width = abs(b - a)
        slow = slow + 1 if new_width > 0.5 * width else 0
        width = new_width
        if width <= xtol + rtol * abs(x):
            return x
    raise DataError(f"root search did not converge in {maxiter} steps on [{lo:g}, {hi:g}]")


def bounded_minimum(fn: Callable[[float], float], lo: float, hi: float, *,
                    xatol: float) -> tuple[float, float]:
    """The minimum of a unimodal ``fn`` on ``[lo, hi]`` by golden-section search.

    Parameters
    ----------
    fn
        Scalar function, unimodal on the interval (else a local minimum is returned).
    lo, hi
        The interval, ``lo < hi``.
    xatol
        Stop when the bracket of the minimum is narrower than this (> 0).

    Returns
    -------
    tuple of float
        ``(x, fn(x))`` at the best point evaluated.

    Raises
    ------
    DataError
        When the interval is empty or not finite, or ``xatol`` is not positive.
    """
    a, b = float(lo), float(hi)
    if not (math.isfinite(a) and math.isfinite(b) and a < b and xatol > 0.0):
        raise DataError(f"minimum search: interval [{lo:g}, {hi:g}] with tolerance {xatol:g}: "
                        "need lo < hi, both finite, and a positive tolerance")
    c = b - _INV_PHI * (b - a)
    d = a + _INV_PHI * (b - a)
    fc, fd = float(fn(c)), float(fn(d))
    while b - a > xatol:
        if fc <= fd:  # the minimum is in [a, d]
            b, d, fd = d, c, fc
            c = b - _INV_PHI * (b - a)
            fc = float(fn(c))
        else:  # in [c, b]
            a, c, fc = c, d, fd
            d = a + _INV_PHI * (b - a)
            fd = float(fn(d))
    return (c, fc) if fc <= fd else (d, fd)
