"""Every row's state when its own motion starts: the compiled pass against the numpy
steps it replaces, on a real print's lag models and on edge cases."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation import compensate, relief
from flowtwin.compensation._refine_kernel import row_starts


def _numpy_starts(seg_gap: Any, seg_owner: Any, states: Any, n_rows: int) -> Any:
    out = np.full(n_rows, np.nan)
    own = np.flatnonzero(~seg_gap)
    if own.size == 0:
        return out
    owners = seg_owner[own]
    first = own[np.concatenate(([True], owners[1:] != owners[:-1]))]
    out[seg_owner[first]] = np.where(first > 0, states[np.maximum(first - 1, 0)], 0.0)
    return out


def _assert_same(gap: list[bool], owner: list[int], n_rows: int) -> None:
    seg_gap = np.array(gap, dtype=bool)
    seg_owner = np.array(owner, dtype=np.int64)
    states = np.arange(1.0, seg_gap.size + 1.0)
    got = np.full(n_rows, np.nan)
    row_starts(seg_gap, seg_owner, states, got)
    assert got.tobytes() == _numpy_starts(seg_gap, seg_owner, states, n_rows).tobytes()


def test_edge_cases() -> None:
    _assert_same([], [], 3)  # no segment
    _assert_same([True, True], [0, 1], 2)  # gaps only
    _assert_same([False], [1], 2)  # one segment, the file's first: 0
    # a row's segments interrupted by a gap and another row's, then again
    _assert_same([True, False, False, True, False, False, False], [0, 0, 0, 1, 1, 0, 2], 4)


@pytest.mark.corpus
def test_the_passes_of_a_slicer_file(corpus_dir: Path, tmp_path: Path,
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[int] = []

    def checked(seg_gap: Any, seg_owner: Any, states: Any, out: Any) -> None:
        want = _numpy_starts(seg_gap, seg_owner, states, out.size)
        row_starts(seg_gap, seg_owner, states, out)
        assert out.tobytes() == want.tobytes()
        calls.append(int(np.count_nonzero(np.isfinite(out))))

    monkeypatch.setattr(relief, "row_starts", checked)
    name = "prusaslicer_2.8.1_minicube_small.gcode"
    compensate(corpus_dir / name, tmp_path / name, advance=True, slip=True)
    assert calls and max(calls) > 1000
