"""Report writing: Markdown with figures beside the claims, JSON rows, atomic files."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from flowtwin.errors import DataError
from flowtwin.reproduce import ReproContext, run, sections, write_report


def test_unknown_paper() -> None:
    with pytest.raises(DataError, match="unknown paper") as info:
        sections("nienhaus")
    assert "nienhaus2021" in (info.value.allowed or "")


def test_write_one_paper(tmp_path: Path) -> None:
    ctx = ReproContext(seed=5)
    report = write_report("greeff2017", tmp_path, ctx=ctx)
    md = tmp_path / "reproduction-greeff2017.md"
    js = tmp_path / "reproduction-greeff2017.json"
    assert report.files[:2] == [md, js]
    figs = sorted(p.name for p in (tmp_path / "figures").iterdir())
    assert figs == ["greeff2017-print-job.png", "greeff2017-slip.png"]
    text = md.read_text(encoding="utf-8")
    # the figure is shown and followed by the claims it illustrates
    i_fig = text.index("![")
    i_row = text.index("Slippage increases with decreasing temperature")
    assert text.index("figures/greeff2017-slip.png") < i_row
    assert i_fig < i_row
    assert "seed 5" in text
    data = json.loads(js.read_text(encoding="utf-8"))
    assert data["papers"] == ["greeff2017"] and data["failed"] == 0
    assert len(data["rows"]) == len(report.rows)
    # deterministic: the same seed writes the same bytes
    first = {p.name: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    write_report("greeff2017", tmp_path, ctx=ReproContext(seed=5))
    second = {p.name: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file()}
    assert first == second


def test_run_without_figures_and_seed(tmp_path: Path) -> None:
    report = write_report("theory", tmp_path, figures=False)
    assert not (tmp_path / "figures").exists()
    assert report.seed == 2021 and report.failed == 0
    assert run("greeff2017", seed=3).seed == 3
    assert "![" not in (tmp_path / "reproduction-theory.md").read_text(encoding="utf-8")
