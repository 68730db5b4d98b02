"""The advance law's per-piece ratio box, jump limit and envelope: the compiled pass
against the numpy expressions it replaces, on a real print's passes and on edge cases
(caps on and off, zero speeds, pulls, anchors, ties of signed zeros)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation import advance, compensate
from flowtwin.compensation._track_kernel import piece_bounds


def _numpy_bounds(rate: Any, row: Any, v_b: Any, cruise: Any, accel: Any, pull: Any,
                  target: Any, length: Any, duration: Any, run_first: Any, scalars: Any,
                  switches: Any) -> Any:
    """The law's array expressions (``follow_law`` before the compiled pass)."""
    (min_flow, retract, cap_ratio, cap_speed, cap_accel, jump_grid, anchor_s,
     band_k) = scalars.tolist()
    pulls, has_ratio, has_speed, has_accel, anchors = switches.tolist()
    c_min = min_flow * rate
    if pulls:
        c_min = np.where(pull, -retract * rate, c_min)
    c_cap = np.full(rate.size, math.inf)
    if has_ratio:
        c_cap = np.minimum(c_cap, cap_ratio)
    with np.errstate(divide="ignore", invalid="ignore"):
        if has_speed:
            c_cap = np.minimum(c_cap, np.where(cruise > 0, cap_speed / cruise, math.inf))
        if has_accel:
            c_cap = np.minimum(c_cap, np.where(accel > 0, cap_accel / accel, math.inf))
    c_max = np.maximum(c_cap, rate)
    prev_rate = np.zeros(rate.size)
    prev_rate[1:] = rate[:-1]
    same_row = np.concatenate(([False], row[1:] == row[:-1]))
    orig_step = np.where(same_row, 0.0, np.abs(rate - prev_rate))
    with np.errstate(divide="ignore", invalid="ignore"):
        dc = np.where(v_b > 1e-9, np.maximum(jump_grid, orig_step * v_b) / v_b, math.inf)
        prev_target = np.concatenate(([0.0], target[:-1]))
        prev_target[run_first] = 0.0
        c_star = (target - prev_target) / length
    anchor = (duration >= anchor_s) if anchors else np.zeros(rate.size, bool)
    band = band_k * np.abs(c_star)
    with np.errstate(invalid="ignore"):  # (a piece of no length: inf − inf)
        env_lo = np.where(anchor, c_star - band, c_min)
        env_hi = np.where(anchor, c_star + band, c_max)
    return np.stack([c_min, c_max, dc, env_lo, env_hi])


def _assert_same(args: tuple[Any, ...]) -> None:
    out = np.empty((5, args[0].size))
    piece_bounds(*args, out)
    want = _numpy_bounds(*args)
    for k in range(5):
        assert out[k].tobytes() == want[k].tobytes(), k


def _case(p: int, seed: int, switches: list[bool]) -> tuple[Any, ...]:
    rng = np.random.default_rng(seed)
    rate = np.where(rng.random(p) < 0.2, 0.0, rng.random(p) * 50)
    row = np.cumsum(rng.random(p) < 0.5).astype(np.int64)
    v_b = np.where(rng.random(p) < 0.2, 0.0, rng.random(p) * 100)
    cruise = np.where(rng.random(p) < 0.2, 0.0, rng.random(p) * 100)
    accel = np.where(rng.random(p) < 0.2, 0.0, rng.random(p) * 3000)
    target = np.cumsum(rng.random(p))
    length = rng.random(p) + 0.01
    duration = rng.random(p) * 0.05
    run_first = rng.random(p) < 0.1
    if p:
        run_first[0] = True
    scalars = np.array([0.25, 0.5, 30.0, 40.0 * 60, 2.0e5, 10.0, 0.02, 0.1])
    return (rate, row, v_b, cruise, accel, rng.random(p) < 0.3, target, length, duration,
            run_first, scalars, np.array(switches, dtype=bool))


def test_edge_cases_and_random_pieces() -> None:
    for switches in ([True] * 5, [False] * 5, [False, True, False, True, False]):
        for p, seed in ((0, 1), (1, 2), (400, 3)):
            _assert_same(_case(p, seed, switches))
    # ties of signed zeros where numpy's maximum/minimum pick the second
    args = list(_case(3, 4, [True] * 5))
    args[0] = np.array([0.0, -0.0, 0.0])
    args[10] = np.array([-0.0, 0.5, 0.0, 0.0, 0.0, -0.0, 0.02, 0.1])
    _assert_same(tuple(args))
    # a piece of no length: the target ratio infinite or undefined, as numpy divides
    args = list(_case(4, 7, [True] * 5))
    args[7] = np.array([1.0, 0.0, 0.0, 2.0])
    args[6] = np.array([1.0, 2.0, 2.0, 3.0])
    _assert_same(tuple(args))


@pytest.mark.corpus
def test_the_passes_of_a_slicer_file(corpus_dir: Path, tmp_path: Path,
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    sizes: list[int] = []

    def checked(*args: Any) -> None:
        _assert_same(args[:-1])
        piece_bounds(*args)
        sizes.append(int(args[0].size))

    monkeypatch.setattr(advance, "piece_bounds", checked)
    name = "prusaslicer_2.8.1_minicube_small.gcode"
    compensate(corpus_dir / name, tmp_path / name, advance=True, slip=True)
    assert sizes and max(sizes) > 1000
