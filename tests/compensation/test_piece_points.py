"""Every piece's end point along its row: the compiled pass against the array expressions
it replaces (``fraction_end``, then ``start + f·(end − start)`` and the rows' ends), on a
real print's passes and on edge cases (rows without pieces, zero-length rows)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation import bake
from flowtwin.compensation.pieces import piece_points

from .conftest import sizes_through_compensation


def _numpy_points(row: Any, s1: Any, row_length: Any, offsets: Any, start: Any,
                  end: Any) -> Any:
    length = row_length[row]
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(length > 0, s1 / length, 1.0)
    counts = np.diff(offsets)
    last = offsets[1:] - 1
    f[last[counts > 0]] = 1.0
    xyz = start[row] + f[:, None] * (end[row] - start[row])
    xyz[last] = end
    return xyz


def _assert_same(args: tuple[Any, ...]) -> None:
    assert piece_points(*args).tobytes() == _numpy_points(*args).tobytes()


def _case(counts: list[int], seed: int) -> tuple[Any, ...]:
    rng = np.random.default_rng(seed)
    n_rows = len(counts)
    offsets = np.concatenate(([0], np.cumsum(counts))).astype(np.int64)
    row = np.repeat(np.arange(n_rows), counts).astype(np.int64)
    row_length = np.where(rng.random(n_rows) < 0.2, 0.0, rng.random(n_rows) * 10)
    s1 = rng.random(row.size) * 10
    end = rng.normal(size=(n_rows, 3)) * 50
    start = np.vstack([rng.normal(size=(1, 3)), end[:-1]]) if n_rows else np.zeros((0, 3))
    return row, s1, row_length, offsets, start, end


def test_edge_cases() -> None:
    _assert_same(_case([], 1))  # nothing
    assert piece_points(*_case([0, 0], 2)).shape == (0, 3)  # rows, no piece (numpy: raised)
    _assert_same(_case([1], 3))
    _assert_same(_case([0, 2, 0, 3, 1, 0], 4))  # rows without pieces, first and last too
    _assert_same(_case(list(np.random.default_rng(5).integers(0, 4, 300)), 6))


@pytest.mark.corpus
def test_the_passes_of_a_slicer_file(corpus_dir: Path, tmp_path: Path,
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    sizes = sizes_through_compensation(monkeypatch, bake, "piece_points", _assert_same,
                                       corpus_dir, tmp_path)
    assert sizes and max(sizes) > 1000
