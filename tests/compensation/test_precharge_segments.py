"""The lag model's pre-charges put on their reset segments, against the loop it replaces,
on the models and pre-charges of a real print's advance passes and on edge cases."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation import compensate
from flowtwin.compensation.refine import LagModel


def _loop_seg_c(model: LagModel, precharge: Any) -> Any:
    """The pre-charges put on one by one (the reset segment just before each piece's
    first segment)."""
    if precharge is None or not np.any(np.asarray(precharge[1]) != 0.0):
        return model.seg_c
    seg_c = model.seg_c.copy()
    first_seg = np.full(int(model.free_pieces.size), -1, dtype=np.int64)
    var, first = np.unique(model.seg_piece, return_index=True)
    first_seg[var[var >= 0]] = first[var >= 0]
    for p, y in zip(np.asarray(precharge[0]).tolist(), np.asarray(precharge[1]).tolist(),
                    strict=True):
        s = int(first_seg[p]) if 0 <= p < first_seg.size else -1
        if y != 0.0 and s > 0 and model.seg_a[s - 1] == 0.0:
            seg_c[s - 1] += y
    return seg_c


def _model() -> LagModel:
    """Three free pieces; segment 2 (before piece 1) and 5 (before piece 2) reset."""
    z = np.zeros(0, dtype=np.int64)
    seg_piece = np.array([-1, 0, -1, 1, 1, -1, 2], dtype=np.int64)
    f = np.zeros(7)
    return LagModel(seg_piece, f, f, np.array([1.0, 0.5, 0.0, 0.5, 0.5, 0.0, 0.5]), f,
                    np.arange(7.0), seg_piece, np.zeros(7, bool), np.zeros(7, bool),
                    np.arange(3, dtype=np.int64), z, 0, seg_piece, f, np.zeros(7, bool))


def test_edge_cases() -> None:
    m = _model()
    for pre in (None, (np.zeros(0, np.int64), np.zeros(0)), (np.array([1]), np.array([0.0])),
                (np.array([0, 1, 2]), np.array([2.0, 3.0, 4.0])),  # 0: no reset before
                (np.array([2, 2, -1, 7]), np.array([1.5, 0.25, 9.0, 9.0]))):  # repeated
        np.testing.assert_array_equal(m._seg_c(pre), _loop_seg_c(m, pre))
    with pytest.raises(ValueError):
        m._seg_c((np.array([1, 2]), np.array([1.0])))


@pytest.mark.corpus
def test_the_precharges_of_a_slicer_file(corpus_dir: Path, tmp_path: Path,
                                         monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[int] = []
    fast = LagModel._seg_c

    def checked(self: LagModel, precharge: Any) -> Any:
        got = fast(self, precharge)
        want = _loop_seg_c(self, precharge)
        assert got.tobytes() == want.tobytes()
        seen.append(int(np.count_nonzero(got != self.seg_c)))
        return got

    monkeypatch.setattr(LagModel, "_seg_c", checked)
    name = "prusaslicer_2.8.1_minicube_small.gcode"
    compensate(corpus_dir / name, tmp_path / name, advance=True, slip=True)
    assert seen and max(seen) > 0  # pre-charges put on in the real passes
