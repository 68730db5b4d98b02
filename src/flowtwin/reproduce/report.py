"""Run the claims of the seed papers and write the reproduction report.

:func:`run` computes the rows of the chosen papers (``all`` or one key);
:func:`write_report` additionally draws every figure to ``<out>/figures/`` and writes the
Markdown report (``reproduction.md`` for all papers, ``reproduction-<paper>.md`` for one)
and the same rows as JSON beside it. ``docs/reproduction.md`` is produced by
``flowtwin reproduce all --out docs/`` and is never edited by hand. Output files are written
atomically; the PNGs carry no timestamp, so a rerun with the same seed gives the same files.
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from flowtwin.atomic import atomic_write_text
from flowtwin.errors import DataError
from flowtwin.reproduce import (
    greeff2017,
    jin2009,
    meltcapacity,
    nienhaus2021,
    theory,
    tronvoll2019,
)
from flowtwin.reproduce.claims import Claim, Row, RowKind
from flowtwin.reproduce.context import ReproContext
from flowtwin.reproduce.figures import PaperSection
from flowtwin.teststand.figures import save_figure

__all__ = [
    "PAPERS",
    "Report",
    "all_claims",
    "render_markdown",
    "run",
    "sections",
    "write_report",
]

#: The papers in seed order, by command key.
PAPERS: dict[str, PaperSection] = {s.key: s for s in (
    nienhaus2021.SECTION, tronvoll2019.SECTION, theory.SECTION, greeff2017.SECTION,
    jin2009.SECTION, meltcapacity.SECTION)}


def sections(which: str) -> tuple[PaperSection, ...]:
    """The sections for ``which``: a paper key or ``"all"``.

    Raises
    ------
    DataError
        Unknown key.
    """
    if which == "all":
        return tuple(PAPERS.values())
    if which not in PAPERS:
        raise DataError("unknown paper", field="paper", value=which,
                        allowed="all, " + ", ".join(PAPERS))
    return (PAPERS[which],)


def all_claims() -> tuple[Claim, ...]:
    """Every claim of every paper, in report order (one test each)."""
    return tuple(c for s in PAPERS.values() for c in s.claims)


@dataclass
class Report:
    """Rows, notes and written files of one run.

    Attributes
    ----------
    which
        ``"all"`` or a paper key.
    seed
        Seed of the run.
    rows
        One row per claim.
    notes
        Markdown paragraphs per paper key.
    files
        Files written (Markdown, JSON, figures).
    """

    which: str
    seed: int
    rows: list[Row]
    notes: dict[str, list[str]] = field(default_factory=dict)
    files: list[Path] = field(default_factory=list)

    @property
    def passed(self) -> int:
        """Rows that pass."""
        return sum(r.passed for r in self.rows)

    @property
    def failed(self) -> int:
        """Rows that fail."""
        return len(self.rows) - self.passed

    def counts(self) -> dict[str, int]:
        """Rows per kind (``reproduced``, ``anchor``, ``data check``), every kind present."""
        return {str(kind): sum(r.kind == kind for r in self.rows) for kind in RowKind}

    def kinds_line(self) -> str:
        """``"37 reproduced, 26 anchors, 6 data checks"``."""
        c = self.counts()
        return (f"{c[RowKind.REPRODUCED]} reproduced, {c[RowKind.ANCHOR]} anchors, "
                f"{c[RowKind.DATA_CHECK]} data checks")

    def as_dict(self) -> dict[str, Any]:
        """The JSON object ``flowtwin reproduce --json`` prints."""
        return {"papers": [s.key for s in sections(self.which)], "seed": self.seed,
                "rows": [r.as_dict() for r in self.rows], "counts": self.counts(),
                "passed": self.passed,
                "failed": self.failed, "files": [str(p) for p in self.files]}


def run(which: str = "all", *, seed: int = 2021,
        ctx: ReproContext | None = None) -> Report:
    """Compute the rows (and notes) of ``which``.

    Parameters
    ----------
    which
        ``"all"`` or a paper key (:data:`PAPERS`).
    seed
        Seed of every random number (virtual test stand, synthetic profiles).
    ctx
        A context to reuse (its seed wins); default a new one.

    Returns
    -------
    Report
    """
    context = ctx or ReproContext(seed=seed)
    chosen = sections(which)
    rows = [c.run(context) for s in chosen for c in s.claims]
    notes = {s.key: s.notes(context) for s in chosen}
    return Report(which, context.seed, rows, notes)


def _cell(value: object) -> str:
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list):
        return "[" + ", ".join(_cell(v) for v in value) + "]"
    return str(value)


def _esc(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def _table(rows: Sequence[Row]) -> list[str]:
    out = ["| claim | source | paper | flowtwin | unit | tolerance | pass | how |",
           "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        status = ("**pass**" if r.passed else "**FAIL**") + (
            "" if r.kind == RowKind.REPRODUCED else f" ({r.kind})")
        out.append(f"| {_esc(r.claim)} | {_esc(r.source)} | {_esc(_cell(r.paper_value))} | "
                   f"{_esc(_cell(r.flowtwin_value))} | {_esc(r.unit)} | {_esc(r.tolerance)} | "
                   f"{status} | {_esc(r.note)}{' — ' + _esc(r.engine) if r.engine else ''} |")
    return out


def render_markdown(report: Report, figure_files: dict[tuple[str, str], str]) -> str:
    """The Markdown report: per paper, each figure followed by the claims it shows.

    Parameters
    ----------
    report
        Rows and notes.
    figure_files
        ``(paper, figure name) → path`` relative to the Markdown file.

    Returns
    -------
    str
    """
    cmd = f"flowtwin reproduce {report.which} --out <folder>"
    lines = [
        "# Reproduction of the seed papers" if report.which == "all"
        else f"# Reproduction of {report.which}", "",
        f"Generated by `{cmd}` (seed {report.seed}); do not edit by hand — rerun the command. "
        "Every value in the flowtwin column is computed by the library when the command runs; "
        "every row is also a test (`tests/reproduce`). A *reproduced* row computes what the "
        "paper states from inputs not fitted to it, within the paper's printed precision or "
        "a stated physical argument. An *anchor* row holds a value flowtwin's defaults were "
        "fitted to or built on (it shows the model carries it, not that flowtwin predicts "
        "it). A *data check* row computes a disagreement inside a paper and passes when the "
        "disagreement is the documented one.",
        "", f"**{report.passed} of {len(report.rows)} rows pass: {report.kinds_line()}.**",
        "",
        "| paper | seed | rows | pass |", "|---|---|---|---|",
    ]
    chosen = sections(report.which)
    for s in chosen:
        rows = [r for r in report.rows if r.paper == s.key]
        lines.append(f"| {s.key} | [{s.seed_id}] | {len(rows)} | {sum(r.passed for r in rows)} |")
    for s in chosen:
        rows = [r for r in report.rows if r.paper == s.key]
        lines += ["", f"## [{s.seed_id}] {s.key}", "", f"*{s.title}*"]
        for fig in s.figures:
            shown = [r for r in rows if r.figure == fig.name]
            mirrors = fig.caption.split("]")[0] + "]" if fig.caption.startswith("[") else ""
            lines += ["", f"### Figure `{fig.name}` {mirrors}".rstrip(), ""]
            path = figure_files.get((s.key, fig.name))
            if path is not None:
                lines += [f"![{_esc(fig.caption)}]({path})", ""]
            lines += [f"*{fig.caption}*", ""]
            if shown:
                lines += _table(shown)
        rest = [r for r in rows if r.figure is None]
        if rest:
            lines += ["", "### Claims without a figure", "", *_table(rest)]
        if report.notes.get(s.key):
            lines += ["", "### Notes", ""]
            for para in report.notes[s.key]:
                lines += [para, ""]
    return "\n".join(lines).rstrip() + "\n"


def write_report(which: str, out_dir: str | os.PathLike[str], *, seed: int = 2021,
                 figures: bool = True, ctx: ReproContext | None = None) -> Report:
    """Run ``which`` and write figures, the Markdown report and the JSON rows to ``out_dir``.

    Parameters
    ----------
    which
        ``"all"`` or a paper key.
    out_dir
        Output folder (created); figures go to ``out_dir/figures/<paper>-<name>.png``.
    seed
        Seed of the run.
    figures
        Draw the figures (False: tables only).
    ctx
        A context to reuse.

    Returns
    -------
    Report
        With ``files`` listing what was written.
    """
    context = ctx or ReproContext(seed=seed)
    report = run(which, ctx=context)
    out = Path(out_dir)
    figure_files: dict[tuple[str, str], str] = {}
    if figures:
        for s in sections(which):
            for fig in s.figures:
                rel = f"figures/{s.key}-{fig.name}.png"
                report.files.append(save_figure(fig.draw(context), out / rel))
                figure_files[(s.key, fig.name)] = rel
    stem = "reproduction" if which == "all" else f"reproduction-{which}"
    md = out / f"{stem}.md"
    atomic_write_text(md, render_markdown(report, figure_files))
    js = out / f"{stem}.json"
    atomic_write_text(js, json.dumps({k: v for k, v in report.as_dict().items()
                                      if k != "files"}, indent=1, ensure_ascii=False) + "\n")
    report.files[:0] = [md, js]
    return report
