"""The advance law's run pieces and targets in one compiled pass
(``_track_kernel.run_pieces``) against the array expressions it replaces, on random
runs, edge cases and a real print's passes."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation import advance
from flowtwin.compensation._track_kernel import run_pieces

from .conftest import sizes_through_compensation


def _numpy(piece_run: Any, row: Any, s0: Any, s1: Any, rate: Any, adv: Any, row_run: Any,
           run_e: Any, n_runs: int) -> tuple[Any, ...]:
    sel = np.flatnonzero(piece_run >= 0)
    pr = row[sel]
    length = (s1 - s0)[sel]
    e0_piece = rate[pr] * length
    prun = piece_run[sel] - int(piece_run[sel][0])
    first_flag = np.concatenate(([True], prun[1:] != prun[:-1]))
    run_first = np.flatnonzero(first_flag)
    run_last = np.append(run_first[1:], sel.size) - 1
    run_id = np.cumsum(first_flag) - 1
    cum = np.cumsum(e0_piece)
    cum_rel = cum - (cum - e0_piece)[run_first][run_id]
    target = cum_rel + adv[sel]
    target[run_last] = cum_rel[run_last]
    run_total = np.bincount(row_run - row_run[0], weights=run_e,
                            minlength=n_runs).astype(np.float64)
    return sel, pr, length, first_flag, run_first, run_last, run_id, target, run_total


def _assert_same(args: tuple[Any, ...]) -> None:
    got = run_pieces(*args)
    want = _numpy(*args)
    for k, (a, b) in enumerate(zip(got, want, strict=True)):
        assert a.dtype == b.dtype, k
        assert a.tobytes() == b.tobytes(), k


def _case(rng: np.random.Generator, n_rows: int, n_p: int) -> tuple[Any, ...]:
    row = np.sort(rng.integers(0, n_rows, n_p)).astype(np.int64)
    elig = rng.random(n_rows) < 0.7
    start = elig & ~np.concatenate(([False], elig[:-1]))
    row_run_all = np.cumsum(start) - 1
    run_rows = np.flatnonzero(elig)
    piece_run = np.where(elig[row], row_run_all[row], -1).astype(np.int64)
    s0 = rng.uniform(0.0, 5.0, n_p)
    s1 = s0 + np.where(rng.random(n_p) < 0.1, 0.0, rng.uniform(0.0, 3.0, n_p))
    s0[rng.random(n_p) < 0.05] = -0.0
    rate = np.where(rng.random(n_rows) < 0.1, -0.0, rng.uniform(-0.5, 3.0, n_rows))
    adv = rng.normal(size=n_p)
    run_e = rng.integers(0, 1000, run_rows.size).astype(np.float64)
    return (piece_run, row, s0, s1, rate, adv, row_run_all[run_rows].astype(np.int64), run_e,
            int(np.count_nonzero(start)))


@pytest.mark.parametrize("seed", range(6))
def test_random_runs(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for n_rows, n_p in ((1, 1), (3, 5), (40, 200), (500, 3000)):
        args = _case(rng, n_rows, n_p)
        if np.any(args[0] >= 0):
            _assert_same(args)


def test_edge_cases() -> None:
    f = np.array
    i = np.int64
    # one piece; a run of one piece between runs; a first piece of E⁰ −0.0
    _assert_same((f([0], dtype=i), f([0], dtype=i), f([0.0]), f([1.0]), f([2.0]),
                  f([0.5]), f([0], dtype=i), f([3.0]), 1))
    _assert_same((f([-1, 0, 0, 1, -1, 2], dtype=i), f([0, 1, 1, 2, 3, 4], dtype=i),
                  f([0.0, 0.0, 1.0, 0.0, 0.0, 0.0]), f([1.0, 1.0, 2.5, 2.0, 1.0, 1.0]),
                  f([1.0, 2.0, -0.0, 0.5, 1.0]), f([9.0, -1.0, 2.0, 3.0, 9.0, 0.25]),
                  f([0, 0, 1, 2], dtype=i), f([1.0, 2.0, 3.0, 4.0]), 3))
    _assert_same((f([0, 0], dtype=i), f([0, 0], dtype=i), f([0.0, 1.0]), f([0.0, 2.0]),
                  f([-0.0]), f([1.0, 1.0]), f([0], dtype=i), f([0.0]), 1))
    # no run piece: empty results
    got = run_pieces(f([-1, -1], dtype=i), f([0, 0], dtype=i), f([0.0, 0.0]), f([1.0, 1.0]),
                     f([1.0]), f([0.0, 0.0]), f([], dtype=i), f([]), 0)
    assert all(a.size == 0 for a in got)


@pytest.mark.corpus
def test_the_passes_of_a_slicer_file(corpus_dir: Path, tmp_path: Path,
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    sizes = sizes_through_compensation(monkeypatch, advance, "run_pieces", _assert_same,
                                       corpus_dir, tmp_path)
    assert len(sizes) >= 2 and max(sizes) > 1000
