"""Windowed flow error over one nozzle diameter of path: exact extremes, spots, per move."""

from __future__ import annotations

import numpy as np
import pytest

from flowtwin.compensation.metrics import window_peak
from flowtwin.errors import DataError
from flowtwin.simulation.windowed import path_lengths_mm, windowed_flow


def _brute(length: np.ndarray, cmd: np.ndarray, dlv: np.ndarray, printed: np.ndarray,
           w: float, step: float = 1e-3) -> tuple[float, float]:
    """Extremes over a dense grid of window starts, stretch by stretch (the definition)."""
    best_hi, best_lo = -np.inf, np.inf
    idx = np.flatnonzero(printed)
    runs = np.split(idx, np.flatnonzero(np.diff(idx) != 1) + 1)
    for run in runs:
        g = np.concatenate(([0.0], np.cumsum(length[run])))
        c = np.concatenate(([0.0], np.cumsum(cmd[run])))
        d = np.concatenate(([0.0], np.cumsum(dlv[run])))
        total = g[-1]
        s = np.arange(0.0, max(total - w, 0.0) + step / 2, step)
        e = np.minimum(s + w, total)
        den = np.interp(e, g, c) - np.interp(s, g, c)
        num = np.interp(e, g, d) - np.interp(s, g, d)
        ok = den > 0
        if np.any(ok):
            best_hi = max(best_hi, float(np.max(num[ok] / den[ok])) - 1.0)
            best_lo = min(best_lo, float(np.min(num[ok] / den[ok])) - 1.0)
    return best_hi, best_lo


def test_known_answer_one_move_doubled() -> None:
    # three 1 mm moves, the middle one delivers twice its command: any 0.4 mm window inside
    # it is +100 %; a window straddling its start mixes (0.2 + 0.4)/(0.4) = +50 %
    length = np.array([1.0, 1.0, 1.0])
    cmd = np.array([1.0, 1.0, 1.0])
    dlv = np.array([1.0, 2.0, 1.0])
    wf = windowed_flow(length, cmd, dlv, np.ones(3, bool), window_mm=0.4)
    assert wf.peak_over == pytest.approx(1.0)
    assert wf.peak_under == 0.0
    assert wf.centred_error.tolist() == pytest.approx([0.0, 1.0, 0.0])
    top = wf.worst_over[0]
    assert (top.first_move, top.last_move, top.centre_move) == (1, 1, 1)
    assert top.length_mm == pytest.approx(0.4)
    assert top.delivered_mm3 - top.commanded_mm3 == pytest.approx(0.4)
    # the window ending at move 0's end and the one starting at move 2's start are 0 %
    assert wf.move_max_error[1] == pytest.approx(1.0)
    assert wf.move_max_error[0] == pytest.approx(0.0)


def test_short_stretch_is_one_window_and_micrometre_moves_are_diluted() -> None:
    # a 0.03 mm move at +600 % at the end of a 2 mm stretch: over 0.4 mm of path it is
    # (0.37·1 + 0.03·7)/(0.4) − 1 = +52.5 %; isolated (its own stretch) it stays +600 %
    length = np.array([2.0, 0.03, 5.0, 0.03])
    cmd = np.array([2.0, 0.03, 0.0, 0.03])
    dlv = np.array([2.0, 0.21, 0.0, 0.21])
    printed = np.array([True, True, False, True])
    wf = windowed_flow(length, cmd, dlv, printed, window_mm=0.4)
    assert wf.peak_over == pytest.approx(6.0)          # the isolated one
    in_stretch = windowed_flow(length, cmd, dlv, np.array([True, True, False, False]),
                               window_mm=0.4)
    assert in_stretch.peak_over == pytest.approx((0.37 + 0.21) / 0.4 - 1.0)
    assert in_stretch.worst_over[0].first_move == 0
    assert in_stretch.worst_over[0].last_move == 1


def test_exact_extremes_match_a_dense_scan() -> None:
    rng = np.random.default_rng(7)
    for _ in range(20):
        n = int(rng.integers(3, 30))
        length = rng.uniform(0.005, 1.5, n)
        cmd = length * rng.uniform(0.02, 0.08, n)
        dlv = cmd * rng.uniform(0.0, 3.0, n)
        printed = rng.random(n) > 0.15
        wf = windowed_flow(length, cmd, dlv, printed, window_mm=0.4)
        hi, lo = _brute(length, cmd, dlv, printed, 0.4)
        if not np.isfinite(hi):
            continue
        # the grid can only miss the exact optimum, never exceed it
        assert wf.peak_over >= hi - 1e-9
        assert wf.peak_over == pytest.approx(hi, abs=0.02)
        assert -wf.peak_under <= min(lo, 0.0) + 1e-9
        assert -wf.peak_under == pytest.approx(min(lo, 0.0), abs=0.02)


