"""The compensation's own lag solutions against the one lag-step primitive.

``_refine_kernel.lag_gain`` (the affine map of a segment of constant acceleration used by
the refinement) and ``column.lag_state_after`` (the column state through a gap, no
backflow) inline the exact solution of the lag; they must agree with
:func:`flowtwin.physics.lag.lag_linear` and :func:`flowtwin.physics.lag.lag_step`.
"""

from __future__ import annotations

import numpy as np
import pytest

from flowtwin.compensation._refine_kernel import lag_gain
from flowtwin.compensation.column import lag_state_after
from flowtwin.physics.lag import lag_linear, lag_step


def test_refine_segment_map_equals_the_primitive() -> None:
    # x(T) = e·x(0) + c·G for a path speed linear from v_a to v_b (input c·v). lag_gain
    # sums 1 − e·(1 + y) by its series below y = T/K = 1e-3 and stops after y⁴/8: the
    # first term left out, y⁵/30, is y³/15 ≈ 7e-11 of the acceleration's part of G there
    # (measured worst 6.4e-11 relative over 20 000 random segments); elsewhere rounding.
    rng = np.random.default_rng(21)
    for _ in range(2000):
        k = float(rng.uniform(0.005, 2.0))
        t = float(rng.choice([rng.uniform(1e-7, 2e-3), rng.uniform(1e-3, 3.0)]))
        v_a, v_b = (float(v) for v in rng.uniform(0.0, 300.0, 2))
        e, g = lag_gain(t, k, v_a, v_b)
        e_ref, _ = lag_linear(1.0, 0.0, 0.0, t, k)
        g_ref, _ = lag_linear(0.0, v_a, (v_b - v_a) / t, t, k)
        assert e == pytest.approx(e_ref, rel=1e-14)
        tol = 1e-10 if t / k < 1e-3 else 1e-12
        assert g == pytest.approx(g_ref, rel=tol, abs=1e-13 * (v_a + v_b) * t)
    assert lag_gain(0.0, 0.1, 1.0, 2.0) == (1.0, 0.0)


def test_column_state_equals_the_primitive() -> None:
    # a row's volume fed evenly over its time with no backflow [001 Fig. 8]
    rng = np.random.default_rng(22)
    for _ in range(3000):
        k = float(rng.uniform(0.01, 1.0))
        x0 = float(rng.uniform(-3.0, 3.0))
        vol = float(rng.choice([-1.0, 1.0, 1.0]) * rng.uniform(0.0, 5.0))
        t = float(rng.uniform(1e-4, 2.0))
        got = lag_state_after(x0, vol, t, k)
        ref = lag_step(x0, vol / t, 0.0, t, k).x_mm
        assert got == pytest.approx(ref, abs=1e-12 * (abs(x0) + abs(vol)))
