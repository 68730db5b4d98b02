"""CSV log of a control run: every measurement, command, printer response and fault.

The file is written through :func:`flowtwin.atomic.atomic_open` and committed when the log
is closed — also when the run ended with an exception, because the log of a crashed run is
complete up to the crash and is exactly what one needs to read afterwards. Rows never
contain secrets: the printer description and the responses carry no API key.
"""

from __future__ import annotations

import contextlib
import csv
import logging
import math
import os
from types import TracebackType
from typing import IO, Any

from flowtwin.atomic import atomic_open

__all__ = ["COLUMNS", "ControlLog"]

log = logging.getLogger("flowtwin.control")

#: Column order of the CSV file.
COLUMNS = ("t_s", "event", "slip", "measurement_age_s", "command_pct", "gcode", "ack",
           "response", "speed_pct", "flow_pct", "detail")


class ControlLog:
    """Append-only CSV log of one run (use as a context manager).

    Parameters
    ----------
    path
        Output CSV file, or None to keep rows only in memory (``rows``).
    keep_rows
        Also keep the rows in memory (tests, summaries).
    """

    def __init__(self, path: str | os.PathLike[str] | None = None, *,
                 keep_rows: bool = True) -> None:
        self.path = path
        self.rows: list[dict[str, str]] = []
        self._keep = keep_rows
        self._cm: contextlib.AbstractContextManager[IO[str]] | None = None
        self._writer: Any = None

    def __enter__(self) -> ControlLog:
        if self.path is not None:
            self._cm = atomic_open(self.path, "w")
            fh = self._cm.__enter__()
            self._writer = csv.DictWriter(fh, fieldnames=COLUMNS, lineterminator="\n")
            self._writer.writeheader()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        cm, self._cm, self._writer = self._cm, None, None
        if cm is not None:
            cm.__exit__(None, None, None)  # commit the rows written so far in every case

    def write(self, t_s: float, event: str, **fields: object) -> None:
        """Append one row; unknown field names are a programming error."""
        unknown = set(fields) - set(COLUMNS)
        if unknown:
            raise KeyError(f"unknown log columns: {sorted(unknown)}")
        row = {"t_s": f"{t_s:.4f}", "event": event}
        for key, value in fields.items():
            row[key] = _fmt(value)
        if self._writer is not None:
            self._writer.writerow(row)
        if self._keep:
            self.rows.append(row)

    def events(self, event: str) -> list[dict[str, str]]:
        """Rows of one event type (from memory)."""
        return [r for r in self.rows if r["event"] == event]


def _fmt(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        return "" if not math.isfinite(value) else f"{value:.6g}"
    return str(value)
