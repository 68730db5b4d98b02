"""The writer's compiled row pass against the numpy steps it replaces, on the drafts of
real slicer files (one and two tools) and on edge cases."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.compensation import compensate, emit
from flowtwin.compensation._rows_kernel import fill_rows
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
