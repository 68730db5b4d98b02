"""The column's state through a gap: ``ẋ = u − max(x, 0)/K`` [001 Eq. 15, Fig. 8].

:func:`lag_state_after` is checked against a fine numerical integration of the same
equation (RK4 with the kink of ``max(x, 0)`` resolved by small steps) and against the
closed forms of its simple cases; :func:`run_start_flow` on a purge blob held by a
retraction over a travel.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowtwin.compensation.column import carried_flows, lag_state_after, run_start_flow


def _integrate(x0: float, volume: float, duration: float, k: float, steps: int = 20000
               ) -> float:
    """RK4 of ``ẋ = V/T − max(x, 0)/K``; the right-hand side is Lipschitz with a kink at
    0, so the error is O(h²) there: 20 000 steps leave < 1e-6 of the scales used here."""
    u = volume / duration
    h = duration / steps
    x = x0

    def f(y: float) -> float:
        return u - max(y, 0.0) / k

    for _ in range(steps):
        k1 = f(x)
        k2 = f(x + 0.5 * h * k1)
        k3 = f(x + 0.5 * h * k2)
        k4 = f(x + h * k3)
        x += h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


@pytest.mark.parametrize(("x0", "volume", "duration", "k"), [
    (0.2, 1.0, 0.3, 0.08),     # feeding a charged column
    (0.2, 0.0, 0.5, 0.08),     # decay (ooze over a travel)
    (0.2, -1.0, 0.05, 0.08),   # a retraction that empties it and goes on
    (0.5, -0.05, 0.05, 0.08),  # a small retraction that does not empty it
    (-0.5, 1.2, 0.4, 0.06),    # a push-back that fills the retraction and charges it
    (-0.5, 0.3, 0.4, 0.06),    # one that does not fill it
    (-0.3, 0.0, 1.0, 0.06),    # a held retraction: nothing flows
    (0.0, 3.0, 1.44, 0.06),    # a purge blob from rest
])
def test_lag_state_after_is_the_integrated_lag(x0: float, volume: float, duration: float,
                                               k: float) -> None:
    exact = lag_state_after(x0, volume, duration, k)
    assert exact == pytest.approx(_integrate(x0, volume, duration, k), abs=1e-6)


def test_lag_state_after_closed_forms() -> None:
    # decay: x0·exp(−T/K); steady feed from rest: u·K·(1 − exp(−T/K)) [001 Eq. 15]
    assert lag_state_after(0.3, 0.0, 0.2, 0.1) == pytest.approx(0.3 * math.exp(-2.0),
                                                                rel=1e-12)
    assert lag_state_after(0.0, 2.0, 1.0, 0.1) == pytest.approx(2.0 * 0.1 * (1 - math.exp(-10)),
                                                                rel=1e-12)
    # at once: the volume is added (no time to flow); no backflow below zero
    assert lag_state_after(0.2, -0.5, 0.0, 0.1) == pytest.approx(-0.3)
    assert lag_state_after(-0.3, 0.0, 5.0, 0.1) == -0.3
    # K = 0: nothing is stored
    assert lag_state_after(0.2, 1.0, 0.5, 0.0) == 0.0


def test_a_retraction_holds_a_purge_blob_into_the_next_run() -> None:
    """Rows: run end (0), blob (1: 3 mm³ over 1.44 s), retraction (2: −1.1 mm³ at once),
    travel (3: 1 s), push-back (4: +1.1 mm³ at once), run start (5). The retraction is
    larger than the blob's stored volume, so the column keeps it through the travel and
    the next run starts with the blob's outflow; without the retraction it oozes away."""
    k = 0.06
    t_start = np.array([0.0, 1.0, 2.44, 2.44, 3.44, 3.44])
    t_end = np.array([1.0, 2.44, 2.44, 3.44, 3.44, 3.5])
    lag = np.full(6, k)
    blob = 3.0 / 1.44 * k * (1.0 - math.exp(-1.44 / k))  # u·K·(1 − e^(−T/K))
    vol = np.array([1.0, 3.0, -1.1, 0.0, 1.1, 0.1])
    q = run_start_flow(np.array([5]), np.array([0]), np.array([0.0]), volume_mm3=vol,
                       t_start_s=t_start, t_end_s=t_end, lag_k_s=lag)
    assert q[0] == pytest.approx(blob / k, rel=1e-9)
    no_retraction = vol.copy()
    no_retraction[[2, 4]] = 0.0
    q = run_start_flow(np.array([5]), np.array([0]), np.array([0.0]),
                       volume_mm3=no_retraction, t_start_s=t_start, t_end_s=t_end,
                       lag_k_s=lag)
    assert q[0] == pytest.approx(blob * math.exp(-1.0 / k) / k, rel=1e-9)
    # a plain retracting travel after a relaxed run end carries nothing
    plain = vol.copy()
    plain[1] = 0.0
    q = run_start_flow(np.array([5]), np.array([0]), np.array([0.0]), volume_mm3=plain,
                       t_start_s=t_start, t_end_s=t_end, lag_k_s=lag)
    assert q[0] == 0.0


def test_carried_flows_short_gaps_decay_long_ones_are_relieved() -> None:
    """Runs 0-1, 3, 5-6 (rows 2 and 4 travels, K = 0.1 s): a 0.03 s travel (< 0.5·K, no
    relief) carries ``Q_end·exp(−gap/K)`` [001 Eq. 15]; a 0.2 s one is relieved (none)."""
    printing = np.array([True, True, False, True, False, True, True])
    t_start = np.array([0.0, 0.1, 0.2, 0.23, 0.3, 0.5, 0.6])
    t_end = np.array([0.1, 0.2, 0.23, 0.3, 0.5, 0.6, 0.7])
    lag = np.full(7, 0.1)
    end_flow = np.array([0.0, 4.0, 0.0, 3.0, 0.0, 0.0, 0.0])
    starts, q = carried_flows(printing, end_flow, volume_mm3=np.zeros(7), t_start_s=t_start,
                              t_end_s=t_end, lag_k_s=lag, relief_lags=0.5)
    assert starts.tolist() == [3, 5]
    assert q[0] == pytest.approx(4.0 * math.exp(-0.3), rel=1e-12)
    assert q[1] == 0.0
