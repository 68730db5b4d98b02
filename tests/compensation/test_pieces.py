"""Cutting moves at the planner's phase boundaries."""

from __future__ import annotations

import numpy as np
import pytest

from flowtwin.compensation.pieces import phase_distance_mm, split_rows
from flowtwin.planner.timeline import PHASE_DTYPE, Timeline


def timeline(rows: list[tuple[float, float, float, float, float]]) -> Timeline:
    """Consecutive moves from ``(start_v, cruise_v, end_v, accel, cruise_t)``."""
    ph = np.zeros(len(rows), PHASE_DTYPE)
    t = 0.0
    for i, (v0, vc, v1, a, tc) in enumerate(rows):
        ta = (vc - v0) / a
        td = (vc - v1) / a
        ph[i] = (t, v0, vc, v1, a, ta, tc, td)
        t += ta + tc + td
    return Timeline(phases=ph, total_time_s=t)


def test_phase_distance_is_the_trapezoid() -> None:
    # 0 → 50 mm/s at 1000 mm/s², 0.5 s cruise, → 0: 1.25 + 25 + 1.25 mm
    sv, cv, ev, ta, tc, td = (np.array([v]) for v in (0.0, 50.0, 0.0, 0.05, 0.5, 0.05))
    for tau, dist, speed in ((0.025, 0.3125, 25.0), (0.05, 1.25, 50.0), (0.3, 13.75, 50.0),
                             (0.575, 27.1875, 25.0), (0.6, 27.5, 0.0), (0.7, 27.5, 0.0)):
        d, v = phase_distance_mm(sv, cv, ev, ta, tc, td, np.array([tau]))
        assert d[0] == pytest.approx(dist, abs=1e-12)
        assert v[0] == pytest.approx(speed, abs=1e-9)


def test_cut_at_phase_boundaries_and_subpieces() -> None:
    tl = timeline([(0.0, 50.0, 0.0, 1000.0, 0.5), (0.0, 50.0, 0.0, 1000.0, 0.5)])
    p = split_rows(tl, np.array([True, False]), accel_pieces=1, min_piece_mm=0.1)
    assert p.counts.tolist() == [3, 1]
    np.testing.assert_allclose(p.s1_mm[:3], [1.25, 26.25, 27.5], atol=1e-12)
    np.testing.assert_allclose(p.v1_mm_s[:3], [50.0, 50.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(p.fraction_end[:3], [1.25 / 27.5, 26.25 / 27.5, 1.0])
    assert p.t1_s[2] == pytest.approx(0.6) and p.t0_s[3] == pytest.approx(0.6)
    # two equal-time pieces per ramp: cuts at 0.025 s into them
    q = split_rows(tl, np.array([True, True]), accel_pieces=2, min_piece_mm=0.1)
    assert q.counts.tolist() == [5, 5]
    np.testing.assert_allclose(q.s1_mm[:5], [0.3125, 1.25, 26.25, 27.1875, 27.5], atol=1e-12)
    # the pieces of a row tile it exactly
    np.testing.assert_allclose(np.bincount(q.row, weights=q.length_mm), [27.5, 27.5])


def test_short_pieces_merge() -> None:
    tl = timeline([(0.0, 10.0, 0.0, 1000.0, 0.001)])  # 0.05 mm ramps, 0.01 mm cruise
    p = split_rows(tl, np.array([True]), accel_pieces=4, min_piece_mm=0.1)
    assert p.counts.tolist() == [1]
    p = split_rows(tl, np.array([True]), accel_pieces=1, min_piece_mm=0.0)
    assert p.counts.tolist() == [3]


def test_phase_only_rows_get_no_subpieces() -> None:
    tl = timeline([(0.0, 100.0, 0.0, 1000.0, 0.2)])
    p = split_rows(tl, np.array([False]), accel_pieces=4, max_piece_s=0.01,
                   phase_only=np.array([True]))
    assert p.counts.tolist() == [3]
