"""``bracketed_root`` (Illinois regula falsi with bisection safeguard) against
``scipy.optimize.brentq`` and analytic roots; ``bounded_minimum`` (golden section) against
``scipy.optimize.minimize_scalar`` and analytic minima."""

from __future__ import annotations

import math

import pytest
from scipy.optimize import brentq, minimize_scalar

from flowtwin.errors import DataError
from flowtwin.scalar_search import bounded_minimum, bracketed_root

CASES = [
    # (function, bracket, analytic root or None)
    (lambda x: x * x - 2.0, (0.0, 2.0), math.sqrt(2.0)),
    (lambda x: math.exp(x) - 10.0, (-5.0, 5.0), math.log(10.0)),
    (lambda x: math.cos(x) - x, (0.0, 1.0), None),  # the Dottie number
    (lambda x: x ** 9 - 1e-3, (0.0, 4.0), 1e-3 ** (1 / 9)),  # flat, then steep: slow for secants
    (lambda x: math.atan(50.0 * (x - 0.3)), (-10.0, 10.0), 0.3),  # nearly a step
    (lambda x: -(x - 7.5) * (1.0 + (x - 7.5) ** 2), (0.0, 100.0), 7.5),  # decreasing
    (lambda x: 1e-12 * (x - 3.0), (0.0, 10.0), 3.0),  # tiny values
]


@pytest.mark.parametrize(("fn", "bracket", "exact"), CASES)
def test_agrees_with_brentq_and_the_analytic_root(fn, bracket, exact) -> None:  # type: ignore[no-untyped-def]
    lo, hi = bracket
    ours = bracketed_root(fn, lo, hi, xtol=1e-13, rtol=1e-13)
    theirs = brentq(fn, lo, hi, xtol=1e-13, rtol=1e-13)
    assert ours == pytest.approx(theirs, abs=1e-10, rel=1e-10)
    if exact is not None:
        assert ours == pytest.approx(exact, abs=1e-11)


def test_bracket_in_either_order_and_roots_at_the_ends() -> None:
    f = lambda x: x - 1.0  # noqa: E731
    assert bracketed_root(f, 3.0, -1.0) == pytest.approx(1.0, abs=1e-12)
    assert bracketed_root(f, 1.0, 5.0) == 1.0
    assert bracketed_root(f, -5.0, 1.0) == 1.0


def test_no_sign_change_or_nan_is_refused() -> None:
    with pytest.raises(DataError, match="same sign"):
        bracketed_root(lambda x: x * x + 1.0, -1.0, 1.0)
    with pytest.raises(DataError, match="not finite"):
        bracketed_root(lambda x: math.nan, 0.0, 1.0)


def test_never_slower_than_bisection() -> None:
    """The safeguard bounds the evaluations by about twice those of bisection, even where
    regula falsi alone stalls (x^9 keeps one end fixed)."""
    calls = []

    def f(x: float) -> float:
        calls.append(x)
        return x ** 9 - 1e-3

    bracketed_root(f, 0.0, 4.0, xtol=1e-12, rtol=0.0)
    bisection_steps = math.ceil(math.log2(4.0 / 1e-12))
    assert len(calls) <= 2 * bisection_steps + 2


MINIMA = [
    (lambda x: (x - 0.3) ** 2, (0.0, 1.0), 0.3),
    (lambda x: math.cosh(4.0 * (x - 2.0)), (-3.0, 10.0), 2.0),
    (lambda x: abs(x - 0.123), (0.0, 1.0), 0.123),  # not smooth
    (lambda x: x, (1.0, 2.0), 1.0),  # at the end of the interval
]


@pytest.mark.parametrize(("fn", "interval", "exact"), MINIMA)
def test_minimum_agrees_with_minimize_scalar(fn, interval, exact) -> None:  # type: ignore[no-untyped-def]
    lo, hi = interval
    x, fx = bounded_minimum(fn, lo, hi, xatol=1e-7)
    ref = minimize_scalar(fn, bounds=interval, method="bounded", options={"xatol": 1e-7})
    assert x == pytest.approx(exact, abs=1e-6)
    assert x == pytest.approx(float(ref.x), abs=1e-5)
    assert fx == pytest.approx(fn(x))


def test_minimum_search_refuses_an_empty_interval() -> None:
    with pytest.raises(DataError, match="need lo < hi"):
        bounded_minimum(lambda x: x, 1.0, 1.0, xatol=1e-3)
