"""Measurement CSV reader: located errors, and a hypothesis fuzz."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flowtwin.calibration.csvdata import Column, read_table, read_table_text
from flowtwin.errors import DataError

COLS = (
    Column("temp_c", "temperature", lower=-273.15, lower_open=True, upper=600.0),
    Column("force_n", "force", lower=0.0, lower_open=True),
    Column("note_free", "optional", required=False),
)


def test_reads_comments_blank_lines_bom_and_spaces() -> None:
    text = "\ufeff# a sweep\n\ntemp_c, force_n\n190, 5.5\n# repeat\n 200 ,4.25\n"
    table = read_table_text(text, COLS, source="s.csv")
    assert len(table) == 2
    assert table.get("temp_c").tolist() == [190.0, 200.0]
    assert table.get("force_n").tolist() == [5.5, 4.25]
    assert table.lines.tolist() == [4, 6]
    assert not table.has("note_free")


@pytest.mark.parametrize(("text", "pattern"), [
    ("temp_c,force_n\n190,abc\n", r"s\.csv:2 \[force_n\]: bad value in column force_n "
                                  r"\(force\); got 'abc'; allowed: a finite number, 0 < force_n"),
    ("temp_c,force_n\n190,-1\n", r"s\.csv:2 \[force_n\].*got '-1'"),
    ("temp_c,force_n\n190,0\n", r"s\.csv:2 \[force_n\].*got '0'"),
    ("temp_c,force_n\n190,nan\n", r"s\.csv:2 \[force_n\].*got 'nan'"),
    ("temp_c,force_n\n700,1\n", r"s\.csv:2 \[temp_c\].*temp_c <= 600"),
    ("temp_c,force_n\n190\n", r"s\.csv:2: row has 1 cells but the header \(line 1\) names 2"),
    ("temp_C,force_n\n190,1\n", r"s\.csv:1 \[temp_C\]: unknown column.*allowed: columns: "
                                r"temp_c, force_n, note_free"),
    ("temp_c,temp_c,force_n\n", r"s\.csv:1 \[temp_c\]: column named twice"),
    ("force_n\n1\n", r"s\.csv:1 \[temp_c\]: required column missing"),
    ("# only comments\n", r"s\.csv: no header line"),
    ("temp_c,force_n\n", r"s\.csv: only 0 data row"),
    ("temp_c,force_n\n1,\x002\n", r"s\.csv:2: binary data"),
])
def test_errors_name_file_line_column_value(text: str, pattern: str) -> None:
    with pytest.raises(DataError, match=pattern):
        read_table_text(text, COLS, source="s.csv")


def test_read_table_file_errors(tmp_path: Path) -> None:
    missing = tmp_path / "nope.csv"
    with pytest.raises(DataError, match=r"nope\.csv: cannot read the file"):
        read_table(missing, COLS)
    latin = tmp_path / "latin.csv"
    latin.write_bytes(b"temp_c,force_n\n190,1\n# caf\xe9\n")
    with pytest.raises(DataError, match=r"latin\.csv:3: the file is not UTF-8"):
        read_table(latin, COLS)
    good = tmp_path / "good.csv"
    good.write_text("temp_c,force_n\n190,1\n200,2\n")
    assert read_table(good, COLS, min_rows=2).get("force_n").tolist() == [1.0, 2.0]
    with pytest.raises(DataError, match=r"only 2 data row.*>= 3 rows"):
        read_table(good, COLS, min_rows=3)


# ------------------------------------------------------------------------- fuzzing ---

@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(alphabet=st.sampled_from(list("temp_cforn,0123456789.-+e# \n\r\t\"x")),
               max_size=120))
def test_fuzz_any_text_gives_a_table_or_a_data_error(text: str) -> None:
    try:
        table = read_table_text(text, COLS, source="fuzz.csv")
    except DataError as exc:
        assert str(exc).startswith("fuzz.csv")        # always located in the file
        return
    # a table: every value finite, in range, of a known column
    for name, values in table.columns.items():
        col = {c.name: c for c in COLS}[name]
        assert all(col.accepts(float(v)) for v in values)
    assert {"temp_c", "force_n"} <= set(table.columns)


_finite_temps = st.floats(min_value=-200.0, max_value=600.0, allow_nan=False)
_forces = st.floats(min_value=1e-6, max_value=1e6, allow_nan=False)


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(_finite_temps, _forces), min_size=1, max_size=20))
def test_fuzz_valid_tables_round_trip_exactly(rows: list[tuple[float, float]]) -> None:
    text = "temp_c,force_n\n" + "".join(f"{t!r},{f!r}\n" for t, f in rows)
    table = read_table_text(text, COLS)
    assert table.get("temp_c").tolist() == [t for t, _ in rows]
    assert table.get("force_n").tolist() == [f for _, f in rows]


@settings(max_examples=100, deadline=None)
@given(st.lists(st.tuples(_finite_temps, _forces), min_size=1, max_size=20),
       st.data(), st.sampled_from(["x", "", "inf", "1e999", "-5", "1,2"]))
def test_fuzz_one_bad_cell_is_named(rows: list[tuple[float, float]], data: st.DataObject,
                                    bad: str) -> None:
    i = data.draw(st.integers(0, len(rows) - 1))
    j = data.draw(st.integers(0, 1))
    if bad == "-5" and j == 0:
        bad = "-300"                                  # below absolute zero
    cells = [[repr(t), repr(f)] for t, f in rows]
    cells[i][j] = bad
    text = "temp_c,force_n\n" + "".join(",".join(r) + "\n" for r in cells)
    with pytest.raises(DataError) as err:
        read_table_text(text, COLS, source="f.csv")
    assert err.value.line == i + 2                    # header is line 1
    if bad != "1,2":                                  # an extra cell: the row's length
        assert err.value.field == ("temp_c", "force_n")[j]
        assert err.value.value == bad


def test_missing_optional_column_is_named() -> None:
    table = read_table_text("temp_c,force_n\n1,2\n", COLS)
    assert isinstance(table.get("temp_c"), np.ndarray)
    with pytest.raises(DataError, match=r"\[note_free\]: the file has no such column"):
        table.get("note_free")
