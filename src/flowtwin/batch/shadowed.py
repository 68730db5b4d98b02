"""Swept parameters that the G-code sets itself (and so overrides from where it does).

The twin, like the printer, obeys the G-code: ``M104``/``M109`` set the nozzle temperature,
``M900``/``M572``/``SET_PRESSURE_ADVANCE`` the pressure advance, ``M204``/``M201``/
``SET_VELOCITY_LIMIT`` the accelerations. A profile value swept over a file that sets the
same quantity only applies before that command, so the rows can look alike for a reason
that has nothing to do with the physics. :func:`shadowed_parameters` finds such cases so the
sweep can say so.
"""

from __future__ import annotations

import gzip
import os
import re
from collections.abc import Iterable
from pathlib import Path

__all__ = ["SHADOWING", "shadowed_parameters"]

_FLAGS = re.MULTILINE | re.IGNORECASE

#: Path prefix -> (commands in words, pattern of a G-code line that sets the quantity).
SHADOWING: dict[str, tuple[str, re.Pattern[bytes]]] = {
    "setup.temperature_c": (
        "M104/M109 S (nozzle temperature)",
        re.compile(rb"^[ \t]*(?:N\d+[ \t]*)?M10[49](?![0-9])[^;\n]*\bS[ \t]*[0-9.]", _FLAGS)),
    "printer.pressure_advance.": (
        "M900 K / M572 / SET_PRESSURE_ADVANCE (pressure advance)",
        re.compile(rb"^[ \t]*(?:N\d+[ \t]*)?(?:M900(?![0-9])[^;\n]*\bK|M572(?![0-9])|"
                   rb"SET_PRESSURE_ADVANCE\b)", _FLAGS)),
    "printer.limits.max_accel": (
        "SET_VELOCITY_LIMIT ACCEL / M204 (acceleration)",
        re.compile(rb"^[ \t]*(?:N\d+[ \t]*)?(?:SET_VELOCITY_LIMIT\b[^;\n]*\bACCEL|"
                   rb"M204(?![0-9]))", _FLAGS)),
    "printer.marlin.": (
        "M201/M203/M204/M205 (machine limits)",
        re.compile(rb"^[ \t]*(?:N\d+[ \t]*)?M20[1345](?![0-9])", _FLAGS)),
}


def _read(path: Path) -> bytes:
    with open(path, "rb") as fh:
        head = fh.read(2)
    if head == b"\x1f\x8b":
        with gzip.open(path, "rb") as gz:
            return gz.read()
    if head == b"GC":  # Prusa binary G-code: the text it stands for
        from flowtwin.gcode.source import open_source

        stream, _ = open_source(path)
        with stream:
            return stream.read()
    return path.read_bytes()


def shadowed_parameters(source: str | os.PathLike[str], paths: Iterable[str]) -> list[str]:
    """Warnings for the swept ``paths`` that the G-code in ``source`` sets itself.

    Parameters
    ----------
    source
        The G-code file (plain or gzip).
    paths
        Canonical parameter paths of the sweep.

    Returns
    -------
    list of str
        One message per shadowed path, naming the command and its first line.
    """
    wanted = [(p, prefix, what, pattern) for p in paths
              for prefix, (what, pattern) in SHADOWING.items() if p.startswith(prefix)]
    if not wanted:
        return []
    data = _read(Path(source))
    out: list[str] = []
    for path, _, what, pattern in wanted:
        found = pattern.search(data)
        if found is not None:
            line = data.count(b"\n", 0, found.start()) + 1
            out.append(f"{source}:{line}: the G-code sets {path} itself ({what}); the swept "
                       "value applies only before that line, as on the printer")
    return out
