"""The writer's compiled row pass against the numpy steps it replaces, on the drafts of
real slicer files (one and two tools) and on edge cases."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation import compensate, draft, emit
from flowtwin.compensation._rows_kernel import changed_rows, fill_rows
from flowtwin.gcode.moves import MOVE_DTYPE


def _numpy_rows(row: Any, src: Any, xyz: Any, de: Any, feed: Any, kind: Any,
                changed_lines: Any, shift_after: Any, line_first: Any,
                changed_piece: Any) -> Any:
    """The rows as the writer made them with numpy."""
    n = row.size
    out = np.zeros(n, dtype=MOVE_DTYPE)
    out["x"], out["y"], out["z"] = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    out["de"] = de
    out["feed_mm_s"] = feed
    out["kind"] = kind
    for name in ("layer", "flow", "tool", "feature"):
        out[name] = src[name][row]
    tool = np.asarray(out["tool"], dtype=np.int64)
    if n == 0 or tool.min() == tool.max():
        out["e"] = np.cumsum(de)
    else:
        e = np.empty(n)
        for t in np.unique(tool).tolist():
            sel = tool == t
            e[sel] = np.cumsum(de[sel])
        out["e"] = e
    line = np.asarray(src["line"], dtype=np.int64)[row]
    k = np.searchsorted(changed_lines, line, side="left")
    before = np.where(k > 0, shift_after[np.maximum(k - 1, 0)], 0) if changed_lines.size \
        else np.zeros(n, dtype=np.int64)
    idx = np.arange(n)
    first_idx = np.maximum.accumulate(np.where(line_first, idx, 0)) if n else idx
    within = np.where(changed_piece, idx - first_idx, 0)
    out["line"] = (line + before + within).astype(np.int32)
    return out


def _assert_same(args: tuple[Any, ...]) -> None:
    out = np.zeros(args[0].size, dtype=MOVE_DTYPE)
    fill_rows(out, *args)
    assert out.tobytes() == _numpy_rows(*args).tobytes()


def _case(rows: list[int], lines: list[int], tools: list[int], de: list[float],
          changed: list[int], first: list[bool], in_line: list[bool]) -> tuple[Any, ...]:
    src = np.zeros(len(lines), dtype=MOVE_DTYPE)
    src["line"] = lines
    src["tool"] = tools
    src["layer"] = np.arange(len(lines))
    src["flow"] = 0.9
    n = len(rows)
    rng = np.random.default_rng(n)
    return (np.array(rows, dtype=np.int64), src, rng.normal(size=(n, 3)),
            np.array(de, dtype=np.float64), rng.uniform(1, 100, n),
            np.full(n, 10, dtype=np.uint8), np.array(changed, dtype=np.int64),
            np.cumsum(np.arange(1, len(changed) + 1)).astype(np.int64),
            np.array(first, dtype=bool), np.array(in_line, dtype=bool))


def test_edge_cases() -> None:
    _assert_same(_case([], [], [], [], [], [], []))  # no piece
    _assert_same(_case([0], [3], [0], [-0.0], [], [False], [False]))  # one, E −0.0
    _assert_same(_case([0], [3], [0], [0.5], [3], [True], [True]))  # one, rewritten
    # two tools, a line after the last rewritten one, rows out of line order
    _assert_same(_case([0, 0, 1, 2, 3, 3], [4, 9, 2, 12], [0, 1, 0, 255],
                       [0.1, 0.2, -0.3, 0.4, 0.5, -0.0], [4, 9],
                       [True, False, True, False, False, False],
                       [True, True, True, False, False, False]))


@pytest.mark.corpus
@pytest.mark.parametrize("name", ["prusaslicer_2.8.1_minicube_small.gcode",
                                  "bambustudio_1.07_2colour_cube_small.gcode"])
def test_the_drafts_of_a_slicer_file(name: str, corpus_dir: Path, tmp_path: Path,
                                     monkeypatch: pytest.MonkeyPatch) -> None:
    """Every draft the compensation lays out (advance and slip) gets the numpy rows."""
    seen: list[int] = []
    tools: set[int] = set()

    def checked(out: Any, *args: Any) -> None:
        fill_rows(out, *args)
        assert out.tobytes() == _numpy_rows(*args).tobytes()
        seen.append(int(out.size))
        tools.update(np.unique(out["tool"]).tolist())

    monkeypatch.setattr(emit, "fill_rows", checked)
    compensate(corpus_dir / name, tmp_path / name, advance=True, slip=True)
    assert seen and max(seen) > 1000
    assert (len(tools) > 1) == ("2colour" in name)  # (T255, T1000 as written too)


def _numpy_changed(row: Any, n: int, xyz: Any, mv: Any, e_grid: Any, row_e: Any, feed: Any,
                   piece_feed: Any) -> Any:
    """The rows to rewrite as the draft found them with numpy."""
    counts = np.bincount(row, minlength=n).astype(np.int64)
    orig = np.column_stack([mv["x"], mv["y"], mv["z"]]).astype(np.float64)
    changed = counts != 1
    single = np.flatnonzero(~changed)
    piece_of = np.searchsorted(row, single)
    moved = np.any(np.abs(xyz[piece_of] - orig[single]) > 1e-9, axis=1)
    e_diff = e_grid[piece_of] != row_e[single]
    changed[single] = moved | e_diff
    changed |= np.isfinite(feed)
    changed |= np.bincount(row, weights=np.isfinite(piece_feed), minlength=n) > 0
    return np.asarray(changed & (np.arange(n) >= 0))


def test_changed_rows_edge_cases() -> None:
    src = np.zeros(4, dtype=MOVE_DTYPE)
    src["x"] = [1.0, 2.0, 3.0, 4.0]
    nan = np.nan
    cases = [
        (np.zeros(0, np.int64), np.zeros((0, 3)), [], [nan] * 4, []),  # no piece at all
        # as written; moved by 2e-9; other E; cut in two; a row feed; a piece feed
        (np.array([0, 1, 2, 3]), np.array([[1, 0, 0], [2 + 2e-9, 0, 0], [3, 0, 0], [4, 0, 0]]),
         [5, 6, 9, 8], [nan, nan, nan, 1200.0], [nan, nan, nan, nan]),
        (np.array([0, 0, 2, 3]), np.array([[1, 0, 0], [1, 0, 0], [3, 0, 0], [4, 0, 0]]),
         [5, 6, 7, 8], [nan] * 4, [nan, nan, 600.0, nan]),
    ]
    for row, xyz, e, feed, piece_feed in cases:
        args = (np.asarray(row, dtype=np.int64), 4, np.asarray(xyz, dtype=np.float64), src,
                np.asarray(e, dtype=np.int64), np.array([5, 6, 7, 8], dtype=np.int64),
                np.asarray(feed, dtype=np.float64), np.asarray(piece_feed, dtype=np.float64))
        np.testing.assert_array_equal(changed_rows(*args), _numpy_changed(*args))


@pytest.mark.corpus
def test_changed_rows_of_a_slicer_file(corpus_dir: Path, tmp_path: Path,
                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """Every draft's rows to rewrite (advance and slip) are the ones numpy found."""
    seen: list[int] = []

    def checked(*args: Any) -> Any:
        got = changed_rows(*args)
        np.testing.assert_array_equal(got, _numpy_changed(*args))
        seen.append(int(np.count_nonzero(got)))
        return got

    monkeypatch.setattr(draft, "changed_rows", checked)
    name = "prusaslicer_2.8.1_minicube_small.gcode"
    compensate(corpus_dir / name, tmp_path / name, advance=True, slip=True)
    assert seen and max(seen) > 1000
