"""Streaming results: part files, manifest, partial reads, resume."""

from __future__ import annotations

import json
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from flowtwin.batch.jobs import Cell
from flowtwin.batch.store import ResultWriter, parts_dir, read_results
from flowtwin.errors import DataError

CONFIG = {"command": "batch", "engine": "plan", "machine": "abc"}


def _row(i: int, **extra: Cell) -> dict[str, Cell]:
    row: dict[str, Cell] = {"index": i, "row_id": f"id{i:03d}", "file": f"f{i}.gcode",
                              "error": None, "error_kind": None, "total_time_s": 10.0 * i}
    row.update(extra)
    return row


class _Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_rows_are_on_disk_as_they_arrive(tmp_path: Path) -> None:
    out = tmp_path / "r.parquet"
    clock = _Clock()
    w = ResultWriter(out, config=CONFIG, flush_rows=3, flush_s=5.0, clock=clock)
    for i in range(2):
        w.add(_row(i))
    assert read_results(out).num_rows == 0  # two rows wait for the third or for 5 s
    w.add(_row(2))
    assert read_results(out).column("row_id").to_pylist() == ["id000", "id001", "id002"]
    w.add(_row(3))
    clock.t = 5.0
    w.tick()  # waited long enough
    assert read_results(out).num_rows == 4
    assert not out.exists()  # the whole table is written at the end
    table = w.finish(complete=True)
    assert table.num_rows == 4 and not parts_dir(out).exists()
    assert pq.read_table(out).column("total_time_s").to_pylist() == [0.0, 10.0, 20.0, 30.0]
    assert read_results(out).num_rows == 4


def test_rows_sorted_by_index_and_deduplicated(tmp_path: Path) -> None:
    out = tmp_path / "r.parquet"
    w = ResultWriter(out, config=CONFIG, flush_rows=1)
    for i in (3, 1, 2, 0):
        assert w.add(_row(i))
    assert not w.add(_row(2))  # the same row again (a recomputed task) is dropped
    table = w.finish(complete=True)
    assert table.column("index").to_pylist() == [0, 1, 2, 3]


def test_rows_with_different_columns_share_a_part(tmp_path: Path) -> None:
    w = ResultWriter(tmp_path / "r.parquet", config=CONFIG, flush_rows=10)
    w.add({"index": 0, "row_id": "a", "file": "bad.gcode", "error": "bad", "error_kind": "input"})
    w.add(_row(1, printer="prusa"))
    table = w.finish(complete=True)
    assert table.column("printer").to_pylist() == [None, "prusa"]
    assert table.column("total_time_s").to_pylist() == [None, 10.0]


def test_killed_writer_leaves_a_readable_table(tmp_path: Path) -> None:
    """What a SIGKILL can leave: a torn manifest line, an unlisted part, a temp file."""
    out = tmp_path / "r.parquet"
    w = ResultWriter(out, config=CONFIG, flush_rows=2)
    for i in range(5):
        w.add(_row(i))
    # Row 4 waits in memory and is lost with the process; simulate the debris.
    folder = parts_dir(out)
    with open(folder / "manifest.jsonl", "a", encoding="utf-8") as fh:
        fh.write('{"part": "part-000003.parq')  # append cut short
    pq.write_table(pq.read_table(folder / "part-000001.parquet"), folder / "part-000009.parquet")
    (folder / ".part-000003.parquet.x1.tmp").write_bytes(b"PAR1 half")
    table = read_results(out)
    assert table.column("row_id").to_pylist() == [f"id{i:03d}" for i in range(4)]
    # Resume: the four rows are done, the torn line is dropped, numbering continues.
    again = ResultWriter(out, config=CONFIG, resume=True, flush_rows=1)
    assert again.done_ids == {f"id{i:03d}" for i in range(4)}
    again.add(_row(4))
    final = again.finish(complete=True)
    assert final.column("row_id").to_pylist() == [f"id{i:03d}" for i in range(5)]
    assert not folder.exists()


