"""The outputs' rows without their zero entries in one compiled pass
(``_program_kernel.drop_zeros``) against the numpy filter it replaces, on random rows,
edge cases and a real print's refinements (``Chain.outputs``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation import compensate, program
from flowtwin.compensation._program_kernel import drop_zeros


def _numpy(ptr: Any, col: Any, val: Any) -> tuple[Any, ...]:
    n_rows = ptr.size - 1
    keep = val != 0.0
    row_of = np.repeat(np.arange(n_rows), np.diff(ptr))
    new_ptr = np.zeros(ptr.size, dtype=np.int64)
    np.cumsum(np.bincount(row_of[keep], minlength=n_rows), out=new_ptr[1:])
    return new_ptr, col[keep], val[keep]


def _assert_same(ptr: Any, col: Any, val: Any) -> None:
    got = drop_zeros(ptr, col, val)
    for k, (a, b) in enumerate(zip(got, _numpy(ptr, col, val), strict=True)):
        assert a.dtype == b.dtype, k
        assert a.tobytes() == b.tobytes(), k


@pytest.mark.parametrize("seed", range(4))
def test_random_rows(seed: int) -> None:
    rng = np.random.default_rng(seed)
    counts = rng.integers(0, 6, 300)
    ptr = np.concatenate(([0], np.cumsum(counts))).astype(np.int64)
    val = rng.normal(size=int(ptr[-1]))
    pick = rng.random(val.size)
    val[pick < 0.2] = 0.0
    val[(pick >= 0.2) & (pick < 0.3)] = -0.0
    val[(pick >= 0.3) & (pick < 0.33)] = np.nan
    _assert_same(ptr, rng.integers(0, 50, val.size).astype(np.int64), val)


def test_edge_cases() -> None:
    i = np.int64
    _assert_same(np.zeros(1, dtype=i), np.zeros(0, dtype=i), np.zeros(0))  # no row
    _assert_same(np.zeros(3, dtype=i), np.zeros(0, dtype=i), np.zeros(0))  # empty rows
    _assert_same(np.array([0, 2], dtype=i), np.array([0, 1], dtype=i), np.array([0.0, -0.0]))
    _assert_same(np.array([0, 1, 3], dtype=i), np.array([4, 0, 1], dtype=i),
                 np.array([np.inf, -0.0, 5.0]))


@pytest.mark.corpus
def test_the_outputs_of_a_slicer_file(corpus_dir: Path, tmp_path: Path,
                                      monkeypatch: pytest.MonkeyPatch) -> None:
    sizes: list[int] = []

    def checked(ptr: Any, col: Any, val: Any) -> Any:
        _assert_same(ptr, col, val)
        sizes.append(int(val.size))
        return drop_zeros(ptr, col, val)

    monkeypatch.setattr(program, "drop_zeros", checked)
    name = "prusaslicer_2.8.1_minicube_small.gcode"
    compensate(corpus_dir / name, tmp_path / name, advance=True, slip=True)
    assert len(sizes) >= 4 and max(sizes) > 1000
