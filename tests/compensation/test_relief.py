"""Pressure relief between runs: where holds start, what the push-back leaves."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flowtwin.compensation.advance import eligible_rows
from flowtwin.compensation.original import read_original
from flowtwin.compensation.relief import relief_amounts, retraction_interims
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