def test_interrupted_finish_keeps_parts_and_writes_partial_table(tmp_path: Path) -> None:
    out = tmp_path / "r.parquet"
    w = ResultWriter(out, config=CONFIG)
    w.add(_row(0))
    w.finish(complete=False)
    assert pq.read_table(out).num_rows == 1  # a plain Parquet file any tool reads
    assert (parts_dir(out) / "manifest.jsonl").is_file()
    resumed = ResultWriter(out, config=CONFIG, resume=True)
    assert resumed.done_ids == {"id000"}


def test_resume_from_a_finished_table_and_retry_of_unfinished_errors(tmp_path: Path) -> None:
    out = tmp_path / "r.parquet"
    w = ResultWriter(out, config=CONFIG)
    w.add(_row(0))
    w.add(_row(1, error="bad.gcode:2: malformed word", error_kind="input", total_time_s=None))
    w.add(_row(2, error="KeyError: 'x' (after 3 attempts)", error_kind="internal",
               total_time_s=None))
    w.finish(complete=True)
    resumed = ResultWriter(out, config=CONFIG, resume=True)
    # Input errors are final; an internal error is computed again.
    assert resumed.done_ids == {"id000", "id001"}
    assert resumed.add(_row(2))
    table = resumed.finish(complete=True)
    rows = {r["row_id"]: r for r in table.to_pylist()}
    assert len(rows) == 3 and rows["id002"]["error"] is None
    assert rows["id002"]["total_time_s"] == 20.0


def test_resume_refuses_another_configuration(tmp_path: Path) -> None:
    out = tmp_path / "r.parquet"
    w = ResultWriter(out, config=CONFIG)
    w.add(_row(0))
    w.finish(complete=False)
    other = dict(CONFIG, machine="def")
    with pytest.raises(DataError, match="different run"):
        ResultWriter(out, config=other, resume=True)
    w2 = ResultWriter(out, config=CONFIG)  # without resume: start afresh
    assert w2.done_ids == frozenset()
    w2.finish(complete=True)
    assert read_results(out).num_rows == 0
    # The finished Parquet table carries its configuration too.
    with pytest.raises(DataError, match="different run"):
        ResultWriter(out, config=other, resume=True)


def test_csv_output(tmp_path: Path) -> None:
    out = tmp_path / "r.csv"
    w = ResultWriter(out, config=CONFIG)
    w.add(_row(0))
    w.add(_row(1, error="boom, with a comma", error_kind="input", total_time_s=None))
    w.finish(complete=True)
    assert out.read_text().splitlines()[0].startswith('"index","row_id"')
    # The parts folder stays: it keeps the types and the configuration for --resume.
    assert (parts_dir(out) / "manifest.jsonl").is_file()
    rows = read_results(out).to_pylist()
    assert rows[0]["error"] is None and rows[1]["error"] == "boom, with a comma"
    assert rows[1]["total_time_s"] is None and rows[0]["total_time_s"] == 0.0
    assert ResultWriter(out, config=CONFIG, resume=True).done_ids == {"id000", "id001"}
    # The CSV alone, read without its parts: the same rows.
    for item in parts_dir(out).iterdir():
        item.unlink()
    parts_dir(out).rmdir()
    alone = read_results(out).to_pylist()
    assert [r["error"] for r in alone] == [None, "boom, with a comma"]
    with pytest.raises(DataError, match="cannot be resumed"):
        ResultWriter(out, config=CONFIG, resume=True)


def test_bad_output_names_and_missing_tables(tmp_path: Path) -> None:
    with pytest.raises(DataError, match="unsupported results format") as info:
        ResultWriter(tmp_path / "r.xlsx", config=CONFIG)
    assert info.value.allowed and ".parquet" in info.value.allowed
    with pytest.raises(DataError, match="no results table"):
        read_results(tmp_path / "none.parquet")
    folder = tmp_path / "x.parquet.parts"
    folder.mkdir()
    (folder / "manifest.jsonl").write_text(json.dumps({"format": "other"}) + "\n")
    with pytest.raises(DataError, match="not a flowtwin results manifest"):
        read_results(tmp_path / "x.parquet")
