"""The advance law's search of segment starts against ``numpy.searchsorted`` itself: on
starts a rounding put out of order (ties and steps down, queries right on them), on the
starts and query times of a real print's advance passes, and on edge cases."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation import advance, compensate
from flowtwin.compensation._law_kernel import search_right


def _check(arr: Any, t: Any) -> None:
    arr = np.asarray(arr, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    got = search_right(arr, t)
    assert got.size == t.size
    np.testing.assert_array_equal(got, np.searchsorted(arr, t, side="right"))


def test_edge_cases() -> None:
    _check([], [0.0, 1.0])  # nothing to search
    _check([1.0], [0.5, 1.0, 2.0])  # one start: before, on, after
    _check([2.0, 1.0], [1.0, 1.5, 2.0])  # one step down, queries in its window
    _check([0.0, 1.0, 1.0, 1.0, 2.0], [1.0, 1.0, 1.0])  # ties, the same query again
    assert search_right(np.array([1.0]), np.zeros(0)).size == 0
    # refused (the caller searches): descending queries, a NaN
    assert search_right(np.array([0.0, 1.0]), np.array([1.0, 0.5])).size == 0
    assert search_right(np.array([0.0, np.nan]), np.array([0.5])).size == 0
    assert search_right(np.array([0.0, 1.0]), np.array([np.nan])).size == 0


def test_starts_out_of_order_by_roundings() -> None:
    """Many ties and steps down of an ulp or a few, with queries right on the starts, in
    their windows and between."""
    rng = np.random.default_rng(11)
    for size in (2, 5, 40, 3000):
        for _ in range(30):
            base = np.cumsum(rng.choice([0.0, 0.0, 1e-3, 0.5], size=size))
            jitter = rng.choice([0, 0, 0, -1, -2, 1], size=size)
            arr = base + jitter * np.spacing(np.maximum(base, 1.0)) * rng.integers(1, 4, size)
            t = np.sort(np.concatenate((rng.choice(arr, size=size), base,
                                        rng.uniform(-1.0, base[-1] + 1.0, size=size))))
            _check(arr, t)


@pytest.mark.corpus
def test_the_advance_passes_of_a_slicer_file(corpus_dir: Path, tmp_path: Path,
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    """Every search the smoothed law makes for a real print (advance and slip; starts out
    of order by roundings) is numpy's."""
    calls: list[int] = []

    def checked(arr: Any, t: Any) -> Any:
        got = search_right(arr, t)
        np.testing.assert_array_equal(got, np.searchsorted(arr, t, side="right"))
        calls.append(int(np.count_nonzero(np.diff(arr) < 0)))
        return got

    monkeypatch.setattr(advance, "search_right", checked)
    name = "prusaslicer_2.8.1_minicube_small.gcode"
    compensate(corpus_dir / name, tmp_path / name, advance=True, slip=True)
    assert calls and max(calls) > 0  # starts out of order in the real passes
