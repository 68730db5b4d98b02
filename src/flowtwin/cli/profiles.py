"""CLI commands: ``flowtwin profiles list`` and ``flowtwin profiles show NAME``.

A thin layer over :mod:`flowtwin.profiles`: ``list`` prints the built-in library (name,
kind, one-line description); ``show`` prints one profile — a built-in name or a ``.toml``
file — as a table or, with ``--json``, as exactly one JSON object. For a roller ``show``
adds the [000 Eq. 9] check of the tabulated minimal pinch force.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer
from rich.console import Console
from rich.table import Table
from rich.text import Text

if TYPE_CHECKING:
    from pydantic import BaseModel

    from flowtwin.profiles import Roller
    from flowtwin.profiles.toml_io import ProfileKind

__all__ = ["profile_report", "register"]

profiles_app = typer.Typer(
    name="profiles",
    help="Built-in and user profiles (printer, drive, hot end, material, filament, set-up).",
    no_args_is_help=True,
)


def _eq9(roller: Roller) -> dict[str, Any] | None:
    check = roller.fp_min_discrepancy()
    if check is None:
        return {"tabulated_n": None, "eq9_n": roller.fp_min_eq9_n,
                "relative_difference": None, "consistent": None, "note": None}
    return {"tabulated_n": check.tabulated_n, "eq9_n": check.eq9_n,
            "relative_difference": check.relative_difference,
            "consistent": check.consistent, "note": check.note}


def _roller_internal(roller: Roller) -> dict[str, Any]:
    return {"outer_radius_mm": roller.outer_radius_mm, "k_s_n": roller.k_s_n,
            "k_inf_per_n": roller.k_inf_per_n, "a_per_n": roller.a_per_n,
            "b_per_n": roller.b_per_n, "c_s_per_mm": roller.c_s_per_mm,
            "fp_min_eq9_n": roller.fp_min_eq9_n}


def _load(name: str) -> tuple[BaseModel, str]:
    """A profile by built-in name or ``.toml`` path, and where it came from."""
    from flowtwin.profiles import library_entries, load_builtin, load_profile

    if name.endswith(".toml") or Path(name).is_file():
        return load_profile(name), name
    entries = {e.name: e for e in library_entries()}
    profile = load_builtin(name)
    return profile, entries[name].resource


def profile_report(name: str) -> dict[str, Any]:
    """The JSON-able report ``flowtwin profiles show NAME --json`` prints.

    Parameters
    ----------
    name
        Built-in profile name or path to a profile ``.toml`` file.

    Returns
    -------
    dict
        ``name``, ``kind``, ``source`` (data file), ``profile`` (the fields as stored) and,
        depending on the kind, derived values: ``internal`` and ``eq9_check`` for a roller,
        ``eq9_checks`` for the roller table, ``resolved_limits`` for a Klipper printer,
        ``cone_length_mm`` for a hot end, ``parts`` for a set-up (after checking they fit).

    Raises
    ------
    ProfileError
        Unknown name, unreadable or invalid file, set-up whose parts do not fit.
    """
    from flowtwin.profiles import (
        HotendProfile,
        PrinterProfile,
        Roller,
        RollerTable,
        SetupProfile,
        kind_of,
        load_machine,
    )

    profile, source = _load(name)
    kind: ProfileKind = kind_of(profile)
    report: dict[str, Any] = {
        "name": getattr(profile, "name", name),
        "kind": kind,
        "source": source,
        "profile": profile.model_dump(mode="json", exclude_none=True),
    }
    if isinstance(profile, Roller):
        report["internal"] = _roller_internal(profile)
        report["eq9_check"] = _eq9(profile)
    elif isinstance(profile, RollerTable):
        report["eq9_checks"] = {str(r.number): _eq9(r) for r in profile.roller}
    elif isinstance(profile, PrinterProfile):
        if profile.limits is not None:
            report["resolved_limits"] = profile.resolved_klipper_limits().model_dump(
                mode="json")
        report["pa_smooth_time_s"] = profile.pa_smooth_time_s
    elif isinstance(profile, HotendProfile):
        report["cone_length_mm"] = profile.cone_length_mm
    elif isinstance(profile, SetupProfile):
        machine = load_machine(name if source == name else profile)
        report["parts"] = {"printer": machine.printer.name, "drive": machine.drive.name,
                           "roller": machine.roller.name, "hotend": machine.hotend.name,
                           "material": machine.material.name,
                           "filament": machine.filament.name}
    return report


def _flatten(data: Any, prefix: str = "") -> list[tuple[str, str]]:
    rows: list[tuple[str, str]] = []
    if isinstance(data, dict):
        for key, value in data.items():
            rows.extend(_flatten(value, f"{prefix}.{key}" if prefix else str(key)))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            rows.extend(_flatten(value, f"{prefix}[{i}]"))
    else:
        text = f"{data:.6g}" if isinstance(data, float) else str(data)
        rows.append((prefix, text))
    return rows


def _eq9_line(number: object, check: dict[str, Any]) -> str:
    if check["tabulated_n"] is None:
        return f"roller {number}: Eq. 9 gives {check['eq9_n']:.1f} N (nothing tabulated)"
    verdict = "agrees" if check["consistent"] else "DISAGREES"
    return (f"roller {number}: F_p,min tabulated {check['tabulated_n']:g} N, "
            f"Eq. 9 sqrt(k_s/(0.1 k_inf)) = {check['eq9_n']:.1f} N, "
            f"difference {100 * check['relative_difference']:+.1f} % -> {verdict}")


def _print_report(report: dict[str, Any], console: Console) -> None:
    table = Table(title=Text(f"{report['kind']} {report['name']}  ({report['source']})"),
                  show_header=True, header_style="bold")
    table.add_column("key")
    table.add_column("value", overflow="fold")
    skip = "roller[" if report["kind"] == "roller_table" else None
    for key, value in _flatten(report["profile"]):
        if skip and key.startswith(skip):
            continue
        table.add_row(Text(key), Text(value))
    for extra in ("internal", "resolved_limits", "parts"):
        if extra in report:
            for key, value in _flatten(report[extra], extra):
                table.add_row(Text(key), Text(value))
    for extra in ("cone_length_mm", "pa_smooth_time_s"):
        if extra in report:
            table.add_row(Text(extra), Text(f"{report[extra]:.6g}"))
    console.print(table)
    if "eq9_check" in report:
        console.print(_eq9_line(report["profile"].get("number", "?"), report["eq9_check"]),
                      markup=False)
        if report["eq9_check"].get("note"):
            console.print(report["eq9_check"]["note"], markup=False)
    if "eq9_checks" in report:
        rollers = Table(title="[000] rollers: Table 3 F_p,min against Eq. 9",
                        header_style="bold")
        for col in ("#", "D mm", "k_s %·N", "k_inf %/N", "F_p,min tab N",
                    "Eq. 9 N", "diff %", "check"):
            rollers.add_column(col)
        for row in report["profile"]["roller"]:
            check = report["eq9_checks"][str(row["number"])]
            rollers.add_row(str(row["number"]), f"{row['outer_diameter_mm']:g}",
                            f"{row['k_s_pct_N']:g}",
                            f"{row['k_inf_pct_per_N']:g}", f"{check['tabulated_n']:g}",
                            f"{check['eq9_n']:.1f}",
                            f"{100 * check['relative_difference']:+.1f}",
                            "ok" if check["consistent"] else "DISAGREES")
        console.print(rollers)


@profiles_app.command("list")
def list_command(
    json_output: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """List the built-in profiles: name, kind and a one-line description."""
    from flowtwin.profiles import library_entries

    entries = library_entries()
    if json_output:
        typer.echo(json.dumps({"profiles": [
            {"name": e.name, "kind": e.kind, "description": e.description}
            for e in entries]}))
        return
    table = Table(title="flowtwin built-in profiles", header_style="bold")
    table.add_column("name")
    table.add_column("kind")
    table.add_column("description", overflow="fold")
    for e in entries:
        table.add_row(Text(e.name), Text(e.kind), Text(e.description))
    Console().print(table)


@profiles_app.command("show")
def show_command(
    name: str = typer.Argument(..., help="Built-in profile name or path to a .toml file."),
    json_output: bool = typer.Option(False, "--json", help="Print one JSON object."),
) -> None:
    """Show one profile (built-in name or .toml file); for a roller, the Eq. 9 check."""
    report = profile_report(name)
    if json_output:
        typer.echo(json.dumps(report))
        return
    _print_report(report, Console())


def register(app: typer.Typer) -> None:
    """Add the ``profiles`` command group to ``app``."""
    app.add_typer(profiles_app, name="profiles")
