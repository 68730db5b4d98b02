"""Reproduce the quantitative results of the seed papers with flowtwin.

The seeds are the specification and the test oracle. Each paper has a module with its
claims (a small function per claim computing flowtwin's value from the library), its
figures and notes; :mod:`~flowtwin.reproduce.report` runs them and writes the report.
``flowtwin reproduce nienhaus2021 | tronvoll2019 | theory | greeff2017 | jin2009 | all``
is the command; ``docs/reproduction.md`` is its output for ``all``.

Quick start::

    from flowtwin.reproduce import run
    report = run("jin2009")
    for row in report.rows:
        print(row.claim_id, row.paper_value, row.flowtwin_value, row.passed)
"""

from flowtwin.reproduce.claims import (
    Claim,
    Outcome,
    Row,
    RowKind,
)
from flowtwin.reproduce.context import Campaign, ReproContext
from flowtwin.reproduce.figures import FigureSpec, PaperSection
from flowtwin.reproduce.report import (
    PAPERS,
    Report,
    all_claims,
    render_markdown,
    run,
    sections,
    write_report,
)

__all__ = [
    "PAPERS",
    "Campaign",
    "Claim",
    "FigureSpec",
    "Outcome",
    "PaperSection",
    "Report",
    "ReproContext",
    "Row",
    "RowKind",
    "all_claims",
    "render_markdown",
    "run",
    "sections",
    "write_report",
]
