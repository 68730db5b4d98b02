"""Test-stand records and their CSV file format (schema 1, docs/teststand.md).

A *record* is one measurement of [000 §3]: one roller at one set pinch force and one set
nominal feed velocity, one repeat, sampled at a fixed rate while the process force ramps
up, the drive stalls and the force is released. The same CSV format is written by the
virtual stand and can be produced by a real stand, so the analysis cannot tell them apart.

CSV schema 1 — one row per sample, comma-separated, ASCII, no quoting; lines starting with
``#`` are comments; the first other line is the header (columns in any order, every column
required, no others):

===================== ====== ===================================================
column                unit   meaning
===================== ====== ===================================================
roller_id             —      roller label, ``[A-Za-z0-9._+-]``, 1–64 characters
pinch_force_set_n     N      set (nominal) pinch force of the record, > 0
nominal_speed_mm_s    mm/s   set feed velocity ``v_fil,nom = ω·r`` [000 Eq. 1], > 0
repeat                —      repeat number of the parameter set, integer ≥ 0
t_s                   s      time since the start of the record, strictly increasing
filament_speed_mm_s   mm/s   filament velocity measured by the encoder
feed_force_n          N      feed force measured by the drive's load cell
pinch_force_n         N      pinch force measured by the idler's load cell
===================== ====== ===================================================

The four key columns (roller, set pinch force, set speed, repeat) identify a record; the
rows of one record must be contiguous. Every bad value raises
:class:`~flowtwin.errors.DataError` naming the file, the line, the column, the value and
what is allowed.
"""

from __future__ import annotations

import itertools
import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from flowtwin.atomic import atomic_open
from flowtwin.errors import DataError

__all__ = [
    "COLUMNS",
    "SCHEMA_VERSION",
    "ColumnSpec",
    "Record",
    "RecordKey",
    "read_records_csv",
    "write_records_csv",
]

FloatArray = npt.NDArray[np.float64]

SCHEMA_VERSION = 1
_ROLLER_RE = re.compile(r"[A-Za-z0-9._+-]{1,64}")
_NUMBER_RE = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
_INT_RE = re.compile(r"\+?\d{1,9}")


@dataclass(frozen=True)
class ColumnSpec:
    """One column of the CSV schema: name, unit, meaning and allowed range."""

    name: str
    unit: str
    description: str
    low: float
    high: float
    low_open: bool = False

    @property
    def allowed(self) -> str:
        """Human-readable allowed range."""
        lo = ">" if self.low_open else ">="
        return f"a finite number {lo} {self.low:g} and <= {self.high:g} ({self.unit})"

    def ok(self, values: FloatArray) -> npt.NDArray[np.bool_]:
        """Element-wise: finite and inside the range."""
        low_ok = values > self.low if self.low_open else values >= self.low
        return np.isfinite(values) & low_ok & (values <= self.high)


#: The numeric columns of schema 1 (``roller_id`` and ``repeat`` are checked separately).
COLUMNS: tuple[ColumnSpec, ...] = (
    ColumnSpec("pinch_force_set_n", "N", "set pinch force of the record", 0.0, 1000.0,
               low_open=True),
    ColumnSpec("nominal_speed_mm_s", "mm/s", "set feed velocity ω·r", 0.0, 1000.0,
               low_open=True),
    ColumnSpec("t_s", "s", "time since the start of the record", 0.0, 1e7),
    ColumnSpec("filament_speed_mm_s", "mm/s", "filament velocity (encoder)", -1000.0, 1000.0),
    ColumnSpec("feed_force_n", "N", "feed force (drive load cell)", -1e4, 1e4),
    ColumnSpec("pinch_force_n", "N", "pinch force (idler load cell)", -1e4, 1e4),
)
_NUMERIC = {c.name: c for c in COLUMNS}
_ALL_COLUMNS = ("roller_id", "pinch_force_set_n", "nominal_speed_mm_s", "repeat", "t_s",
                "filament_speed_mm_s", "feed_force_n", "pinch_force_n")


@dataclass(frozen=True, order=True)
class RecordKey:
    """What identifies a record: roller, set pinch force (N), set speed (mm/s), repeat."""

    roller_id: str
    pinch_force_set_n: float
    nominal_speed_mm_s: float
    repeat: int

    def describe(self) -> str:
        """Short text such as ``roller 3, 80 N, 1 mm/s, repeat 0``."""
        return (f"roller {self.roller_id}, {self.pinch_force_set_n:g} N, "
                f"{self.nominal_speed_mm_s:g} mm/s, repeat {self.repeat}")


