"""The rows after which the writer restores the E coordinate: the compiled merge
(``_rows_kernel.g92_after``) against the binary searches it replaces
(``emit._g92_after_searched``), on random files, edge cases and a real print's drafts."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation import compensate, emit
from flowtwin.compensation._rows_kernel import g92_after


def _assert_same(line_inert: Any, abs_e: Any, row_line: Any, changed: Any) -> None:
    original = SimpleNamespace(line_inert=np.asarray(line_inert, dtype=bool),
                               abs_e=np.asarray(abs_e, dtype=bool))
    row_line = np.asarray(row_line, dtype=np.int64)
    changed = np.asarray(changed, dtype=np.int64)
    want = emit._g92_after_searched(original, row_line, changed,  # type: ignore[arg-type]
                                    np.zeros(row_line.size, dtype=bool))
    got = np.zeros(row_line.size, dtype=bool)
    assert g92_after(original.line_inert, original.abs_e, row_line, changed, got)
    assert np.array_equal(got, want)
    # and through the writer's entry point
    assert np.array_equal(emit._g92_after(original, row_line, changed),  # type: ignore[arg-type]
                          want)


def _random_case(rng: np.random.Generator, n_lines: int) -> tuple[Any, ...]:
    line_inert = rng.random(n_lines) < rng.uniform(0.2, 0.95)
    row_line = np.sort(rng.integers(1, n_lines + 1, rng.integers(1, 3 * n_lines)))
    abs_e = rng.random(row_line.size) < 0.7
    lines = np.unique(row_line)
    changed = np.sort(rng.choice(lines, rng.integers(1, lines.size + 1), replace=False))
    return line_inert, abs_e, row_line, changed


@pytest.mark.parametrize("seed", range(8))
def test_random_files(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for n_lines in (1, 2, 5, 40, 400):
        _assert_same(*_random_case(rng, n_lines))


def test_edge_cases() -> None:
    # no line after the rewritten one may read E; every line inert
    _assert_same([False, True, True], [True, True], [1, 1], [1])
    _assert_same([True, True, True], [True, True, True], [1, 2, 3], [1, 3])
    # the next line is rewritten too; the next line has no row (abs_e of the next row,
    # of the last row past the end)
    _assert_same([False, False, False], [True, False, True], [1, 2, 3], [1, 2])
    _assert_same([False, True, False, False], [True, False], [1, 3], [1])
    _assert_same([False, False, True, False, False], [False, True, True], [1, 2, 2], [1, 2])
    # a rewritten line before any row (the searches' last row −1 is the last row)
    _assert_same([False, False, False], [True, True], [2, 3], [1])
    # relative E there: nothing to restore
    _assert_same([False, False], [False, False], [1, 2], [1])


def test_out_of_order_falls_back_to_the_searches() -> None:
    inert = np.zeros(4, dtype=bool)
    out = np.zeros(3, dtype=bool)
    assert not g92_after(inert, np.ones(3, dtype=bool), np.array([2, 1, 3]), np.array([1]), out)
    assert not g92_after(inert, np.ones(3, dtype=bool), np.array([1, 2, 3]), np.array([2, 1]),
                         out)
    assert not np.any(out)


@pytest.mark.corpus
def test_the_drafts_of_a_slicer_file(corpus_dir: Path, tmp_path: Path,
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    marked: list[int] = []
    own = emit._g92_after

    def checked(original: Any, row_line: Any, changed: Any) -> Any:
        got = own(original, row_line, changed)
        want = emit._g92_after_searched(original, row_line, changed,
                                        np.zeros(row_line.size, dtype=bool))
        assert np.array_equal(got, want)
        marked.append(int(np.count_nonzero(got)))
        return got

    monkeypatch.setattr(emit, "_g92_after", checked)
    name = "kisslicer_1.1.0.5_thinbox_small.gcode"  # absolute E (M82)
    compensate(corpus_dir / name, tmp_path / name, advance=True, slip=True)
    assert marked and max(marked) > 0
