"""Helpers shared by the CLI modules: JSON output and rich tables."""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence

from rich.console import Console
from rich.table import Table

__all__ = ["console", "err_console", "fmt_duration", "print_json", "table_from_rows"]

console = Console(highlight=False)
err_console = Console(stderr=True, highlight=False)


def _clean(value: object) -> object:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Mapping):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    return value


def print_json(obj: Mapping[str, object]) -> None:
    """Print exactly one JSON object on stdout (NaN/inf become null)."""
    print(json.dumps(_clean(obj), allow_nan=False))


def fmt_duration(seconds: float | None) -> str:
    """``1h 02m 03.4s`` style duration."""
    if seconds is None or not math.isfinite(seconds):
        return "-"
    h, rem = divmod(seconds, 3600.0)
    m, s = divmod(rem, 60.0)
    if h >= 1:
        return f"{int(h)}h {int(m):02d}m {s:04.1f}s"
    if m >= 1:
        return f"{int(m)}m {s:04.1f}s"
    return f"{s:.2f}s"


def table_from_rows(title: str, columns: Sequence[str],
                    rows: Iterable[Sequence[object]]) -> Table:
    """A rich table with right-aligned columns (no header row when all names are empty)."""
    table = Table(title=title, title_justify="left", show_header=any(columns))
    for i, col in enumerate(columns):
        table.add_column(col, justify="left" if i == 0 else "right")
    for row in rows:
        table.add_row(*[str(v) for v in row])
    return table
