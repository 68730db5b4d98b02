"""Swept parameters that the G-code sets itself (and so overrides from where it does).

The twin, like the printer, obeys the G-code: ``M104``/``M109`` set the nozzle temperature,
``M900``/``M572``/``SET_PRESSURE_ADVANCE`` the pressure advance, ``M204``/``M201``/
``SET_VELOCITY_LIMIT`` the accelerations. A profile value swept over a file that sets the
same quantity only applies before that command, so the rows can look alike for a reason
that has nothing to do with the physics. :func:`shadowed_parameters` finds such cases so the
sweep can say so. The file is read by flowtwin's reader (its events), so a command counts
exactly when the twin would obey it (comments, line numbers and checksums as the reader
treats them).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable

from flowtwin.gcode.moves import Event
from flowtwin.gcode.reader import iter_move_chunks

__all__ = ["SHADOWING", "shadowed_parameters"]


def _has_number(ev: Event, key: str) -> bool:
    return isinstance(ev.params.get(key), float)


#: Path prefix -> (commands in words, whether an event of the file sets the quantity).
SHADOWING: dict[str, tuple[str, Callable[[Event], bool]]] = {
    "setup.temperature_c": (
        "M104/M109 S (nozzle temperature)",
        lambda ev: ev.code in ("M104", "M109") and _has_number(ev, "S")),
    "printer.pressure_advance.": (
        "M900 K / M572 / SET_PRESSURE_ADVANCE (pressure advance)",
        lambda ev: (ev.code == "M900" and "K" in ev.params)
        or ev.code in ("M572", "SET_PRESSURE_ADVANCE")),
    "printer.limits.max_accel": (
        "SET_VELOCITY_LIMIT ACCEL / M204 (acceleration)",
        lambda ev: (ev.code == "SET_VELOCITY_LIMIT" and "ACCEL" in ev.params)
        or ev.code == "M204"),
    "printer.marlin.": (
        "M201/M203/M204/M205 (machine limits)",
        lambda ev: ev.code in ("M201", "M203", "M204", "M205")),
}


def shadowed_parameters(source: str | os.PathLike[str], paths: Iterable[str]) -> list[str]:
    """Warnings for the swept ``paths`` that the G-code in ``source`` sets itself.

    Parameters
    ----------
    source
        The G-code file (plain, gzip or Prusa binary .bgcode).
    paths
        Canonical parameter paths of the sweep.

    Returns
    -------
    list of str
        One message per shadowed path, naming the command and its first line.

    Raises
    ------
    GcodeError
        The file cannot be read (as the sweep's simulations would report).
    """
    wanted = [(p, what, sets) for p in paths
              for prefix, (what, sets) in SHADOWING.items() if p.startswith(prefix)]
    if not wanted:
        return []
    first: dict[str, int] = {}
    for table in iter_move_chunks(source):
        for ev in table.events:
            for path, _, sets in wanted:
                if path not in first and sets(ev):
                    first[path] = ev.line
        if len(first) == len(wanted):
            break
    return [f"{source}:{first[path]}: the G-code sets {path} itself ({what}); the swept "
            "value applies only before that line, as on the printer"
            for path, what, _ in wanted if path in first]
