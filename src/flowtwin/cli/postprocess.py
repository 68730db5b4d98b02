"""``flowtwin postprocess``: the one line in a slicer's post-processing scripts.

Thin layer over :func:`flowtwin.postprocess.postprocess`; everything heavy is imported
when the command runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

__all__ = ["EXIT_FAIL_ON", "register"]

#: Exit status when a ``--fail-on`` condition stops the export.
EXIT_FAIL_ON = 1


def _fail_on(values: list[str]) -> frozenset[str]:
    out: set[str] = set()
    for v in values:
        for part in v.split(","):
            part = part.strip().lower()
            if part and part != "none":
                out.add(part)
    return frozenset(out)


def register(app: typer.Typer) -> None:
    """Add ``flowtwin postprocess``."""

    @app.command("postprocess")
    def postprocess_cmd(
        gcode: Annotated[Path, typer.Argument(
            help="The G-code (text, gzip or .bgcode); slicers pass it as the last argument. "
                 "Edited in place.")],
        profile: Annotated[str | None, typer.Option(
            "--profile", "-p", help="Machine set-up (drive, hot end, material): built-in "
                                    "name or set-up TOML.")] = None,
        klipper_config: Annotated[Path | None, typer.Option(
            "--klipper-config", help="Plan with this Klipper printer.cfg.")] = None,
        moonraker: Annotated[str | None, typer.Option(
            "--moonraker", help="Plan with the live configuration of the Klipper printer "
                                "behind this Moonraker URL (http://host:7125).")] = None,
        advance: Annotated[bool, typer.Option(
            "--advance", help="Bake pressure advance into the G-code (turn the "
                              "firmware's off).")] = False,
        slip: Annotated[bool, typer.Option(
            "--slip", help="Feed the predicted drive slip forward.")] = False,
        pace: Annotated[bool, typer.Option(
            "--pace", help="Slow the path where the flow changes faster than the melt "
                           "follows.")] = False,
        pace_budget: Annotated[float, typer.Option(
            "--pace-budget", metavar="PCT",
            help="Pacing: largest share of the print time it may add, percent (inf: no "
                 "cap).")] = 10.0,
        guard: Annotated[bool, typer.Option(
            "--guard", help="Slow moves that would grind the filament.")] = False,
        report: Annotated[bool, typer.Option(
            "--report", help="Also write the HTML report beside the output "
                             "(<output>.report.html).")] = False,
        fail_on: Annotated[list[str] | None, typer.Option(
            "--fail-on", help="Stop the export (exit 1, G-code untouched) when the twin "
                              "predicts: grinding, melt-limit, or none (repeat or "
                              "comma-separate).")] = None,
        stream: Annotated[bool | None, typer.Option(
            "--stream/--no-stream", help="Bounded memory: times and a verdict from "
            "whole-print and per-move figures (no windowed places, no compensation or "
            "report; default: for files over 32 MB).")] = None,
        json_out: Annotated[bool, typer.Option(
            "--json", help="Print the sidecar's JSON object on stdout.")] = False,
    ) -> None:
        """Write firmware-exact times into a sliced G-code and check it with the twin.

        The slicer's post-processing script (PrusaSlicer, SuperSlicer, OrcaSlicer, Bambu
        Studio): the G-code is edited in place, the verdict goes to stderr and
        <output>.flowtwin.json; see docs/postprocess.md.
        """
        from flowtwin.cli.compensate import pace_budget_share
        from flowtwin.postprocess import PostprocessOptions, postprocess
        from flowtwin.postprocess.run import json_clean

        opts = PostprocessOptions(
            setup=profile, klipper_config=klipper_config, moonraker=moonraker,
            advance=advance, slip=slip, pace=pace, pace_budget=pace_budget_share(pace_budget),
            guard=guard, report=report,
            fail_on=_fail_on(fail_on or []), stream=stream)
        result = postprocess(gcode, opts)
        for line in result.stderr_lines():
            typer.echo(line, err=True)
        if json_out:
            import json

            typer.echo(json.dumps(json_clean(result.as_dict()), allow_nan=False))
        if result.failures:
            raise typer.Exit(EXIT_FAIL_ON)
