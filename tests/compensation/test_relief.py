"""Pressure relief between runs: where holds start, what the push-back leaves."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flowtwin.compensation import compensate
from flowtwin.compensation.advance import AdvanceOptions, eligible_rows
from flowtwin.compensation.original import read_original
from flowtwin.compensation.relief import (
    relief_amounts,
    relieved_gaps,
    retraction_interims,
    start_gap,
)
from flowtwin.errors import ProfileError
from flowtwin.planner.timeline import PHASE_DTYPE, Timeline
from flowtwin.simulation import simulate


def test_a_hold_starts_at_the_retraction_not_at_the_travel_before_it(tmp_path: Path) -> None:
    """PrusaSlicer moves off its purge line before it retracts: the melt oozes during
    that travel like in any gap, so the hold (and the compression it keeps) starts at the
    first retracting row."""
    path = tmp_path / "travel_first.gcode"
    path.write_text("\n".join([
        "G21", "G90", "M83", "M104 S215", "G1 X10 Y10 F9000",
        "G1 X50 Y10 E1.6 F3600",          # run 1
        "G1 X53 Y10 F9000",               # travel, no retraction yet
        "G1 E-0.8 F2100",                 # retraction
        "G1 X53 Y40 F9000",               # travel
        "G1 E0.8 F2100",                  # push-back
        "G1 X90 Y40 E1.6 F3600",          # run 2
    ]) + "\n")
    res = simulate(path, pressure_advance=False)
    table = res.plan.table
    e = read_original(path, table).row_e
    elig = eligible_rows(table, e)
    kind = np.asarray(table.moves["kind"], dtype=np.uint8)
    found = retraction_interims(elig, kind, e, table.moves["tool"], res.plan.timeline,
                                np.zeros(len(table)))
    assert len(found) == 1
    hold, push = found[0]
    assert e[hold] < 0 and e[hold - 1] == 0  # the retraction, after the travel
    assert elig[hold - 2]                      # ... which follows run 1
    assert e[push] > 0 and elig[push + 1]      # the push-back right before run 2


def _primed(path: Path) -> Path:
    """Cura's start: a prime of 3 mm at 200 mm/min, a retraction held over the travel to
    the skirt, its push-back, then the skirt (0.6 mm moves at 30 mm/s)."""
    lines = ["G21", "G90", "M82", "M104 S215", "G92 E0", "G1 F200 E3", "G92 E0",
             "G1 F1500 E-6.5", "G0 F6000 X100 Y100 Z0.2", "G1 F1500 E0"]
    e = 0.0
    for k in range(1, 40):
        e += 0.02
        lines.append(f"G1 F1800 X{100 + 0.6 * k:.3f} Y100 E{e:.5f}")
    lines += [f"G1 F1500 E{e - 6.5:.5f}", "M104 S0"]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_the_prime_held_over_the_start_is_relieved(tmp_path: Path) -> None:
    """The rows before the first run are a retracting interim: the prime's compression,
    held by the retraction, no longer lands on the skirt's first move (Cura 4.13's wedge:
    +211 % after the advance, +0.8 % with the start relieved)."""
    path = _primed(tmp_path / "primed.gcode")
    res = simulate(path, pressure_advance=False)
    table = res.plan.table
    e = read_original(path, table).row_e
    elig = eligible_rows(table, e)
    first = int(np.flatnonzero(elig)[0])
    assert start_gap(elig) == [(0, first)]
    assert start_gap(np.zeros(4, dtype=bool)) == [] and start_gap(np.ones(4, dtype=bool)) == []
    kind = np.asarray(table.moves["kind"], dtype=np.uint8)
    found = retraction_interims(elig, kind, e, table.moves["tool"], res.plan.timeline,
                                np.zeros(len(table)))
    assert found and e[found[0][0]] < 0 and found[0][1] == first - 1
    report = compensate(path, tmp_path / "out.gcode", advance=True)
    assert report.before.peak_overextrusion_window > 0.5      # the prime's pressure: +1xx %
    assert report.after.peak_overextrusion_window * 5 <= report.before.peak_overextrusion_window
    assert report.advance[0].relief_retractions >= 1
    assert report.commanded_e_after_mm == pytest.approx(report.commanded_e_before_mm,
                                                        rel=1e-9)


def test_pulling_back_keeps_the_column_and_the_volume(thin_gcode: Path, tmp_path: Path) -> None:
    """Pieces that pull back while slowing are written as XY moves with negative E inside
    their printing moves; the file keeps its E, and without the refinement (which keeps the
    column at x >= 0) nothing pulls."""
    report = compensate(thin_gcode, tmp_path / "out.gcode", advance=True)
    assert any(p.pull_pieces > 0 and p.pull_mm > 0 for p in report.advance)
    res = report.compensated_result
    assert res is not None and report.piece_row is not None
    moves = res.plan.table.moves
    pulling = (moves["de"] < 0) & ((moves["kind"] & 8) != 0)
    orig = report.original_result
    assert orig is not None
    printing = orig.plan.table.moves["de"][report.piece_row] > 0
    assert np.any(pulling & printing)
    assert report.commanded_e_after_mm == pytest.approx(report.commanded_e_before_mm,
                                                        rel=1e-9)
    plain = compensate(thin_gcode, tmp_path / "law.gcode",
                       advance=AdvanceOptions(refine=None, relief=False))
    assert all(p.pull_pieces == 0 for p in plain.advance)
    with pytest.raises(ProfileError):
        AdvanceOptions(retract_ratio=-1.0)


@pytest.mark.parametrize(("x", "y", "back"), [(1000.4, 0.0, 2001 + 1 - 1000),
                                              (1000.4, 300.2, 2001 + 1 - 1000 + 300),
                                              (1000.4, 5000.0, 2001 + 1)])
def test_push_back_returns_all_but_the_compression_less_the_precharge(
        x: float, y: float, back: int) -> None:
    """Retract ``⌈2x⌉ + 1`` (twice the compression, so the melt stops at once); push back
    all of it but ``x − y``: the next run starts with the pre-charge ``y``, at most
    ``x`` (the hold would keep no more)."""
    start = np.full(4, np.nan)
    start[2] = x
    out = relief_amounts([(2, 3)], start, np.array([y]), e_unit_mm=1e-5)
    ret = int(np.ceil(2 * x)) + 1
    assert out == [(2, 3, ret, back)]
    assert ret == 2002


def test_no_relief_below_the_threshold_or_without_a_model() -> None:
    start = np.array([np.nan, 10.0, np.nan])
    # 21 units of 1e-5 mm = 0.21 µm < the 2 µm threshold
    assert relief_amounts([(1, 2)], start, e_unit_mm=1e-5) == []
    assert relief_amounts([(1, 2)], start, e_unit_mm=1e-5, keep_zero=True) == [(1, 2, 0, 0)]
    assert relief_amounts([(1, 2)], None, e_unit_mm=1e-5, keep_zero=True) == [(1, 2, 0, 0)]


def test_relieved_gaps_name_the_holds_an_earlier_pass_shortened() -> None:
    """A later pass finds the gaps whose E adds up to less than their original rows:
    hold row, push-back row (−1: none after the retraction), next run's first row and the
    shortfall; a gap that shares an original row with a run, or lost nothing, is not
    one. Rows: runs 0–1, 5–6, 9–10, 13–14, 17; gaps 2–4, 7–8, 11–12, 15–16."""
    elig = np.zeros(18, dtype=bool)
    elig[[0, 1, 5, 6, 9, 10, 13, 14, 17]] = True
    row_e = np.array([5, 5, 0, -4, 3, 5, 5, -2, 0, 5, 5, -3, 3, 5, 5, -1, 1, 5],
                     dtype=np.int64)
    # original row of every row: original 3 was cut in two (rows 3, 4); original 5 is
    # the run's last row 6 and the gap's rows 7, 8
    group = np.array([0, 1, 2, 3, 3, 4, 5, 5, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14],
                     dtype=np.int64)
    orig_e = np.array([5, 5, 0, 1, 5, 5, 5, 5, -3, 3, 5, 5, -1, 1, 5], dtype=np.int64)
    phases = np.zeros(18, dtype=PHASE_DTYPE)
    phases["t_start"] = np.arange(18.0)
    phases["cruise_t"] = 1.0
    timeline = Timeline(phases=phases)
    # gap 2–4: originals 2 and 3 meant 0 + 1, the rows now give 0 − 4 + 3: short by 2,
    # pushed back at row 4 after the retraction at row 3; gap 7–8 shares original 5
    # with run row 6; gaps 11–12 and 15–16 give what their originals meant
    assert relieved_gaps(elig, row_e, group, orig_e, timeline) == [(3, 4, 5, 2)]
    row_e[4] = 0  # no push-back after the retraction: short by 1 + 4
    assert relieved_gaps(elig, row_e, group, orig_e, timeline) == [(3, -1, 5, 5)]
