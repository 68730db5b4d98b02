"""The smoothed law's segments (three per row) and their integrals: the compiled passes
against the numpy expressions they replace, on a real print's advance passes and edge
cases."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation import advance
from flowtwin.compensation._law_kernel import run_segments, segment_integrals

from .conftest import sizes_through_compensation


def _numpy_segments(t0: Any, ta: Any, tc: Any, td: Any, sv: Any, cv: Any, ev: Any, g: Any,
                    run_of_row: Any) -> tuple[Any, ...]:
    starts = np.column_stack([t0, t0 + ta, t0 + ta + tc]).ravel()
    durs = np.column_stack([ta, tc, td]).ravel()
    a0 = np.column_stack([g * sv, g * cv, g * cv]).ravel()
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.column_stack([np.where(ta > 0, g * (cv - sv) / ta, 0.0), np.zeros_like(g),
                                 np.where(td > 0, g * (ev - cv) / td, 0.0)]).ravel()
    seg_run = np.repeat(run_of_row, 3)
    first = np.ones(starts.size, dtype=bool)
    first[1:] = seg_run[1:] != seg_run[:-1]
    return starts, durs, a0, slope, first


def _numpy_integrals(starts: Any, durs: Any, a0: Any, slope: Any) -> tuple[Any, ...]:
    f1_len = a0 * durs + 0.5 * slope * durs * durs
    f2_len = 0.5 * a0 * durs ** 2 + slope * durs ** 3 / 6.0
    return f1_len, f2_len, starts + durs


def _assert_same(args: tuple[Any, ...]) -> int:
    got = run_segments(*args)
    want = _numpy_segments(*args)
    for k, (a, b) in enumerate(zip(got, want, strict=True)):
        assert a.tobytes() == np.asarray(b, dtype=a.dtype).tobytes(), k
    starts, durs, a0, slope, _ = got
    got2 = segment_integrals(starts, durs, durs ** 3, a0, slope)
    for k, (a, b) in enumerate(zip(got2, _numpy_integrals(starts, durs, a0, slope),
                                   strict=True)):
        assert a.tobytes() == b.tobytes(), k
    return int(starts.size)


def _rows(m: int, seed: int) -> tuple[Any, ...]:
    rng = np.random.default_rng(seed)
    ta = np.where(rng.random(m) < 0.3, 0.0, rng.random(m) * 0.1)
    td = np.where(rng.random(m) < 0.3, 0.0, rng.random(m) * 0.1)
    tc = np.where(rng.random(m) < 0.3, 0.0, rng.random(m))
    t0 = np.cumsum(ta + tc + td + rng.random(m) * 0.01)
    sv, cv, ev = (rng.random(m) * 100 for _ in range(3))
    g = rng.normal(size=m) * 1e-3
    g[: m // 4] = -0.0
    run = np.cumsum(rng.random(m) < 0.2).astype(np.int64)
    return (t0, ta, tc, td, sv, cv, ev, g, run)


def test_edge_cases_and_random_rows() -> None:
    assert _assert_same(_rows(0, 1)) == 0
    assert _assert_same(_rows(1, 2)) == 3
    for seed in range(5):
        _assert_same(_rows(500, seed))


@pytest.mark.corpus
def test_the_passes_of_a_slicer_file(corpus_dir: Path, tmp_path: Path,
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    sizes = sizes_through_compensation(monkeypatch, advance, "run_segments", _assert_same,
                                       corpus_dir, tmp_path)
    assert sizes and max(sizes) > 1000