def test_spots_are_separate_and_sorted() -> None:
    rng = np.random.default_rng(3)
    n = 400
    length = rng.uniform(0.05, 0.6, n)
    cmd = length * 0.05
    dlv = cmd * rng.uniform(0.5, 1.6, n)
    wf = windowed_flow(length, cmd, dlv, np.ones(n, bool), window_mm=0.4, spots=10)
    errs = [s.error for s in wf.worst_over]
    assert len(errs) == 10 and errs == sorted(errs, reverse=True)
    assert errs[0] == pytest.approx(wf.peak_over)
    spans = [(s.first_move, s.last_move) for s in wf.worst_over]
    for i, (a0, a1) in enumerate(spans):
        for b0, b1 in spans[i + 1:]:
            assert a1 < b0 or b1 < a0                      # no shared move
    assert wf.worst_under[0].error == pytest.approx(-wf.peak_under)


def test_compensation_window_peak_is_the_same_figure() -> None:
    rng = np.random.default_rng(11)
    length = rng.uniform(0.01, 1.0, 200)
    cmd = length * 0.05
    dlv = cmd * rng.uniform(0.7, 1.4, 200)
    printed = rng.random(200) > 0.1
    assert window_peak(length, cmd, dlv, printed, window_mm=0.4) == \
        windowed_flow(length, cmd, dlv, printed, window_mm=0.4).peak_over


def test_path_lengths_and_bad_input() -> None:
    xyz = np.array([[3.0, 4.0, 0.0], [3.0, 4.0, 1.0]])
    assert path_lengths_mm(xyz, np.zeros(3)).tolist() == [5.0, 1.0]
    with pytest.raises(DataError, match="window_mm"):
        windowed_flow(np.ones(2), np.ones(2), np.ones(2), np.ones(2, bool), window_mm=0.0)
    with pytest.raises(DataError, match="shapes"):
        windowed_flow(np.ones(2), np.ones(3), np.ones(2), np.ones(2, bool), window_mm=0.4)
    empty = windowed_flow(np.ones(2), np.ones(2), np.ones(2), np.zeros(2, bool), window_mm=0.4)
    assert empty.peak_over == 0.0 and empty.worst_over == () and np.isnan(empty.centred_error).all()


@pytest.mark.parametrize("ties", [False, True])
def test_spots_from_the_partial_sort_are_the_full_sorts(monkeypatch: pytest.MonkeyPatch,
                                                        ties: bool) -> None:
    """The worst windows are looked for among the few hundred worst candidates first (a
    partial sort); the spots are those of the sort of every candidate, ties included."""
    import flowtwin.simulation.windowed as windowed

    rng = np.random.default_rng(11)
    n = 30_000
    length = rng.exponential(0.5, n) * (rng.random(n) < 0.95)
    cmd = rng.exponential(0.05, n)
    dlv = cmd * (1.0 + rng.normal(0.0, 0.3, n))
    if ties:
        dlv = cmd.copy()
        dlv[::7] *= 1.5
        dlv[3::11] *= 0.5
    printed = (length > 0) & (rng.random(n) < 0.97)
    fields = ("error", "first_move", "last_move", "centre_move", "length_mm",
              "commanded_mm3", "delivered_mm3")

    def spots(s: int) -> tuple[list[tuple[object, ...]], list[tuple[object, ...]]]:
        wf = windowed_flow(length, cmd, dlv, printed, window_mm=0.4, spots=s)
        return ([tuple(getattr(x, f) for f in fields) for x in wf.worst_over],
                [tuple(getattr(x, f) for f in fields) for x in wf.worst_under])

    partial = {s: spots(s) for s in (1, 10, 40)}
    monkeypatch.setattr(windowed, "_HEAD_PER_SPOT", 10**9)  # every candidate sorted
    for s, got in partial.items():
        assert got == spots(s)
        assert len(got[0]) == s and len(got[1]) == s

