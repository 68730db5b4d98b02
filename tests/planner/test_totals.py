"""Plan totals: one pass, the same figures in pieces as in one piece, against a direct
computation per layer."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.gcode.moves import MoveKind
from flowtwin.planner.plan_file import PlanResult, plan_gcode
from flowtwin.planner.totals import PlanTotals


def _direct_per_layer(plan: PlanResult) -> list[dict[str, float | int]]:
    """Per-layer rows computed layer by layer with numpy masks (the reference)."""
    m = plan.table.moves
    times = plan.timeline.move_time_s
    owners = np.clip([d[0] for d in plan.timeline.dwell_s], 0, len(m) - 1)
    rows: list[dict[str, float | int]] = []
    for key in np.unique(m["layer"]).tolist():
        sel = m["layer"] == key
        z = plan.table.layer_z[key] if 0 <= key < len(plan.table.layer_z) else math.nan
        if z != z:
            ext = sel & ((m["kind"] & MoveKind.EXTRUDE) != 0)
            z = float(m["z"][ext][0]) if ext.any() else math.nan
        written = (m["kind"] & MoveKind.FW_RETRACT) == 0
        dwell = sum(d[1] for d, o in zip(plan.timeline.dwell_s, owners, strict=True)
                    if m["layer"][o] == key)
        rows.append({"layer": key, "z_mm": z, "time_s": float(times[sel].sum()) + dwell,
                     "filament_mm": float(m["de"][sel & written].sum()),
                     "moves": int(sel.sum())})
    return rows


@pytest.fixture(scope="module")
def plan(tmp_path_factory: pytest.TempPathFactory) -> PlanResult:
    path = tmp_path_factory.mktemp("totals") / "p.gcode"
    write_print(path, PrintSpec(layers=12))
    text = path.read_text()
    # dwells between layers, so that per-layer times carry them
    path.write_text(text.replace(";LAYER_CHANGE\n", ";LAYER_CHANGE\nG4 P250\n"))
    return plan_gcode(path, printer="generic-marlin")


def test_per_layer_matches_a_direct_computation(plan: PlanResult) -> None:
    assert plan.timeline.dwell_s, "the print has dwells"
    got = plan.per_layer()
    want = _direct_per_layer(plan)
    assert [r["layer"] for r in got] == [r["layer"] for r in want]
    for a, b in zip(got, want, strict=True):
        assert a["moves"] == b["moves"]
        for key in ("z_mm", "time_s", "filament_mm"):
            assert a[key] == pytest.approx(b[key], rel=1e-12, abs=1e-12), key


def test_layer_z_unknown_takes_the_first_extrusion(plan: PlanResult) -> None:
    blind = PlanResult(plan.table, plan.timeline, plan.printer, plan.settings)
    saved = plan.table.layer_z
    try:
        plan.table.layer_z = []
        rows = blind.per_layer()
        want = _direct_per_layer(blind)
    finally:
        plan.table.layer_z = saved
    assert [r["z_mm"] for r in rows] == [r["z_mm"] for r in want]
    assert all(r["z_mm"] == r["z_mm"] for r in rows if r["layer"] >= 0)  # no NaN


@pytest.mark.parametrize("cuts", [[1], [7, 8, 500], [250, 251, 252, 900]])
def test_pieces_sum_as_one_piece_to_the_bit(plan: PlanResult, cuts: list[int]) -> None:
    m, p = plan.table.moves, plan.timeline.phases
    whole = plan.totals()
    pieces = PlanTotals()
    bounds = [0, *[c for c in cuts if c < len(m)], len(m)]
    dwells = plan.timeline.dwell_s
    for a, b in itertools.pairwise(bounds):
        last = b == len(m)
        own = [(d[0] - a, d[1], d[2]) for d in dwells if a <= d[0] < b or (last and d[0] >= b)]
        pieces.add(m[a:b], p[a:b], own)
    assert pieces.per_layer(plan.table.layer_z) == whole.per_layer(plan.table.layer_z)
    assert pieces.filament_by_tool() == whole.filament_by_tool()
    assert pieces.time_by_feature(plan.table.features) == whole.time_by_feature(
        plan.table.features)
    assert (pieces.moves, pieces.extruding_written, pieces.layers) == (
        whole.moves, whole.extruding_written, whole.layers)


def test_empty_plan(tmp_path: Path) -> None:
    path = tmp_path / "empty.gcode"
    path.write_text("G4 P100\n")
    plan = plan_gcode(path)
    assert plan.per_layer() == []
    s = plan.summary()
    assert s.moves == 0 and s.layers == 0 and s.net_filament_mm == {}
