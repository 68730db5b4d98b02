"""CLI command: ``flowtwin reproduce nienhaus2021|tronvoll2019|theory|greeff2017|jin2009|all``.

A thin layer over :mod:`flowtwin.reproduce`: computes every claim of the chosen papers,
prints the table (claim, paper value, flowtwin value, tolerance, pass) or, with ``--json``,
one JSON object with the rows; with ``--out`` also writes the figures, the Markdown report
and the JSON rows (``flowtwin reproduce all --out docs/`` makes ``docs/reproduction.md``).
The exit status is 1 if any row fails.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import typer
from rich.console import Console
from rich.table import Table
from rich.text import Text

if TYPE_CHECKING:
    from flowtwin.reproduce import Report

__all__ = ["PAPER_KEYS", "register"]

EXIT_ROW_FAILED = 1

#: The keys of :data:`flowtwin.reproduce.PAPERS`, for the help text without importing the
#: papers' models (``tests/cli`` checks they agree).
PAPER_KEYS = ("nienhaus2021", "tronvoll2019", "theory", "greeff2017", "jin2009",
              "meltcapacity")


def _cell(value: object) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list):
        return "[" + ", ".join(_cell(v) for v in value) + "]"
    return str(value)


def _print(report: Report, console: Console) -> None:
    table = Table(title=Text(f"flowtwin reproduce {report.which} (seed {report.seed}): "
                             f"{report.passed}/{len(report.rows)} pass; "
                             f"{report.kinds_line()}"),
                  header_style="bold", show_lines=False)
    for col in ("claim", "kind", "paper value", "flowtwin", "tolerance", "pass"):
        table.add_column(col, overflow="fold")
    for r in report.rows:
        table.add_row(Text(f"{r.paper}/{r.claim_id}"), Text(str(r.kind)),
                      Text(_cell(r.paper_value)),
                      Text(_cell(r.flowtwin_value) + (f" {r.unit}" if r.unit else "")),
                      Text(r.tolerance.split(" (")[0]),
                      Text("pass" if r.passed else "FAIL",
                           style="green" if r.passed else "bold red"))
    console.print(table)
    for path in report.files:
        console.print(Text(f"wrote {path}"))


def reproduce_command(
    paper: str = typer.Argument(..., help="Paper: " + ", ".join(PAPER_KEYS) + " or all."),
    out: Path | None = typer.Option(None, "--out",
                                    help="Write figures, Markdown and JSON to this folder."),
    seed: int = typer.Option(2021, "--seed", help="Seed of all random numbers."),
    figures: bool = typer.Option(True, "--figures/--no-figures",
                                 help="Draw the figures (with --out)."),
    json_output: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Reproduce the quantitative claims of a seed paper (or all): table, figures, JSON."""
    from flowtwin.reproduce import run, write_report

    report = (write_report(paper, out, seed=seed, figures=figures) if out is not None
              else run(paper, seed=seed))
    if json_output:
        typer.echo(json.dumps(report.as_dict(), ensure_ascii=False))
    else:
        _print(report, Console())
    if report.failed:
        raise SystemExit(EXIT_ROW_FAILED)


def register(app: typer.Typer) -> None:
    """Add the ``reproduce`` command to ``app``."""
    app.command("reproduce")(reproduce_command)
