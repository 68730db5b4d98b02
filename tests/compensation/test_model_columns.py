"""The lag model's per-segment columns, objective stretches and hold units: the compiled
pass against the numpy steps it replaces, on a real print's models and edge cases."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation import refine
from flowtwin.compensation._refine_kernel import model_columns

from .conftest import sizes_through_compensation


def _numpy_columns(seg_piece: Any, owner: Any, var_of_piece: Any, piece_ratio: Any, g: Any,
                   row_free: Any, row_de: Any, row_hold: Any, row_group: Any) -> tuple[Any, ...]:
    n_s = seg_piece.size
    is_gap = seg_piece < 0
    seg_var = np.where(is_gap, -1, var_of_piece[np.maximum(seg_piece, 0)])
    ratio = np.where(is_gap, 0.0, piece_ratio[np.maximum(seg_piece, 0)])
    seg_b = np.where(seg_var >= 0, g, 0.0)
    seg_c = np.where(seg_var >= 0, 0.0, g * ratio)
    change = np.ones(n_s, dtype=bool)
    change[1:] = (is_gap[1:] != is_gap[:-1]) | (owner[1:] != owner[:-1])
    unit_start = np.flatnonzero(change)
    unit_end = np.append(unit_start[1:], n_s)
    unit_is_gap = is_gap[unit_start]
    unit_row = owner[unit_start]
    unit_free = np.where(unit_is_gap, False, row_free[unit_row])
    unit_de = np.where(unit_is_gap, 0.0, row_de[unit_row])
    unit_hold = np.where(unit_is_gap, False, row_hold[unit_row])
    seg_row = np.where(is_gap, -1, row_group[owner])
    first = np.zeros(n_s, dtype=bool)
    last = np.zeros(n_s, dtype=bool)
    idx = np.flatnonzero(seg_row >= 0)
    if idx.size:
        rows_v = seg_row[idx]
        first[idx[np.concatenate(([True], rows_v[1:] != rows_v[:-1]))]] = True
        last[idx[np.concatenate((rows_v[1:] != rows_v[:-1], [True]))]] = True
    return (seg_var, ratio, seg_b, seg_c, seg_row, first, last, unit_start, unit_end,
            unit_free, unit_de, unit_hold)


def _assert_same(args: tuple[Any, ...]) -> None:
    got = model_columns(*args)
    want = list(_numpy_columns(*args))
    want[8] = want[8][:want[7].size]  # (numpy's ends of no unit: [n]; read by no one)
    for k, (a, b) in enumerate(zip(got, want, strict=True)):
        assert a.dtype == np.asarray(b).dtype or a.dtype.kind == np.asarray(b).dtype.kind, k
        assert np.asarray(a).tobytes() == np.asarray(b, dtype=a.dtype).tobytes(), k


def _case(seg_piece: list[int], owner: list[int], group: list[int]) -> tuple[Any, ...]:
    n_rows = len(group)
    n_p = max([*seg_piece, 0]) + 1
    var = np.where(np.arange(n_p) % 2 == 0, np.arange(n_p) // 2, -1).astype(np.int64)
    return (np.array(seg_piece, dtype=np.int64), np.array(owner, dtype=np.int64), var,
            np.linspace(-1.0, 2.0, n_p), np.linspace(0.5, -0.5, len(seg_piece)),
            np.arange(n_rows) % 3 == 0, np.linspace(-2.0, 2.0, n_rows),
            np.arange(n_rows) % 2 == 1, np.array(group, dtype=np.int64))


def test_edge_cases() -> None:
    _assert_same(_case([], [], [0]))  # no segment
    _assert_same(_case([-1], [0], [0]))  # one gap
    _assert_same(_case([0], [0], [-1]))  # one segment, a row without objective
    # gaps between rows, a row of several pieces, objective rows repeated and skipped
    _assert_same(_case([-1, 0, 1, 1, -1, 2, 3, -1, -1, 4], [0, 0, 0, 0, 1, 1, 2, 3, 3, 3],
                       [0, 0, -1, 1]))


@pytest.mark.corpus
def test_the_models_of_a_slicer_file(corpus_dir: Path, tmp_path: Path,
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    sizes = sizes_through_compensation(monkeypatch, refine, "model_columns", _assert_same,
                                       corpus_dir, tmp_path)
    assert sizes and max(sizes) > 1000
