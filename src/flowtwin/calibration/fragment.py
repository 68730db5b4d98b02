"""Profile fragments: a fitted TOML table with its uncertainties as comments.

A fragment is one TOML table (``[viscosity]``, ``[strand]``) to paste into a profile,
preceded by comments that say where the numbers come from, and with each fitted value's
1σ standard error as a trailing comment (TOML has no place for it in the data itself, and
the profile schemas reject unknown keys). The text is parsed back with :mod:`tomllib`
before it is written, so a fragment on disk is always valid TOML holding exactly the
values given; files are written atomically.
"""

from __future__ import annotations

import math
import os
import tomllib
from collections.abc import Mapping, Sequence

from flowtwin.atomic import atomic_write_text
from flowtwin.errors import CalibrationError

__all__ = ["format_toml_value", "render_fragment", "write_fragment"]


def format_toml_value(value: object) -> str:
    """A TOML literal for a string, bool, int or finite float (7 significant digits)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise CalibrationError("a fitted value is not finite", value=value,
                                   allowed="a finite number")
        text = f"{value:.7g}"
        if not any(c in text for c in ".eEn"):
            text += ".0"
        return text
    if isinstance(value, str):
        escaped = value.replace("\\", "\\\\").replace('"', '\\"')
        return f'"{escaped}"'
    raise TypeError(f"cannot write {type(value).__name__} to a fragment")


def render_fragment(table: str, values: Mapping[str, object], *,
                    stderr: Mapping[str, float] | None = None,
                    header: Sequence[str] = ()) -> str:
    """The TOML text of one table with ``± stderr`` comments.

    Parameters
    ----------
    table
        Table name (``"viscosity"``).
    values
        Key → value, in the order to write.
    stderr
        Key → 1σ standard error, written as ``# ± …`` after the value.
    header
        Comment lines above the table.

    Returns
    -------
    str
        The text; it parses back (``tomllib``) to ``{table: values}`` up to the 7
        significant digits written.
    """
    stderr = stderr or {}
    out = [f"# {line}" if line else "#" for line in header]
    out.append(f"[{table}]")
    width = max((len(k) for k in values), default=0)
    for key, value in values.items():
        text = f"{key.ljust(width)} = {format_toml_value(value)}"
        err = stderr.get(key)
        if err is not None:
            text = f"{text.ljust(width + 20)} # ± {err:.2g} (1σ)"
        out.append(text)
    result = "\n".join(out) + "\n"
    parsed = tomllib.loads(result)   # never write a fragment that does not parse back
    if set(parsed[table]) != set(values):
        raise AssertionError("fragment keys changed on the round trip")  # pragma: no cover
    return result


def write_fragment(path: str | os.PathLike[str], text: str) -> None:
    """Write fragment ``text`` atomically (after checking it parses as TOML)."""
    tomllib.loads(text)
    atomic_write_text(path, text)
