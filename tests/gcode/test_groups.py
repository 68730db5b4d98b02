"""group_sums against np.unique + per-group sums (the code it replaces)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowtwin.gcode.groups import group_sums


@pytest.mark.parametrize("lo, hi", [(-1, 5), (0, 1), (-3, 300), (-(1 << 30), 1 << 30)])
def test_matches_unique(lo: int, hi: int) -> None:
    rng = np.random.default_rng(7)
    key = rng.integers(lo, hi, size=5000).astype(np.int32)
    w1 = rng.normal(size=5000)
    w2 = rng.uniform(size=5000)
    keys, counts, (s1, s2) = group_sums(key, w1, w2)
    ref_keys, ref_counts = np.unique(key, return_counts=True)
    np.testing.assert_array_equal(keys, ref_keys)
    np.testing.assert_array_equal(counts, ref_counts)
    for k, a, b in zip(keys, s1, s2, strict=True):
        # compensated vs pairwise summation of <= 5000 terms of order 1: rounding only
        assert a == pytest.approx(np.sum(w1[key == k]), rel=1e-12, abs=1e-12)
        assert b == pytest.approx(np.sum(w2[key == k]), rel=1e-12, abs=1e-12)


def test_strided_record_field_and_single_group() -> None:
    rec = np.zeros(4, dtype=[("tool", np.int16), ("de", np.float64)])
    rec["tool"] = 3
    rec["de"] = [0.1, 0.2, 0.3, -0.05]
    keys, counts, (s,) = group_sums(rec["tool"], rec["de"])
    assert keys.tolist() == [3] and counts.tolist() == [4]
    assert s[0] == math.fsum(rec["de"])  # compensated: the correctly rounded sum here


def test_empty() -> None:
    keys, counts, (s,) = group_sums(np.zeros(0, np.int16), np.zeros(0))
    assert keys.size == 0 and counts.size == 0 and s.size == 0
