"""Rounding of the refined piece E to the file's E grid."""

from __future__ import annotations

import numpy as np

from flowtwin.compensation.bake import round_total


def _reference(e: np.ndarray, total: int) -> np.ndarray:
    """The plain rule: scale, round the running sums, low pieces borrow from the largest
    (first index on ties), one at a time."""
    scaled = e * (total / float(np.sum(e)))
    pos = np.rint(np.cumsum(scaled)).astype(np.int64)
    pos[-1] = total
    out = np.diff(np.concatenate(([0], pos)))
    for j in np.flatnonzero(out < 1).tolist():
        k = int(np.argmax(out))
        need = 1 - int(out[j])
        if out[k] - need < 1:
            break
        out[j] += need
        out[k] -= need
    return out


def test_round_total_keeps_the_total_and_every_piece_printing() -> None:
    rng = np.random.default_rng(11)
    for trial in range(30):
        n = int(rng.integers(1, 400))
        # many pieces below one grid unit (tiny moves), a few large ones
        e = np.where(rng.random(n) < 0.4, rng.uniform(0.0, 0.8, n), rng.uniform(1, 60, n))
        total = int(round(float(np.sum(e)))) + int(rng.integers(-3, 4))
        total = max(total, n)
        out = round_total(e, total)
        assert int(np.sum(out)) == total, trial
        assert np.all(out >= 1), trial
        np.testing.assert_array_equal(out, _reference(e, total))
