"""Strict reading of measurement tables (CSV) for the fits.

A measurement file is comma-separated text (UTF-8, optional BOM): lines starting with
``#`` and blank lines are ignored, the first other line names the columns, every further
line is one measurement. Column names carry their unit (``temp_c``, ``feed_force_n``,
``flow_mm3_s``) and are matched exactly; a column the fit does not know is an error (a
typo such as ``temp_C`` must not be ignored), so is a missing required column, a row with
the wrong number of cells, and a cell that is not a finite number inside the column's
bounds. Every :class:`~flowtwin.errors.DataError` names the file, the line, the column
and the value, and says what is allowed.
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.errors import DataError

__all__ = ["Column", "Table", "read_table", "read_table_text"]

#: Largest file read (a fit needs thousands of rows, not gigabytes).
MAX_BYTES = 64 * 1024 * 1024


@dataclass(frozen=True, slots=True)
class Column:
    """One column a fit understands.

    Attributes
    ----------
    name
        Exact header name, unit included (``temp_c``).
    description
        What to measure, for messages and ``--help``.
    required
        The file must have this column.
    lower, upper
        Allowed range of the values (inclusive unless ``lower_open``).
    lower_open
        ``lower`` itself is not allowed (``> 0`` rather than ``>= 0``).
    """

    name: str
    description: str
    required: bool = True
    lower: float = -math.inf
    upper: float = math.inf
    lower_open: bool = False

    def allowed(self) -> str:
        """Human text of the allowed values."""
        lo = "" if self.lower == -math.inf else (
            f"{self.lower:g} < " if self.lower_open else f"{self.lower:g} <= ")
        hi = "" if self.upper == math.inf else f" <= {self.upper:g}"
        return f"a finite number, {lo}{self.name}{hi}" if lo or hi else "a finite number"

    def accepts(self, value: float) -> bool:
        """True if ``value`` is finite and inside the bounds."""
        if not math.isfinite(value) or value > self.upper:
            return False
        return value > self.lower if self.lower_open else value >= self.lower


@dataclass(frozen=True)
class Table:
    """Columns read from a measurement file.

    Attributes
    ----------
    source
        File name (or ``"<text>"``).
    columns
        Column name → values, shape ``(n_rows,)`` each; only the columns the file has.
    lines
        Source line of each row, shape ``(n_rows,)``.
    """

    source: str
    columns: dict[str, npt.NDArray[np.float64]]
    lines: npt.NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.lines.shape[0])

    def has(self, name: str) -> bool:
        """True if the file has column ``name``."""
        return name in self.columns

    def get(self, name: str) -> npt.NDArray[np.float64]:
        """The values of column ``name``.

        Raises
        ------
        DataError
            The file has no such column.
        """
        if name not in self.columns:
            raise DataError("the file has no such column", source=self.source, field=name,
                            allowed="columns: " + ", ".join(self.columns))
        return self.columns[name]


def read_table(path: str | os.PathLike[str], columns: Sequence[Column], *,
               min_rows: int = 1) -> Table:
    """Read a measurement CSV file.

    Parameters
    ----------
    path
        The file.
    columns
        The columns the caller understands (any others are an error).
    min_rows
        Fewest data rows accepted.

    Returns
    -------
    Table

    Raises
    ------
    DataError
        Unreadable file, not UTF-8, or any problem :func:`read_table_text` reports.
    """
    name = os.fspath(path)
    try:
        with open(name, "rb") as fh:
            raw = fh.read(MAX_BYTES + 1)
    except OSError as exc:
        raise DataError(f"cannot read the file: {exc.strerror}", source=name) from exc
    if len(raw) > MAX_BYTES:
        raise DataError("file too large for a measurement table", source=name,
                        allowed=f"at most {MAX_BYTES // (1024 * 1024)} MiB")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise DataError("the file is not UTF-8 text", source=name, line=line,
                        allowed="a UTF-8 (or ASCII) CSV file") from exc
    return read_table_text(text, columns, source=name, min_rows=min_rows)


def read_table_text(text: str, columns: Sequence[Column], *, source: str = "<text>",
                    min_rows: int = 1) -> Table:
    """Parse measurement CSV ``text`` (see the module docstring for the format).

    Parameters
    ----------
    text
        The file's content.
    columns
        The columns the caller understands.
    source
        Name used in error messages.
    min_rows
        Fewest data rows accepted.

    Returns
    -------
    Table

    Raises
    ------
    DataError
        No header, an unknown, duplicate or missing column, a row with the wrong number of
        cells, a cell that is not a finite number in range, or fewer than ``min_rows``
        rows. The message names the line and column.
    """
    known: Mapping[str, Column] = {c.name: c for c in columns}
    if "\x00" in text:
        line = text[: text.index("\x00")].count("\n") + 1
        raise DataError("binary data (NUL byte) in a CSV file", source=source, line=line,
                        allowed="comma-separated text")
    text = text.lstrip("\ufeff")
    header: list[str] | None = None
    header_line = 0
    values: list[list[float]] = []
    rows_lines: list[int] = []
    lines = text.splitlines()
    for lineno, raw_line in enumerate(lines, start=1):
        stripped = raw_line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        try:
            cells = next(csv.reader(io.StringIO(stripped), skipinitialspace=True))
        except csv.Error as exc:
            raise DataError(f"malformed CSV line: {exc}", source=source, line=lineno,
                            value=stripped, allowed="comma-separated cells") from exc
        cells = [c.strip() for c in cells]
        if header is None:
            header, header_line = _check_header(cells, known, source, lineno), lineno
            continue
        if len(cells) != len(header):
            raise DataError(f"row has {len(cells)} cells but the header (line {header_line}) "
                            f"names {len(header)} columns", source=source, line=lineno,
                            value=stripped, allowed=f"{len(header)} comma-separated numbers")
        row: list[float] = []
        for name, cell in zip(header, cells, strict=True):
            col = known[name]
            number = _number(cell)
            if number is None or not col.accepts(number):
                raise DataError(f"bad value in column {name} ({col.description})",
                                source=source, line=lineno, field=name, value=cell,
                                allowed=col.allowed())
            row.append(number)
        values.append(row)
        rows_lines.append(lineno)
    if header is None:
        raise DataError("no header line with column names", source=source,
                        allowed="a first line naming the columns: "
                                + ", ".join(c.name for c in columns))
    if len(values) < min_rows:
        raise DataError(f"only {len(values)} data row(s)", source=source,
                        value=len(values), allowed=f">= {min_rows} rows")
    data = np.asarray(values, dtype=np.float64).reshape(len(values), len(header))
    return Table(source, {name: data[:, j].copy() for j, name in enumerate(header)},
                 np.asarray(rows_lines, dtype=np.int64))


def _check_header(cells: list[str], known: Mapping[str, Column], source: str,
                  lineno: int) -> list[str]:
    allowed = ", ".join(known)
    seen: set[str] = set()
    for name in cells:
        if name not in known:
            raise DataError("unknown column", source=source, line=lineno, field=name or "''",
                            value=name, allowed=f"columns: {allowed}")
        if name in seen:
            raise DataError("column named twice", source=source, line=lineno, field=name,
                            value=name, allowed="each column once")
        seen.add(name)
    missing = [c.name for c in known.values() if c.required and c.name not in seen]
    if missing:
        raise DataError("required column missing", source=source, line=lineno,
                        field=missing[0], value=",".join(cells),
                        allowed="the header must name " + ", ".join(
                            c.name for c in known.values() if c.required))
    return cells


def _number(cell: str) -> float | None:
    if not cell or cell.lower().lstrip("+-") in ("nan", "inf", "infinity"):
        return None
    try:
        value = float(cell)
    except ValueError:
        return None
    return value if math.isfinite(value) else None
