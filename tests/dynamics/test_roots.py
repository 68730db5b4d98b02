"""Root finding of the compiled integrator (private module ``_roots``)."""

from __future__ import annotations

import numpy as np
import pytest

from flowtwin.dynamics._roots import hermite_root, speed_roots


def test_hermite_root_is_exact_on_a_cubic() -> None:
    # the cubic Hermite interpolant of a cubic is the cubic itself: its root in the bracket
    # is found to rounding (seeded random cubics with one sign change in (lo, hi))
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(200):
        root = rng.uniform(0.1, 0.9)
        a, b = rng.uniform(-3, 3, 2)
        lo, hi = 0.0, rng.uniform(0.5, 2.0)
        r = root * hi

        def g(t: float, r: float = r, a: float = a, b: float = b) -> float:
            return (t - r) * (1.0 + a * a + (t - r) * b * (t - r) / 4.0)

        def dg(t: float, r: float = r, a: float = a, b: float = b) -> float:
            return 1.0 + a * a + 0.75 * b * (t - r) ** 2

        if g(lo) * g(hi) >= 0.0:
            continue
        got = hermite_root(lo, hi, g(lo), dg(lo), g(hi), dg(hi))
        # tolerance: the Newton iteration stops at a step of 1e-12 of the bracket
        assert got == pytest.approx(r, abs=1e-11 * hi)
        checked += 1
    assert checked > 100


def test_speed_roots_are_the_sign_changes_of_the_cubic() -> None:
    # seeded random cubic speeds: every real root inside (0, T) where the cubic changes
    # sign, in order, against numpy's eigenvalue roots; tolerance 1e-9 of T (eigenvalue
    # roots of a cubic are accurate to ~1e-12 relative here; the Newton search is exact
    # to rounding)
    rng = np.random.default_rng(11)
    out = np.empty(8)
    found = 0
    for _ in range(500):
        c = rng.uniform(-5, 5, 4)
        t_len = rng.uniform(0.1, 3.0)
        n = speed_roots(c[0], c[1], c[2], c[3], t_len, out)
        r = np.roots(c[::-1])
        real = np.sort(r[np.abs(r.imag) < 1e-12].real)
        inside = [x for x in real if 1e-9 < x < t_len - 1e-9
                  and np.polyval(c[::-1], x - 1e-7) * np.polyval(c[::-1], x + 1e-7) < 0]
        assert n == len(inside)
        np.testing.assert_allclose(out[:n], inside, rtol=0, atol=1e-9 * t_len)
        found += n
    assert found > 100
