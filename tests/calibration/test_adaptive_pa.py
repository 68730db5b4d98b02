"""Adaptive pressure advance in OrcaSlicer's format: read, write, clamped interpolation."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import CubicHermiteSpline, PchipInterpolator

from flowtwin.calibration.csvdata import read_table, read_table_text
from flowtwin.calibration.tuning.adaptive_pa import (
    ADAPTIVE_PA_COLUMNS,
    FIT_K_MEASUREMENT_HEADER,
    AdaptivePaTable,
    append_measurement,
    hermite_slopes,
    parse_orca_model,
    read_orca_model,
    table_from_measurements,
    write_orca_model,
)
from flowtwin.errors import DataError
from flowtwin.physics.deposition import bead_area_mm2

#: The example of OrcaSlicer's tooltip for "Adaptive pressure advance measurements".
ORCA_EXAMPLE = "0.04,3.96,3000\n0.033,3.96,10000\n0.029,7.91,3000\n0.026,7.91,10000\n"


def test_orca_example_round_trips_and_reproduces_its_points(tmp_path: Path) -> None:
    table = parse_orca_model(ORCA_EXAMPLE)
    assert len(table) == 4
    # sorted by acceleration, then flow
    assert table.to_orca_text() == ("0.04,3.96,3000\n0.029,7.91,3000\n0.033,3.96,10000\n"
                                    "0.026,7.91,10000\n")
    assert table.k_at(table.flow_mm3_s, table.accel_mm_s2) == pytest.approx(table.k_s,
                                                                            abs=1e-15)
    out = tmp_path / "apa.txt"
    write_orca_model(out, table)
    again = read_orca_model(out)
    assert np.array_equal(again.k_s, table.k_s)
    assert np.array_equal(again.flow_mm3_s, table.flow_mm3_s)


def test_escaped_newlines_as_stored_in_a_profile() -> None:
    table = parse_orca_model('"0.04,3.96,3000\\n0.029,7.91,3000"')
    assert table.k_s.tolist() == [0.04, 0.029]


def test_clamped_at_the_edges_of_the_data() -> None:
    table = parse_orca_model(ORCA_EXAMPLE)
    # beyond the flows and accelerations: the edge values, no extrapolation
    assert table.k_at(0.5, 3000) == pytest.approx(0.04)
    assert table.k_at(50.0, 3000) == pytest.approx(0.029)
    assert table.k_at(3.96, 500) == pytest.approx(0.04)
    assert table.k_at(3.96, 50000) == pytest.approx(0.033)
    assert table.k_at(100.0, 1e6) == pytest.approx(0.026)
    # inside: between the neighbours (monotone data stays monotone)
    mid = float(table.k_at(5.0, 6000))
    assert 0.026 < mid < 0.04
    assert float(table.k_at(5.0, 6000, orca_rounding=True)) == round(mid, 3)


def test_plane_is_reproduced_exactly() -> None:
    # data linear in flow and acceleration: secant end slopes and harmonic means of equal
    # secants are the plane's slopes, so the cubic Hermite pieces are the plane itself
    flows = np.array([2.0, 5.0, 9.0, 14.0])
    accs = np.array([1000.0, 2500.0, 4000.0])
    f, a = np.meshgrid(flows, accs)

    def plane(q: np.ndarray, acc: np.ndarray) -> np.ndarray:
        return 0.08 - 0.002 * q - 4e-6 * acc

    table = AdaptivePaTable.from_points(plane(f, a), f, a)
    q = np.linspace(2.0, 14.0, 17)
    acc = np.linspace(1000.0, 4000.0, 17)
    assert table.k_at(q, acc) == pytest.approx(plane(q, acc), abs=1e-14)


def test_matches_scipy_hermite_spline_and_pchip_interior_slopes() -> None:
    x = np.array([1.0, 2.0, 4.0, 7.0, 11.0])
    y = np.array([0.05, 0.04, 0.03, 0.031, 0.02])
    d = hermite_slopes(x, y)
    # interior slopes are scipy's PCHIP (Fritsch–Butland); the ends are secants
    assert d[1:-1] == pytest.approx(PchipInterpolator(x, y).derivative()(x)[1:-1], rel=1e-12)
    assert d[0] == pytest.approx((y[1] - y[0]) / (x[1] - x[0]))
    assert d[-1] == pytest.approx((y[-1] - y[-2]) / (x[-1] - x[-2]))
    table = AdaptivePaTable.from_points(y, x, np.full(x.shape, 3000.0))
    q = np.linspace(1.0, 11.0, 41)
    reference = CubicHermiteSpline(x, y, d)(q)
    assert table.k_at(q, 3000.0) == pytest.approx(reference, abs=1e-15)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.5, 50.0), min_size=2, max_size=6, unique=True),
       st.lists(st.floats(0.0, 0.2), min_size=6, max_size=6))
def test_monotone_data_gives_no_overshoot(flows: list[float], ks: list[float]) -> None:
    x = np.sort(np.array(flows))
    y = np.sort(np.array(ks[: x.size]))[::-1]          # falling with flow, like real K
    table = AdaptivePaTable.from_points(y, x, np.full(x.shape, 2000.0))
    q = np.linspace(0.0, 60.0, 121)
    k = table.k_at(q, 2000.0)
    assert np.all(k <= y.max() + 1e-12) and np.all(k >= y.min() - 1e-12)
    assert np.all(np.diff(k) <= 1e-12)


def test_repeats_are_averaged_and_single_flow_accelerations_flagged() -> None:
    table = AdaptivePaTable.from_points([0.04, 0.05, 0.03, 0.02], [5.0, 5.0, 10.0, 5.0],
                                        [2000, 2000, 2000, 8000])
    assert table.k_s.tolist() == pytest.approx([0.045, 0.03, 0.02])
    # 8000 mm/s² measured at one flow: constant in flow here, ignored by OrcaSlicer
    assert table.k_at([1.0, 50.0], 8000.0) == pytest.approx([0.02, 0.02])
    (note,) = table.orca_warnings()
    assert "8000" in note and "OrcaSlicer ignores it" in note


def test_measurements_csv_with_speed_use_the_bead_area() -> None:
    text = ("k_s,accel_mm_s2,speed_mm_s,line_width_mm,layer_height_mm\n"
            "0.04,3000,50,0.45,0.2\n0.03,3000,200,0.45,0.2\n")
    table = table_from_measurements(read_table_text(text, ADAPTIVE_PA_COLUMNS))
    area = float(bead_area_mm2(0.45, 0.2))           # [001 Eq. 7]
    assert table.flow_mm3_s.tolist() == pytest.approx([50 * area, 200 * area])


@pytest.mark.parametrize(("text", "pattern"), [
    ("k_s,accel_mm_s2\n0.04,3000\n", "either as flow_mm3_s"),
    ("k_s,accel_mm_s2,flow_mm3_s,speed_mm_s\n0.04,3000,5,50\n", "either as flow_mm3_s"),
    ("k_s,accel_mm_s2,flow_mm3_s\n0.04,2500.5,5\n", r"m\.csv:2 \[accel_mm_s2\].*whole "
                                                   r"number"),
    ("k_s,accel_mm_s2,speed_mm_s,line_width_mm,layer_height_mm\n0.04,3000,50,0.1,0.2\n",
     r"m\.csv:2 \[line_width_mm\].*ill-defined"),
])
def test_measurement_errors(text: str, pattern: str) -> None:
    with pytest.raises(DataError, match=pattern):
        table_from_measurements(read_table_text(text, ADAPTIVE_PA_COLUMNS, source="m.csv"))


@pytest.mark.parametrize("text", ["0.04,3.96\n", "K,flow,accel\n0.04,3.96,3000\n",
                                  "0.04,x,3000\n"])
def test_bad_orca_lines_are_located(text: str) -> None:
    with pytest.raises(DataError, match=r"t\.txt:1: an adaptive pressure advance line must "
                                        r"be three numbers"):
        parse_orca_model(text, source="t.txt")


def test_repeats_are_weighted_by_their_errors() -> None:
    table = AdaptivePaTable.from_points([0.04, 0.05, 0.03], [5.0, 5.0, 9.0],
                                        [3000, 3000, 3000], k_err_s=[0.001, 0.002, 0.001])
    # inverse-variance mean of 0.04 ± 0.001 and 0.05 ± 0.002: (0.04·1e6 + 0.05·2.5e5)/1.25e6
    assert table.k_s.tolist() == pytest.approx([0.042, 0.03])
    with pytest.raises(DataError, match=r"\[k_err_s\]"):
        AdaptivePaTable.from_points([0.04], [5.0], [3000], k_err_s=[0.0])
    with pytest.raises(DataError, match="one advance-factor error per measurement"):
        AdaptivePaTable.from_points([0.04, 0.05], [5.0, 6.0], [3000, 3000], k_err_s=[0.001])


def test_fit_k_rows_feed_the_table(tmp_path: Path) -> None:
    path = tmp_path / "measured.csv"
    rows = [(0.045, 0.0004, 4.0, 3000), (0.04, 0.0005, 8.0, 3000), (0.05, 0.0004, 4.0, 6000),
            (0.046, 0.0004, 8.0, 6000)]
    for i, (k, e, q, a) in enumerate(rows, start=1):
        n = append_measurement(path, {"k_s": k, "k_err_s": e, "flow_mm3_s": q,
                                      "accel_mm_s2": a})
        assert n == i
    assert path.read_text().splitlines()[0] == FIT_K_MEASUREMENT_HEADER
    table = table_from_measurements(read_table(path, ADAPTIVE_PA_COLUMNS))
    assert len(table) == 4 and table.orca_warnings() == []
    # two accelerations: the monotone cubic through two points with secant end slopes is
    # the straight line, so half-way in acceleration is the mean
    assert float(table.k_at(6.0, 4500)) == pytest.approx(
        float(table.k_at(6.0, 3000)) / 2 + float(table.k_at(6.0, 6000)) / 2, rel=1e-12)
    other = tmp_path / "other.csv"
    other.write_text("k_s,flow_mm3_s,accel_mm_s2\n0.04,5,3000\n")
    with pytest.raises(DataError, match="other columns"):
        append_measurement(other, {"k_s": 0.04, "k_err_s": 0.001, "flow_mm3_s": 5.0,
                                   "accel_mm_s2": 3000.0})
