"""Results table written as the rows arrive: Parquet part files plus an append-only manifest.

Layout for ``--out results.parquet``::

    results.parquet.parts/
        manifest.jsonl          line 1: header (format, version, run configuration);
                                then one line per finished part: {"part": ..., "rows": n}
        part-000001.parquet     rows in arrival order, each file written atomically
        part-000002.parquet
    results.parquet             the whole table sorted by ``index``: written atomically
                                when the run ends, completely or not (Ctrl-C)

A part is renamed into place (complete) before its manifest line is appended, and the
reader ignores a torn last line and any file the manifest does not list, so a run killed at
any instant leaves a table :func:`read_results` can read: every row in it is complete and
none is duplicated. A finished run removes the parts folder; an interrupted one keeps it for
``--resume``. ``.csv`` outputs are converted from the same Parquet parts at the end and keep
the parts folder (CSV holds neither the column types nor the run configuration).
"""

from __future__ import annotations

import contextlib
import json
import os
import time
from collections.abc import Callable, Mapping
from pathlib import Path

import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from flowtwin.atomic import atomic_open, atomic_write_text
from flowtwin.batch.jobs import Cell
from flowtwin.errors import DataError

__all__ = [
    "FORMAT",
    "RETRY_KINDS",
    "VERSION",
    "ResultWriter",
    "parts_dir",
    "read_results",
]

FORMAT = "flowtwin-results"
VERSION = 1
MANIFEST = "manifest.jsonl"
#: Schema-metadata key of the run configuration in a consolidated Parquet file.
META_KEY = b"flowtwin.results"
#: Error kinds that ``--resume`` computes again (not a property of the input).
RETRY_KINDS = frozenset({"internal", "killed"})
_SUFFIXES = (".parquet", ".csv")


def parts_dir(out: str | os.PathLike[str]) -> Path:
    """The folder of part files and manifest that belongs to the output ``out``."""
    path = Path(out)
    return path.with_name(path.name + ".parts")


def _check_suffix(out: Path) -> None:
    if out.suffix.lower() not in _SUFFIXES:
        raise DataError("unsupported results format", source=str(out), value=out.suffix or "",
                        allowed="a file name ending in .parquet or .csv")


def _read_manifest(folder: Path) -> tuple[dict[str, object], list[tuple[str, int]]]:
    """Header and the (part, rows) entries of a manifest; a torn last line is ignored."""
    path = folder / MANIFEST
    try:
        lines = path.read_text(encoding="utf-8").split("\n")
    except OSError as exc:
        raise DataError(f"cannot read the manifest: {exc.strerror}", source=str(path)) from exc
    complete = lines[:-1]  # the text after the last newline is an unfinished append
    if not complete:
        raise DataError("empty manifest", source=str(path), allowed="a header line")
    try:
        header = json.loads(complete[0])
    except json.JSONDecodeError as exc:
        raise DataError("unreadable manifest header", source=str(path), line=1) from exc
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise DataError("not a flowtwin results manifest", source=str(path), line=1,
                        allowed=f"format = {FORMAT!r}")
    if header.get("version") != VERSION:
        raise DataError("unsupported manifest version", source=str(path), line=1,
                        value=header.get("version"), allowed=str(VERSION))
    entries: list[tuple[str, int]] = []
    for number, line in enumerate(complete[1:], start=2):
        if not line.strip():
            continue
        try:
            entry = json.loads(line)
            entries.append((str(entry["part"]), int(entry["rows"])))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
            raise DataError("corrupt manifest line", source=str(path), line=number,
                            value=line) from exc
    return header, entries


def _combine(tables: list[pa.Table]) -> pa.Table:
    """Concatenate, keep the last row of each ``row_id``, sort by ``index``."""
    tables = [t for t in tables if t.num_rows]
    if not tables:
        return pa.table({"index": pa.array([], pa.int64()), "row_id": pa.array([], pa.string())})
    table = pa.concat_tables(tables, promote_options="permissive")
    ids = table.column("row_id").to_pylist()
    last = {rid: i for i, rid in enumerate(ids)}
    if len(last) != len(ids):
        table = table.take(sorted(last.values()))
    return table.sort_by([("index", "ascending")])


def _read_table(path: Path) -> pa.Table:
    try:
        if path.suffix.lower() == ".csv":
            return pacsv.read_csv(path, convert_options=pacsv.ConvertOptions(
                strings_can_be_null=True))
        return pq.read_table(path)
    except (OSError, pa.ArrowInvalid) as exc:
        raise DataError(f"cannot read the results table: {exc}", source=str(path)) from exc


