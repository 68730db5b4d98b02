"""The original file's E split over an arc's chords: the compiled pass against the numpy
loop it replaces (``numpy.sum``, ``cumsum``, ``rint`` per line), on real slicer files
with arcs and on edge cases."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation._grid_kernel import MAX_ROWS, _numpy_sum, split_lines
from flowtwin.compensation.original import split_line
from flowtwin.gcode.reader import read_gcode


def _numpy_split(de: Any, first: Any, counts: Any, line_grid: Any, out: Any) -> None:
    """The loop as the original file's reader ran it (every line of several rows)."""
    for k in np.flatnonzero(counts != 1).tolist():
        a, b = int(first[k]), int(first[k] + counts[k])
        out[a:b] = split_line(de[a:b], int(line_grid[k]))


def _assert_same(de: Any, first: Any, counts: Any, line_grid: Any) -> int:
    want = np.zeros(de.size, dtype=np.int64)
    _numpy_split(de, first, counts, line_grid, want)
    got = np.zeros(de.size, dtype=np.int64)
    left = split_lines(de, first, counts, line_grid, got)
    for k in left.tolist():  # the caller's part
        assert counts[k] > MAX_ROWS or float(np.sum(de[first[k]:first[k] + counts[k]])) == 0.0
        a, b = int(first[k]), int(first[k] + counts[k])
        got[a:b] = want[a:b]
    np.testing.assert_array_equal(got, want)
    return int(np.count_nonzero(counts > 1)) - int(left.size)


def test_numpy_sum_is_numpys() -> None:
    rng = np.random.default_rng(2)
    for n in [*range(0, 300), 1000, 4096]:
        for _ in range(5):
            a = rng.normal(size=n + 3) * 10.0 ** rng.integers(-6, 6, size=n + 3)
            a[1] = -0.0
            assert _numpy_sum(a, 1, n) == np.sum(a[1:1 + n])
            assert np.float64(_numpy_sum(a, 1, n)).tobytes() == np.sum(a[1:1 + n]).tobytes()


def test_edge_cases() -> None:
    e = np.zeros(0, dtype=np.int64)
    assert _assert_same(np.zeros(0), e, e, e) == 0  # no row
    assert _assert_same(np.array([0.5]), np.array([0]), np.array([1]), np.array([50])) == 0
    # a line whose rows sum to zero (spread evenly, by the caller), a retraction split in
    # three, a long line left to the caller
    de = np.concatenate(([0.2, -0.2], [-0.1, -0.3, -0.05], np.full(MAX_ROWS + 1, 1e-3)))
    first = np.array([0, 2, 5])
    counts = np.array([2, 3, MAX_ROWS + 1])
    assert _assert_same(de, first, counts, np.array([0, -45, 4097])) == 1


@pytest.mark.corpus
@pytest.mark.parametrize("name", ["arcwelder_1.2.0_on_slic3r_1.33.3_benchy.gcode",
                                  "prusaslicer_2.7.1_benchy.gcode"])
def test_arcs_of_slicer_files(name: str, corpus_dir: Path) -> None:
    """Every arc's chords of a real file, E on the file's own grid (5 decimals)."""
    mv = read_gcode(corpus_dir / name).moves
    lines = np.asarray(mv["line"], dtype=np.int64)
    first = np.flatnonzero(np.concatenate(([True], lines[1:] != lines[:-1])))
    counts = np.diff(np.append(first, lines.size))
    de = np.asarray(mv["de"], dtype=np.float64)
    line_grid = np.rint(np.add.reduceat(de, first) * 1e5).astype(np.int64)
    assert _assert_same(de, first, counts, line_grid) > 100
