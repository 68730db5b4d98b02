"""The compiled integrator against the one lag-step primitive (:mod:`flowtwin.physics.lag`).

The kernels inline the exact step of the lag (``_expint.lag4`` / ``free4``, the
zero-crossing events of ``_lag_kernel``); on random segments of constant acceleration —
feeds, retractions, ramps through zero, gaps — they must give what
:func:`flowtwin.physics.lag.lag_step` gives, segment by segment and over a whole feed.
"""

from __future__ import annotations

import numpy as np
import pytest

from flowtwin.dynamics import ExtrusionParams, integrate
from flowtwin.dynamics._expint import FREE, LAG, free4, lag4
from flowtwin.dynamics._regime import advance
from flowtwin.physics.lag import lag_linear, lag_step

from .conftest import feed_of


def _segments(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    dt = rng.uniform(0.002, 0.4, n)
    v0 = rng.choice([1.0, 1.0, 1.0, -1.0], n) * rng.uniform(0.0, 12.0, n)
    a = np.where(rng.uniform(size=n) < 0.3, 0.0, rng.uniform(-300.0, 300.0, n))
    return dt, v0, a


def test_exact_step_equals_the_primitive() -> None:
    rng = np.random.default_rng(5)
    ws = np.zeros((16, 6))
    for _ in range(2000):
        k = float(rng.uniform(0.005, 2.0))
        x0 = float(rng.uniform(-1.0, 1.0))
        v0, a = float(rng.uniform(-20, 20)), float(rng.uniform(-500, 500))
        t = float(rng.choice([rng.uniform(1e-7, 1e-3), rng.uniform(0.0, 3.0)]))
        x_ref, ix_ref = lag_linear(x0, v0, a, t, k)
        scale = abs(x0) + abs(v0) * t + abs(a) * t * t
        x, ix = lag4(x0, v0, a, 0.0, 0.0, k, t)
        assert x == pytest.approx(x_ref, abs=4e-15 * scale)
        assert ix == pytest.approx(ix_ref, abs=4e-15 * scale * t)
        # one regime piece of the integrator (same closed forms)
        xe, ixe, _ = advance(LAG, x0, v0, a, 0.0, 0.0, 0.0, t, 1.0, k, 0.01, 0.0, 0.0, 0.0,
                             1.0, 6, ws)
        assert (xe, ixe) == (x, ix)
        # with no output (x ≤ 0): x' = v
        xf, _ = free4(x0, v0, a, 0.0, 0.0, t)
        assert xf == pytest.approx(x0 + v0 * t + a * t * t / 2, abs=4e-15 * scale)
        xa, _, _ = advance(FREE, x0, v0, a, 0.0, 0.0, 0.0, t, 1.0, k, 0.01, 0.0, 0.0, 0.0,
                           1.0, 6, ws)
        assert xa == xf


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_integrator_equals_the_primitive_over_random_feeds(seed: int) -> None:
    # one move per segment, a lag factor per move, no slip and no force limit: the
    # integrator is then the lag with no backflow, which lag_step solves segment by segment
    rng = np.random.default_rng(seed)
    n = 300
    dt, v0, a = _segments(rng, n)
    k = rng.uniform(0.01, 0.4, n)
    feed = feed_of(dt, [[v0[i], a[i]] for i in range(n)])
    params = ExtrusionParams.build(n, lag_k_s=k, compliance_mm_per_n=0.02,
                                   filament_diameter_mm=1.75)
    res = integrate(feed, params)
    area = params.filament_area_mm2
    x = 0.0
    out = np.empty(n)
    crossings = 0
    for i in range(n):
        step = lag_step(x, float(v0[i]), float(a[i]), float(dt[i]), float(k[i]))
        crossings += (x > 0.0) != (step.x_mm > 0.0)
        x = step.x_mm
        out[i] = step.out_mm
    scale = float(np.max(np.abs(v0) * dt + np.abs(a) * dt * dt))
    assert crossings > 10                       # the no-backflow condition is exercised
    assert res.final_compression_mm == pytest.approx(x, abs=1e-12 * scale)
    np.testing.assert_allclose(res.moves["out_mm3"] / area, out, rtol=0, atol=1e-12 * scale)
    assert np.all(res.moves["out_mm3"] >= 0.0)