@dataclass(frozen=True)
class Record:
    """One test-stand measurement (module docstring).

    Attributes
    ----------
    key
        Roller, set pinch force, set speed, repeat.
    t_s
        Sample times, s, shape (n,), strictly increasing.
    filament_speed_mm_s
        Encoder velocity, mm/s, shape (n,).
    feed_force_n
        Feed force, N, shape (n,).
    pinch_force_n
        Measured pinch force, N, shape (n,).
    source
        File the record was read from (``None`` if simulated).
    first_line
        Line of its first row in ``source`` (``None`` if simulated).
    """

    key: RecordKey
    t_s: FloatArray
    filament_speed_mm_s: FloatArray
    feed_force_n: FloatArray
    pinch_force_n: FloatArray
    source: str | None = None
    first_line: int | None = None

    def __post_init__(self) -> None:
        n = self.t_s.shape
        for name in ("filament_speed_mm_s", "feed_force_n", "pinch_force_n"):
            if getattr(self, name).shape != n:
                raise DataError(f"record arrays must have equal shapes ({self.key.describe()})",
                                source=self.source, line=self.first_line, field=name,
                                value=(getattr(self, name).shape, n), allowed=f"shape {n}")
        if len(n) != 1 or n[0] < 1:
            raise DataError("a record needs a 1-D series of at least one sample",
                            source=self.source, line=self.first_line, field="t_s",
                            value=n, allowed="shape (n,), n >= 1")

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.t_s.size)

    def where(self) -> str:
        """Location text for messages: ``file:line (roller …)`` or the key alone."""
        if self.source is None:
            return self.key.describe()
        return f"{self.source}:{self.first_line} ({self.key.describe()})"


def _fmt(value: float) -> str:
    """A set point as the shortest text that reads back to the same float."""
    return repr(float(value))


def write_records_csv(path: str | os.PathLike[str], records: Iterable[Record], *,
                      comment: str | None = None) -> int:
    """Write records to a schema-1 CSV file, atomically.

    Parameters
    ----------
    path
        Output file (created or replaced only when complete).
    records
        Records in the order to write them.
    comment
        Extra text for the comment header (one ``#`` line per line of text).

    Returns
    -------
    int
        Number of data rows written.
    """
    rows = 0
    with atomic_open(path, "w") as fh:
        fh.write(f"# flowtwin test-stand records, schema {SCHEMA_VERSION} "
                 "(columns and units: docs/teststand.md)\n")
        if comment:
            for line in comment.splitlines():
                fh.write(f"# {line}\n")
        fh.write(",".join(_ALL_COLUMNS) + "\n")
        for rec in records:
            k = rec.key
            prefix = (f"{k.roller_id},{_fmt(k.pinch_force_set_n)},"
                      f"{_fmt(k.nominal_speed_mm_s)},{k.repeat},")
            lines = [
                f"{prefix}{t:.4f},{v:.5f},{f:.4f},{p:.4f}\n"
                for t, v, f, p in zip(rec.t_s.tolist(), rec.filament_speed_mm_s.tolist(),
                                      rec.feed_force_n.tolist(), rec.pinch_force_n.tolist(),
                                      strict=True)
            ]
            fh.writelines(lines)
            rows += len(lines)
    return rows


def _bad(source: str, line: int, column: str, value: object, message: str,
         allowed: str) -> DataError:
    return DataError(message, source=source, line=line, field=column, value=value,
                     allowed=allowed)


def _parse_header(fields: Sequence[str], source: str, line: int) -> dict[str, int]:
    names = [f.strip() for f in fields]
    index: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in index:
            raise _bad(source, line, name, name, "duplicate column in the header",
                       "each column once")
        if name not in _ALL_COLUMNS:
            raise _bad(source, line, name or "<empty>", name, "unknown column in the header",
                       ", ".join(_ALL_COLUMNS))
        index[name] = i
    missing = [c for c in _ALL_COLUMNS if c not in index]
    if missing:
        raise _bad(source, line, missing[0], ",".join(names),
                   f"header lacks column(s) {', '.join(missing)}", ", ".join(_ALL_COLUMNS))
    return index


def _check_numbers(texts: list[str], lines: list[int], spec: ColumnSpec,
                   source: str) -> FloatArray:
    """Parse a column of number texts strictly; the first bad one raises with its line."""
    try:
        values = np.array(texts, dtype=np.float64)
        fast_ok = not any("_" in t or "n" in t or "N" in t for t in texts)
    except ValueError:
        fast_ok = False
        values = np.empty(0)
    if not fast_ok:
        for text, line in zip(texts, lines, strict=True):
            # blanks around a number are fine; other "whitespace" (control characters such
            # as \x1f, which str.strip would remove) is not a number
            if _NUMBER_RE.fullmatch(text.strip(" \t\r")) is None:
                raise _bad(source, line, spec.name, text, "not a number", spec.allowed)
        values = np.array(texts, dtype=np.float64)
    ok = spec.ok(values)
    if not ok.all():
        i = int(np.argmin(ok))
        raise _bad(source, lines[i], spec.name, texts[i], "value out of range", spec.allowed)
    return values


