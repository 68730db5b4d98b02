"""The compiled block layout of the refinement's program against the numpy steps it
replaces (the blocks from the rows' spans, then stable sorts by block), on the programs a
real slicer file makes and on edge cases."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest

from flowtwin.compensation import _qp, compensate
from flowtwin.compensation._qp_blocks import block_layout, qp_blocks

IntArray = npt.NDArray[np.int64]


def _row_spans(ptr: IntArray, col: IntArray) -> tuple[IntArray, IntArray]:
    m = ptr.size - 1
    row_lo = np.zeros(m, dtype=np.int64)
    row_hi = np.zeros(m, dtype=np.int64)
    nonempty = np.flatnonzero(np.diff(ptr) > 0)
    if nonempty.size:
        row_lo[nonempty] = np.minimum.reduceat(col, ptr[nonempty])
        row_hi[nonempty] = np.maximum.reduceat(col, ptr[nonempty])
    return row_lo, row_hi


def _numpy_layout(n: int, h_r: IntArray, h_c: IntArray, c_ptr: IntArray, c_col: IntArray,
                  r_ptr: IntArray, r_col: IntArray) -> tuple[IntArray, ...]:
    """The layout as numpy computed it (orders written out in full)."""
    row_lo, row_hi = _row_spans(c_ptr, c_col)
    sq_lo, sq_hi = _row_spans(r_ptr, r_col)
    starts, ends = qp_blocks(n, h_r, h_c, np.concatenate((row_lo, sq_lo)),
                             np.concatenate((row_hi, sq_hi)))
    nb = starts.size
    h_block = np.searchsorted(starts, h_r, side="right") - 1
    h_order = np.argsort(h_block, kind="stable")
    h_ptr = np.searchsorted(h_block[h_order], np.arange(nb + 1))
    row_block = np.searchsorted(starts, row_lo, side="right") - 1
    row_order = np.argsort(row_block, kind="stable")
    row_ptr = np.searchsorted(row_block[row_order], np.arange(nb + 1))
    sq_order = np.argsort(sq_hi, kind="stable")
    sq_ptr = np.searchsorted(np.searchsorted(starts, sq_hi[sq_order], side="right") - 1,
                             np.arange(nb + 1))
    return starts, ends, h_order, h_ptr, row_order, row_ptr, sq_order, sq_ptr


def _assert_same(args: tuple[object, ...]) -> None:
    got = block_layout(*args)
    want = _numpy_layout(*args)  # type: ignore[arg-type]
    for k, (a, b) in enumerate(zip(got, want, strict=True)):
        if k in (2, 4, 6) and a.size == 0:  # nothing moves: the identity
            a = np.arange(b.size)
        np.testing.assert_array_equal(a, b, err_msg=f"output {k}")


def _csr(rows: list[list[int]]) -> tuple[IntArray, IntArray]:
    ptr = np.concatenate(([0], np.cumsum([len(r) for r in rows]))).astype(np.int64)
    col = np.array([c for r in rows for c in r], dtype=np.int64)
    return ptr, col


def test_edge_cases() -> None:
    e = np.zeros(0, dtype=np.int64)
    z = np.zeros(1, dtype=np.int64)
    _assert_same((0, e, e, z, e, z, e))  # nothing at all: one empty block
    _assert_same((1, e, e, z, e, z, e))  # one variable, no row
    ptr, col = _csr([[0]])
    _assert_same((1, np.array([0]), np.array([0]), ptr, col, ptr, col))  # one of each
    ptr, col = _csr([[2], []])  # an empty constraint row joins nothing (block 0)
    _assert_same((4, e, e, ptr, col, z, e))


def test_unordered_rows_and_entries() -> None:
    rng = np.random.default_rng(5)
    for n in (2, 7, 40):
        for _ in range(20):
            k = int(rng.integers(0, 2 * n))
            h_r = rng.integers(0, n, size=k)
            h_c = np.minimum(h_r + rng.integers(0, 3, size=k), n - 1)
            rows = [sorted(rng.choice(n, size=int(rng.integers(0, min(n, 4) + 1)),
                                      replace=False).tolist()) for _ in range(n)]
            sq = [r for r in ([sorted(rng.choice(n, size=int(rng.integers(1, min(n, 5) + 1)),
                                                 replace=False).tolist())
                               for _ in range(n // 2)])]
            c_ptr, c_col = _csr(rows)
            r_ptr, r_col = _csr(sq)
            _assert_same((n, h_r.astype(np.int64), h_c.astype(np.int64), c_ptr, c_col,
                          r_ptr, r_col))
    ptr, col = _csr([[0, 1], [1, 2], [5, 6], [3], [4]])
    starts, ends, *_ = block_layout(9, np.array([0, 3, 2]), np.array([1, 4, 2]), ptr, col,
                                    np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64))
    assert list(zip(starts.tolist(), ends.tolist(), strict=True)) == [
        (0, 3), (3, 5), (5, 7), (7, 8), (8, 9)]


@pytest.mark.corpus
def test_the_programs_of_a_slicer_file(corpus_dir: Path, tmp_path: Path,
                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """Every program the refinement solves for a real print (advance and slip) is laid out
    as numpy lays it out."""
    seen: list[tuple[object, ...]] = []

    def recorded(*args: object) -> tuple[IntArray, ...]:
        seen.append(tuple(a.copy() if isinstance(a, np.ndarray) else a for a in args))
        return block_layout(*args)  # type: ignore[no-any-return]

    monkeypatch.setattr(_qp, "block_layout", recorded)
    name = "prusaslicer_2.8.1_minicube_small.gcode"
    compensate(corpus_dir / name, tmp_path / name, advance=True, slip=True)
    assert seen
    assert max(int(np.asarray(a[0])) for a in seen) > 1000  # programs of some size
    for args in seen:
        _assert_same(args)
