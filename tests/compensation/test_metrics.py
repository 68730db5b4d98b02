"""The flow figures: per-move and windowed peak over-extrusion."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flowtwin.compensation import flow_figures
from flowtwin.compensation.metrics import window_peak
from flowtwin.errors import DataError
from flowtwin.simulation import simulate


def _brute_window_peak(path: np.ndarray, cmd: np.ndarray, dlv: np.ndarray,
                       printed: np.ndarray, w: float, samples: int = 4001) -> float:
    """Reference: the windowed figure sampled densely along every stretch."""
    best = -np.inf
    idx = np.flatnonzero(printed)
    groups = np.split(idx, np.flatnonzero(np.diff(idx) != 1) + 1)
    for g in groups:
        edges = np.concatenate(([0.0], np.cumsum(path[g])))
        c = np.concatenate(([0.0], np.cumsum(cmd[g])))
        d = np.concatenate(([0.0], np.cumsum(dlv[g])))
        total = edges[-1]
        if total <= w:
            best = max(best, d[-1] / c[-1] - 1.0)
            continue
        s = np.linspace(0.0, total - w, samples)
        num = np.interp(s + w, edges, d) - np.interp(s, edges, d)
        den = np.interp(s + w, edges, c) - np.interp(s, edges, c)
        best = max(best, float(np.max(num / den)) - 1.0)
    return best


def test_window_peak_of_a_small_bulge_is_spread_over_the_window() -> None:
    # ten 1 mm moves at the intent; one 0.1 mm move delivers twice its volume (+100 %)
    path = np.array([1.0] * 5 + [0.1] + [1.0] * 5)
    cmd = path * 0.05                              # mm³: a uniform bead
    dlv = cmd.copy()
    dlv[5] *= 2.0
    printed = np.ones(path.size, dtype=bool)
    # any window of 0.4 mm over the small move: excess 0.005 mm³ over 0.4 mm of 0.05 mm³/mm
    assert window_peak(path, cmd, dlv, printed, window_mm=0.4) == pytest.approx(
        0.005 / (0.4 * 0.05), rel=1e-12)
    # a window shorter than the move itself sees the move's own ratio
    assert window_peak(path, cmd, dlv, printed, window_mm=0.05) == pytest.approx(1.0,
                                                                                 rel=1e-12)


def test_window_peak_stays_within_stretches_and_short_stretches_are_one_window() -> None:
    path = np.array([0.1, 0.1, 5.0, 0.2, 0.1])
    cmd = path * 0.05
    dlv = cmd * np.array([1.5, 1.0, 1.0, 1.0, 1.0])
    # row 2 (the long move) does not print: rows 0-1 and 3-4 are separate stretches
    printed = np.array([True, True, False, True, True])
    # stretch 0-1 is 0.2 mm < 0.4 mm: one window, (0.0075 + 0.005)/0.01 − 1
    assert window_peak(path, cmd, dlv, printed, window_mm=0.4) == pytest.approx(0.25,
                                                                                rel=1e-12)
    # nothing printed
    assert window_peak(path, cmd, dlv, np.zeros(5, dtype=bool), window_mm=0.4) == 0.0


def test_window_peak_is_the_maximum_over_all_windows_and_below_the_move_peak() -> None:
    rng = np.random.default_rng(7)
    n = 300
    path = rng.exponential(0.5, n)
    cmd = path * rng.uniform(0.02, 0.08, n)
    dlv = cmd * rng.uniform(0.5, 2.0, n)
    printed = rng.random(n) > 0.1
    for w in (0.1, 0.4, 2.0):
        exact = window_peak(path, cmd, dlv, printed, window_mm=w)
        brute = _brute_window_peak(path, cmd, dlv, printed, w)
        # the sampled reference can only miss the maximum (by its sampling step)
        assert exact >= brute - 1e-12
        assert exact == pytest.approx(brute, abs=2e-3)
        per_move = float(np.max(dlv[printed] / cmd[printed])) - 1.0
        assert exact <= per_move + 1e-12


def test_flow_figures_window(example: Path) -> None:
    res = simulate(example)
    rows = np.arange(len(res.plan.table))
    fig = flow_figures(res, res, rows, window_mm=0.4)
    assert fig.window_mm == 0.4
    assert np.isfinite(fig.peak_overextrusion_window)
    assert fig.peak_overextrusion_window <= fig.peak_overextrusion + 1e-12
    assert np.isnan(flow_figures(res, res, rows).peak_overextrusion_window)
    with pytest.raises(DataError, match="window_mm"):
        flow_figures(res, res, rows, window_mm=0.0)