def read_records_csv(path: str | os.PathLike[str]) -> tuple[Record, ...]:
    """Read a schema-1 test-stand CSV file (module docstring) into records.

    Parameters
    ----------
    path
        The CSV file.

    Returns
    -------
    tuple of Record
        In file order; each knows its file and first line.

    Raises
    ------
    DataError
        Unreadable file, missing or unknown columns, a field that is not a number or out of
        range, a row with the wrong number of fields, a record whose rows are not
        contiguous or whose times do not increase, or no data at all. The message names the
        file, line, column, value and what is allowed.
    """
    source = os.fspath(path)
    try:
        raw = Path(source).read_bytes()
    except OSError as exc:
        raise DataError(f"cannot read the test-stand file: {exc.strerror or exc}",
                        source=source) from exc
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as exc:
        bad_line = raw[:exc.start].count(b"\n") + 1
        raise DataError("the test-stand file must be ASCII text", source=source, line=bad_line,
                        value=raw[exc.start:exc.start + 1], allowed="ASCII characters") from exc

    header: dict[str, int] | None = None
    header_line = 0
    cols: dict[str, list[str]] = {c: [] for c in _ALL_COLUMNS}
    lines: list[int] = []
    for lineno, text_line in enumerate(text.split("\n"), start=1):
        stripped = text_line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        if '"' in stripped:
            raise _bad(source, lineno, "-", stripped[:40], "quoted fields are not supported",
                       "plain comma-separated values")
        fields = stripped.split(",")
        if header is None:
            header = _parse_header(fields, source, lineno)
            header_line = lineno
            continue
        if len(fields) != len(header):
            raise _bad(source, lineno, "-", len(fields),
                       "wrong number of fields in the row", f"{len(header)} fields")
        for name, i in header.items():
            cols[name].append(fields[i])
        lines.append(lineno)
    if header is None:
        raise DataError("no header line found", source=source,
                        allowed="a header line naming the columns " + ", ".join(_ALL_COLUMNS))
    if not lines:
        raise DataError("the file has a header but no data rows", source=source,
                        line=header_line, allowed="one row per sample")

    # blanks only: str.strip would also take control characters such as \x1f away
    roller = [t.strip(" \t\r") for t in cols["roller_id"]]
    for text, line in zip(roller, lines, strict=True):
        if _ROLLER_RE.fullmatch(text) is None:
            raise _bad(source, line, "roller_id", text, "invalid roller id",
                       "1-64 characters of A-Z a-z 0-9 . _ + -")
    repeat: list[int] = []
    for rep_text, line in zip(cols["repeat"], lines, strict=True):
        rep = rep_text.strip(" \t\r")
        if _INT_RE.fullmatch(rep) is None:
            raise _bad(source, line, "repeat", rep_text, "not a repeat number",
                       "an integer 0 <= repeat <= 999999999")
        repeat.append(int(rep))
    values = {name: _check_numbers(cols[name], lines, spec, source)
              for name, spec in _NUMERIC.items()}
    return _split_records(source, lines, roller, repeat, values)


def _split_records(source: str, lines: list[int], roller: list[str], repeat: list[int],
                   values: dict[str, FloatArray]) -> tuple[Record, ...]:
    fp = values["pinch_force_set_n"]
    vn = values["nominal_speed_mm_s"]
    n = len(lines)
    rep = np.asarray(repeat)
    change = np.zeros(n, dtype=bool)
    change[0] = True
    if n > 1:
        change[1:] = ((fp[1:] != fp[:-1]) | (vn[1:] != vn[:-1]) | (rep[1:] != rep[:-1])
                      | np.array([a != b for a, b in zip(roller[1:], roller[:-1], strict=True)]))
    starts = [*np.flatnonzero(change).tolist(), n]
    seen: dict[RecordKey, int] = {}
    out: list[Record] = []
    t = values["t_s"]
    for a, b in itertools.pairwise(starts):
        key = RecordKey(roller[a], float(fp[a]), float(vn[a]), int(rep[a]))
        if key in seen:
            raise _bad(source, lines[a], "repeat", key.describe(),
                       f"record continues after other records (it started at line "
                       f"{seen[key]})", "the rows of one record contiguous")
        seen[key] = lines[a]
        dt = np.diff(t[a:b])
        if dt.size and not np.all(dt > 0.0):
            i = a + 1 + int(np.argmin(dt > 0.0))
            raise _bad(source, lines[i], "t_s", f"{t[i]:g}",
                       f"time does not increase within the record ({key.describe()})",
                       f"t_s > {t[i - 1]:g}")
        out.append(Record(key=key, t_s=t[a:b].copy(),
                          filament_speed_mm_s=values["filament_speed_mm_s"][a:b].copy(),
                          feed_force_n=values["feed_force_n"][a:b].copy(),
                          pinch_force_n=values["pinch_force_n"][a:b].copy(),
                          source=source, first_line=lines[a]))
    return tuple(out)
