"""Flow patterns: multiplier blocks, max-volumetric-speed ramp, flow line."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from flowtwin.calibration.patterns.flow_rate import (
    FlowBlockParams,
    FlowLineParams,
    MaxFlowParams,
    flow_block_pattern,
    flowline_pattern,
    maxflow_pattern,
)
from flowtwin.calibration.patterns.pattern import PrintSettings
from flowtwin.calibration.patterns.verify import verify_pattern
from flowtwin.errors import CalibrationError
from flowtwin.firmware import Firmware


def _lengths(table: Any) -> np.ndarray:
    m = table.moves
    x0 = np.concatenate(([0.0], m["x"][:-1]))
    y0 = np.concatenate(([0.0], m["y"][:-1]))
    return np.hypot(m["x"] - x0, m["y"] - y0)


def test_blocks_scale_every_e_by_their_multiplier(gc: Any, firmware: Firmware) -> None:
    s = PrintSettings(firmware=firmware)
    params = FlowBlockParams(multiplier_start=0.9, multiplier_end=1.1, multiplier_step=0.1,
                             layers=2)
    pattern = flow_block_pattern(s, params)
    table = gc.read_pattern(pattern)
    assert table.unknown_commands == {}
    assert table.net_filament_mm()[0] == pytest.approx(pattern.filament_mm,
                                                       abs=gc.e_tolerance(pattern))
    m = table.moves
    ext = gc.extruding(table)
    length = _lengths(table)
    e_per_mm = s.bead_area_mm2() / s.filament_area_mm2    # [001 Eq. 7] / A_fil
    for b, mult in enumerate((0.9, 1.0, 1.1)):
        sel = ext & (m["feature"] == table.features.index(f"Block {b}"))
        ratio = m["de"][sel] / length[sel]
        # E to 1e-5 mm over >= 9 mm paths (and 3-decimal XY): 2e-4 relative at most
        assert ratio == pytest.approx(np.full(ratio.shape, mult * e_per_mm), rel=2e-4)
        # total: the multiplier times the block's path length (each E word rounded to
        # 5 decimals: at most 5e-6 mm per move)
        assert float(np.sum(m["de"][sel])) == pytest.approx(
            mult * e_per_mm * float(np.sum(length[sel])), abs=5e-6 * np.count_nonzero(sel))


def test_blocks_fit_the_row_layout() -> None:
    pattern = flow_block_pattern(PrintSettings(), FlowBlockParams(
        multiplier_start=0.8, multiplier_end=1.2, multiplier_step=0.05, columns=5))
    assert len(pattern.values) == 9
    x0, y0, x1, y1 = pattern.bounds_xy_mm
    assert x1 - x0 == pytest.approx(5 * 25.0 - 5.0, abs=0.5)   # 5 columns of 20 + gaps
    assert y1 - y0 >= 2 * 25.0 - 5.0                              # two rows (and prime)


@pytest.mark.parametrize("printer", ["generic-klipper", "generic-marlin"])
def test_maxflow_reaches_its_volumetric_targets(printer: str) -> None:
    fw = Firmware.KLIPPER if printer == "generic-klipper" else Firmware.MARLIN
    s = PrintSettings(firmware=fw)
    pattern = maxflow_pattern(s, MaxFlowParams(flow_start_mm3_s=2.0, flow_end_mm3_s=20.0,
                                               flow_step_mm3_s=3.0))
    check = verify_pattern(pattern, printer=printer)
    assert check.ok
    targets = [c.segment.flow_mm3_s for c in check.segments]
    assert targets == pytest.approx([2.0, 5.0, 8.0, 11.0, 14.0, 17.0, 20.0], rel=1e-5)
    for c, q in zip(check.segments, targets, strict=True):
        # flow from the planner's cruise speed and the reader's E per mm; E to 1e-5 mm
        # over 80 mm lines (~2.9 mm of filament): 1e-5 relative
        assert c.flow_mm3_s == pytest.approx(q, rel=1e-4)


def test_maxflow_beyond_the_printer_is_reported() -> None:
    # prusa-i3-mk25 caps X/Y at 200 mm/s: flows above 200·A cannot be reached
    s = PrintSettings(firmware=Firmware.MARLIN)
    pattern = maxflow_pattern(s, MaxFlowParams(flow_start_mm3_s=14.0, flow_end_mm3_s=22.0,
                                               flow_step_mm3_s=2.0))
    check = verify_pattern(pattern, printer="prusa-i3-mk25")
    limit = 200.0 * s.bead_area_mm2()
    flows = (14.0, 16.0, 18.0, 20.0, 22.0)
    assert sorted(c.segment.group for c in check.shortfalls) == [
        i for i, q in enumerate(flows) if q > limit] == [2, 3, 4]
    assert all(c.cruise_v_mm_s == pytest.approx(200.0, rel=1e-6) for c in check.shortfalls)


def test_maxflow_rejects_absurd_speed() -> None:
    with pytest.raises(CalibrationError, match=r"\[flow_end_mm3_s\]"):
        maxflow_pattern(PrintSettings(), MaxFlowParams(flow_start_mm3_s=100.0,
                                                       flow_end_mm3_s=400.0,
                                                       flow_step_mm3_s=100.0))


def test_flowline_alternates_quarter_and_full_flow(gc: Any, firmware: Firmware) -> None:
    s = PrintSettings(firmware=firmware)
    pattern = flowline_pattern(s, FlowLineParams(flow_mm3_s=8.0, cycles=3))
    table = gc.read_pattern(pattern)
    assert table.unknown_commands == {}
    assert gc.pa_events(table) == []              # the printer's own factor
    roles = [seg.role for seg in pattern.segments]
    assert roles == ["slow", "fast"] * 3 + ["slow"]
    area = s.bead_area_mm2()
    for seg in pattern.segments:
        q = 8.0 if seg.role == "fast" else 2.0
        assert seg.flow_mm3_s == pytest.approx(q, rel=1e-5)
        assert seg.speed_mm_s == pytest.approx(q / area, rel=1e-5)


def test_flowline_cruises_and_sets_one_factor_per_line(gc: Any) -> None:
    pattern = flowline_pattern(PrintSettings(), FlowLineParams(
        flow_mm3_s=10.0, k_start=0.0, k_end=0.04, k_step=0.02))
    check = verify_pattern(pattern, printer="generic-klipper")
    assert check.ok
    for c in check.segments:
        assert c.flow_mm3_s == pytest.approx(c.segment.flow_mm3_s, rel=1e-4)
    events = gc.pa_events(gc.read_pattern(pattern))
    assert [k for _, _, k in events] == pytest.approx([0.0, 0.02, 0.04])
    assert pattern.value_name == "k_s"


def test_flowline_needs_all_three_k_options() -> None:
    with pytest.raises(CalibrationError, match=r"k_start, k_end and k_step together"):
        FlowLineParams(k_start=0.0)


def test_bead_area_is_the_slicer_model() -> None:
    # [001 Eq. 7] with w = 0.48, h = 0.2: 0.096 − (1 − π/4)·0.04
    assert PrintSettings().bead_area_mm2() == pytest.approx(
        0.096 - (1 - math.pi / 4) * 0.04, rel=1e-15)
