"""The compiled integrator's helpers (private module ``_lag_kernel``)."""

from __future__ import annotations

import numpy as np
import pytest

from flowtwin.dynamics._lag_kernel import _hermite_root


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
        got = _hermite_root(lo, hi, g(lo), dg(lo), g(hi), dg(hi))
        # tolerance: the Newton iteration stops at a step of 1e-12 of the bracket
        assert got == pytest.approx(r, abs=1e-11 * hi)
        checked += 1
    assert checked > 100