def _config_of(table: pa.Table) -> dict[str, object] | None:
    meta = table.schema.metadata or {}
    raw = meta.get(META_KEY)
    if raw is None:
        return None
    config = json.loads(raw)
    return config if isinstance(config, dict) else None


def read_results(path: str | os.PathLike[str]) -> pa.Table:
    """Read a results table, finished or not.

    Parameters
    ----------
    path
        The ``--out`` file of a run (``.parquet`` or ``.csv``), or its ``.parts`` folder.

    Returns
    -------
    pyarrow.Table
        Every completed row, one per ``row_id`` (the last written wins), sorted by
        ``index``. While the parts folder exists (a run in progress or interrupted) the
        rows come from the parts the manifest lists; otherwise from the file.

    Raises
    ------
    DataError
        Neither the file nor a manifest exists, or they cannot be read.
    """
    target = Path(path)
    folder = target if (target / MANIFEST).is_file() else parts_dir(target)
    if (folder / MANIFEST).is_file():
        _, entries = _read_manifest(folder)
        return _combine([_read_table(folder / name) for name, _ in entries])
    if target.is_file():
        return _combine([_read_table(target)])
    raise DataError("no results table here", source=str(target),
                    allowed="the --out file of a batch or sweep run, or its .parts folder")


class ResultWriter:
    """Streams result rows to part files; writes the whole table at :meth:`finish`.

    Parameters
    ----------
    out
        The output file (``.parquet`` or ``.csv``).
    config
        Run configuration (JSON-able): kept in the manifest and the Parquet metadata;
        ``resume`` refuses a table made with a different one.
    resume
        Keep the rows of an earlier run of the same configuration (from its parts folder,
        else from ``out``) and report their ids in :attr:`done_ids`. Without it an
        earlier table and its parts are replaced.
    flush_rows
        Write a part once this many rows are waiting.
    flush_s
        Write a part once the oldest waiting row has waited this long, s (checked on
        :meth:`add` and :meth:`tick`).
    clock
        Monotonic clock, s.
    """

    def __init__(self, out: str | os.PathLike[str], *, config: Mapping[str, object],
                 resume: bool = False, flush_rows: int = 256, flush_s: float = 1.0,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.out = Path(out)
        _check_suffix(self.out)
        if flush_rows < 1 or not flush_s >= 0.0:
            raise DataError("invalid flush policy", field="flush_rows/flush_s",
                            value=(flush_rows, flush_s), allowed="flush_rows >= 1, "
                                                                 "flush_s >= 0")
        self.config = json.loads(json.dumps(dict(config), sort_keys=True))
        self.folder = parts_dir(self.out)
        self._flush_rows = flush_rows
        self._flush_s = flush_s
        self._clock = clock
        self._buffer: list[dict[str, Cell]] = []
        self._first_wait: float | None = None
        self._entries: list[tuple[str, int]] = []
        self._written: set[str] = set()
        previous: list[pa.Table] = []
        if resume:
            previous = self._load_previous()
        else:
            self._remove_parts()
        self.folder.mkdir(parents=True, exist_ok=True)
        header = {"format": FORMAT, "version": VERSION, "config": self.config}
        lines = [json.dumps(header, sort_keys=True)]
        lines += [json.dumps({"part": n, "rows": r}) for n, r in self._entries]
        atomic_write_text(self.folder / MANIFEST, "\n".join(lines) + "\n")
        if previous:  # rows of a finished (consolidated) run become the first part
            self._write_part(_combine(previous))
        done = _combine([_read_table(self.folder / n) for n, _ in self._entries])
        kinds = (done.column("error_kind").to_pylist() if "error_kind" in done.column_names
                 else [None] * done.num_rows)
        ids = done.column("row_id").to_pylist() if done.num_rows else []
        #: Rows of the earlier run that are final (errors of RETRY_KINDS are not).
        self.done_ids: frozenset[str] = frozenset(
            rid for rid, kind in zip(ids, kinds, strict=True) if kind not in RETRY_KINDS)
        self._written = set(self.done_ids)

    # -- earlier runs -----------------------------------------------------------------

    def _check_config(self, config: object, where: Path) -> None:
        if config != self.config:
            raise DataError("the table was made by a different run (other profile, engine "
                            "or command); resume needs the same one", source=str(where),
                            value=config, allowed=json.dumps(self.config, sort_keys=True)
                            + " (or drop --resume to start afresh)")

    def _load_previous(self) -> list[pa.Table]:
        if (self.folder / MANIFEST).is_file():
            header, entries = _read_manifest(self.folder)
            self._check_config(header.get("config"), self.folder / MANIFEST)
            self._entries = entries
            return []
        if self.out.is_file():
            table = _read_table(self.out)
            config = _config_of(table)
            if config is None:
                raise DataError("the table does not say which run made it (a CSV file or a "
                                "Parquet file from elsewhere), so it cannot be resumed",
                                source=str(self.out), allowed=f"its {self.folder.name} "
                                "folder beside it, or drop --resume to start afresh")
            self._check_config(config, self.out)
            return [table]
        return []

    def _remove_parts(self) -> None:
        """Delete the manifest, the parts and their temporary files (nothing else)."""
        if not self.folder.is_dir():
            return
        for item in self.folder.iterdir():
            ours = (item.name == MANIFEST or item.name.startswith(("part-", ".part-",
                                                                    f".{MANIFEST}")))
            if item.is_file() and ours:
                item.unlink()
        with contextlib.suppress(OSError):  # left in place if someone else's file is there
            self.folder.rmdir()

    # -- writing ----------------------------------------------------------------------

    def _write_part(self, table: pa.Table) -> None:
        name = f"part-{len(self._entries) + 1:06d}.parquet"
        with atomic_open(self.folder / name, "wb") as fh:
            pq.write_table(table, fh)
        line = json.dumps({"part": name, "rows": table.num_rows}) + "\n"
        with open(self.folder / MANIFEST, "a", encoding="utf-8") as fh:
            fh.write(line)
            fh.flush()
            os.fsync(fh.fileno())
        self._entries.append((name, table.num_rows))

    def add(self, row: Mapping[str, Cell]) -> bool:
        """Queue one row (written within ``flush_rows`` rows or ``flush_s`` seconds).

        Returns
        -------
        bool
            False if a row with the same ``row_id`` was already written (not added).
        """
        rid = row["row_id"]
        if not isinstance(rid, str):
            raise TypeError("a result row needs a string row_id")
        if rid in self._written:
            return False
        self._written.add(rid)
        self._buffer.append(dict(row))
        if self._first_wait is None:
            self._first_wait = self._clock()
        self.tick()
        return True

    def tick(self) -> None:
        """Write the waiting rows if the flush policy says so."""
        if not self._buffer or self._first_wait is None:
            return
        if (len(self._buffer) >= self._flush_rows
                or self._clock() - self._first_wait >= self._flush_s):
            self.flush()

    def flush(self) -> None:
        """Write the waiting rows as a new part now."""
        if not self._buffer:
            return
        # Rows differ in columns (an error row has no results): take the union, in order.
        columns = list(dict.fromkeys(k for row in self._buffer for k in row))
        self._write_part(pa.table({c: [row.get(c) for row in self._buffer] for c in columns}))
        self._buffer = []
        self._first_wait = None

    def table(self) -> pa.Table:
        """Every row written so far (waiting rows are flushed first)."""
        self.flush()
        return _combine([_read_table(self.folder / n) for n, _ in self._entries])

    def finish(self, *, complete: bool) -> pa.Table:
        """Flush, write the whole table to :attr:`out` atomically, and tidy up.

        Parameters
        ----------
        complete
            Every job of the run has its row: the parts folder is removed. Otherwise it is
            kept (for ``--resume``) and :attr:`out` holds the rows done so far.

        Returns
        -------
        pyarrow.Table
            The table written.
        """
        table = self.table()
        meta = dict(table.schema.metadata or {})
        meta[META_KEY] = json.dumps(self.config, sort_keys=True).encode()
        table = table.replace_schema_metadata(meta)
        if self.out.suffix.lower() == ".csv":
            with atomic_open(self.out, "wb") as fh:
                pacsv.write_csv(table, fh)
        else:
            with atomic_open(self.out, "wb") as fh:
                pq.write_table(table, fh)
        if complete and self.out.suffix.lower() != ".csv":
            # A CSV file keeps neither the column types nor the run configuration: its
            # parts folder stays beside it for read_results and --resume.
            self._remove_parts()
        return table

