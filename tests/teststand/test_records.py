"""Schema-1 test-stand CSV: round trip, and every bad input names file, line, column, value."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flowtwin.errors import DataError
from flowtwin.profiles import load_rollers
from flowtwin.teststand import (
    DriveUnderTest,
    Procedure,
    Record,
    RecordKey,
    SlipLaw,
    read_records_csv,
    simulate_campaign,
    write_records_csv,
)

HEADER = ("roller_id,pinch_force_set_n,nominal_speed_mm_s,repeat,t_s,filament_speed_mm_s,"
          "feed_force_n,pinch_force_n")


def _campaign() -> tuple[Record, ...]:
    drive = DriveUnderTest.from_roller(load_rollers()[5], law=SlipLaw.COMBINED, k_p=0.0063)
    proc = Procedure(pinch_forces_n=(30.0, 90.0), speeds_mm_s=(0.5, 5.0), repeats=2)
    return simulate_campaign(drive, seed=3, procedure=proc)


def test_round_trip(tmp_path: Path) -> None:
    records = _campaign()
    path = tmp_path / "stand.csv"
    rows = write_records_csv(path, records, comment="test\nsecond line")
    assert rows == sum(r.n_samples for r in records)
    back = read_records_csv(path)
    assert [r.key for r in back] == [r.key for r in records]
    for a, b in zip(records, back, strict=True):
        # written with 4 decimals (s, N) and 5 decimals (mm/s): half a unit of the last digit
        np.testing.assert_allclose(b.t_s, a.t_s, atol=5e-5)
        np.testing.assert_allclose(b.feed_force_n, a.feed_force_n, atol=5e-5)
        np.testing.assert_allclose(b.pinch_force_n, a.pinch_force_n, atol=5e-5)
        np.testing.assert_allclose(b.filament_speed_mm_s, a.filament_speed_mm_s, atol=5e-6)
        assert b.source == str(path)
    text = path.read_text()
    assert text.startswith("# flowtwin test-stand records, schema 1")
    assert "# second line\n" in text
    assert back[0].first_line is not None
    assert back[1].first_line == back[0].first_line + back[0].n_samples


def test_columns_in_any_order_comments_and_blank_lines(tmp_path: Path) -> None:
    path = tmp_path / "real.csv"
    path.write_text("# from a real stand\n\n"
                    "t_s,feed_force_n,filament_speed_mm_s,pinch_force_n,repeat,roller_id,"
                    "nominal_speed_mm_s,pinch_force_set_n\r\n"
                    "0.00,0.5,1.00,80.2,0,hobb-goblin,1,80\r\n"
                    "# pause\n"
                    "0.02,0.7,0.99,79.9,0,hobb-goblin,1,80\r\n")
    (rec,) = read_records_csv(path)
    assert rec.key == RecordKey("hobb-goblin", 80.0, 1.0, 0)
    np.testing.assert_array_equal(rec.feed_force_n, [0.5, 0.7])
    assert rec.first_line == 4


def _write(tmp_path: Path, body: str, header: str = HEADER) -> Path:
    path = tmp_path / "bad.csv"
    path.write_text(header + "\n" + body)
    return path


GOOD = "3,80,1,0,0.00,1.0,0.5,80\n3,80,1,0,0.02,1.0,0.6,80\n"


@pytest.mark.parametrize(("body", "line", "field", "what"), [
    ("3,80,1,0,0.00,1.0,abc,80\n", 2, "feed_force_n", "not a number"),
    ("3,80,1,0,0.00,1.0,nan,80\n", 2, "feed_force_n", "not a number"),
    ("3,80,1,0,0.00,1.0,1_0,80\n", 2, "feed_force_n", "not a number"),
    ("3,80,1,0,0.00,1.0,1e9,80\n", 2, "feed_force_n", "out of range"),
    (GOOD + "3,80,-1,0,0.04,1.0,0.6,80\n", 4, "nominal_speed_mm_s", "out of range"),
    ("3,0,1,0,0.00,1.0,0.5,80\n", 2, "pinch_force_set_n", "out of range"),
    ("3,80,1,x,0.00,1.0,0.5,80\n", 2, "repeat", "not a repeat number"),
    ("3,80,1,-1,0.00,1.0,0.5,80\n", 2, "repeat", "not a repeat number"),
    # a control character str.strip would take away (found by the fuzz test below)
    ("3,80,1,0\x1f,0.00,1.0,0.5,80\n", 2, "repeat", "not a repeat number"),
    ("3\x1f,80,1,0,0.00,1.0,0.5,80\n", 2, "roller_id", "invalid roller id"),
    ("ro ller,80,1,0,0.00,1.0,0.5,80\n", 2, "roller_id", "invalid roller id"),
    (GOOD + "3,80,1,0,0.02,1.0,0.6,80\n", 4, "t_s", "time does not increase"),
    (GOOD + "3,80,1,0,0.04,1.0,0.6\n", 4, "-", "wrong number of fields"),
    (GOOD + "3,80,2,0,0.00,1.0,0.6,80\n3,80,1,0,0.06,1.0,0.6,80\n", 5, "repeat",
     "continues after other records"),
])
def test_bad_values_name_line_and_column(tmp_path: Path, body: str, line: int, field: str,
                                         what: str) -> None:
    path = _write(tmp_path, body)
    with pytest.raises(DataError, match=what) as info:
        read_records_csv(path)
    err = info.value
    assert err.source == str(path)
    assert err.line == line
    assert err.field == field
    assert err.allowed  # says what would have been accepted
    assert f"{path}:{line}" in str(err)


@pytest.mark.parametrize(("header", "what", "field"), [
    (HEADER.replace("feed_force_n,", ""), "lacks column", "feed_force_n"),
    (HEADER + ",temperature_c", "unknown column", "temperature_c"),
    (HEADER + ",t_s", "duplicate column", "t_s"),
])
def test_bad_headers(tmp_path: Path, header: str, what: str, field: str) -> None:
    path = _write(tmp_path, GOOD, header=header)
    with pytest.raises(DataError, match=what) as info:
        read_records_csv(path)
    assert info.value.line == 1
    assert info.value.field == field


def test_empty_header_only_non_ascii_and_missing(tmp_path: Path) -> None:
    empty = tmp_path / "empty.csv"
    empty.write_text("# nothing\n\n")
    with pytest.raises(DataError, match="no header"):
        read_records_csv(empty)
    header_only = tmp_path / "header.csv"
    header_only.write_text(HEADER + "\n")
    with pytest.raises(DataError, match="no data rows"):
        read_records_csv(header_only)
    utf = tmp_path / "utf.csv"
    utf.write_bytes((HEADER + "\n3,80,1,0,0.0,1.0,0.5,80\n3,80,1,0,0.02,1.0,0.5,8\u00b0\n")
                    .encode())
    with pytest.raises(DataError, match="ASCII") as info:
        read_records_csv(utf)
    assert info.value.line == 3
    with pytest.raises(DataError, match="cannot read"):
        read_records_csv(tmp_path / "missing.csv")
    quoted = _write(tmp_path, '"3",80,1,0,0.0,1.0,0.5,80\n')
    with pytest.raises(DataError, match="quoted"):
        read_records_csv(quoted)


def test_write_is_atomic(tmp_path: Path) -> None:
    path = tmp_path / "out.csv"
    path.write_text("old\n")

    def broken():
        yield from _campaign()[:1]
        raise RuntimeError("simulated crash while writing")

    with pytest.raises(RuntimeError):
        write_records_csv(path, broken())
    assert path.read_text() == "old\n"  # untouched
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]  # no temporary left


_FIELD = st.one_of(st.text(alphabet="0123456789.-+eEnaifx_ ,#\"", max_size=8),
                   st.floats(allow_nan=True, allow_infinity=True).map(repr),
                   st.integers(-5, 10**10).map(str))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                   HealthCheck.function_scoped_fixture])
@given(rows=st.lists(st.lists(_FIELD, min_size=6, max_size=10), min_size=0, max_size=6),
       header_ok=st.booleans())
def test_fuzz_reader_only_raises_data_error(tmp_path: Path, rows: list[list[str]],
                                            header_ok: bool) -> None:
    header = HEADER if header_ok else HEADER.replace("t_s", "time")
    path = tmp_path / "fuzz.csv"
    path.write_text(header + "\n" + "\n".join(",".join(r) for r in rows) + "\n")
    try:
        records = read_records_csv(path)
    except DataError as exc:
        assert exc.source == str(path)
        return
    for rec in records:  # whatever is accepted obeys the schema
        assert np.all(np.isfinite(rec.feed_force_n))
        assert rec.key.nominal_speed_mm_s > 0 and rec.key.pinch_force_set_n > 0
        assert np.all(np.diff(rec.t_s) > 0)


@settings(max_examples=100, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_fuzz_mutated_valid_file(tmp_path: Path, data: st.DataObject) -> None:
    lines = [HEADER, *GOOD.strip().split("\n"), "3,80,1,0,0.04,0.9,0.7,80.1"]
    i = data.draw(st.integers(0, len(lines) - 1))
    fields = lines[i].split(",")
    j = data.draw(st.integers(0, len(fields) - 1))
    fields[j] = data.draw(st.text(max_size=6))
    lines[i] = ",".join(fields)
    path = tmp_path / "mut.csv"
    path.write_bytes(("\n".join(lines) + "\n").encode("utf-8", "surrogatepass"))
    try:
        read_records_csv(path)
    except DataError as exc:
        assert exc.source == str(path)
