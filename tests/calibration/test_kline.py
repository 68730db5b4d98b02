"""K-factor lines: read back by the reader and planned by the planner."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from flowtwin.calibration.patterns.kline import KLineParams, kline_pattern
from flowtwin.calibration.patterns.pattern import PrintSettings
from flowtwin.calibration.patterns.verify import verify_pattern
from flowtwin.firmware import Firmware


def test_defaults_follow_tronvoll_table_1() -> None:
    # [001 Table I]: K_LA 0-0.2 s in 0.01 s increments, 0.48 mm lines; [001 Fig. 10] /
    # Marlin's pattern: 20 mm slow, 40 mm fast, 20 mm slow
    p = KLineParams()
    assert p.k_values == pytest.approx([0.01 * i for i in range(21)])
    assert (p.slow_length_mm, p.fast_length_mm) == (20.0, 40.0)
    assert PrintSettings().line_width_mm == 0.48


def test_read_back_no_unknown_commands_and_net_filament(gc: Any, firmware: Firmware) -> None:
    s = PrintSettings(firmware=firmware)
    pattern = kline_pattern(s, KLineParams(k_end=0.05))
    table = gc.read_pattern(pattern)
    assert table.unknown_commands == {}
    assert table.warnings == []
    assert table.net_filament_mm()[0] == pytest.approx(pattern.filament_mm,
                                                       abs=gc.e_tolerance(pattern))
    # independent sum of the beads [001 Eq. 7]: 6 lines of 80 mm, the 80 mm prime line,
    # ticks of 4 mm on lines 0 and 5, per filament area
    area = 0.48 * 0.2 - (1 - math.pi / 4) * 0.2 ** 2
    beads_mm = (6 * 80.0 + 80.0 + 2 * 4.0) * area / (math.pi * 1.75 ** 2 / 4)
    assert pattern.bead_filament_mm == pytest.approx(beads_mm, rel=1e-12)
    # the only net loss is the final retraction
    assert pattern.filament_mm == pytest.approx(beads_mm - s.retract_mm, rel=1e-12)


def test_one_advance_command_per_line_before_its_first_move(gc: Any, firmware: Firmware) -> None:
    pattern = kline_pattern(PrintSettings(firmware=firmware), KLineParams(k_end=0.05))
    table = gc.read_pattern(pattern)
    events = gc.pa_events(table)
    assert [k for _, _, k in events] == pytest.approx(list(pattern.values))
    lines = table.moves["line"]
    slow_first = [s for s in pattern.segments if s.role == "slow"][::2]
    for (move_index, _, _), seg in zip(events, slow_first, strict=True):
        # the command takes effect right before the line's first (slow) segment
        assert lines[move_index] == seg.line


@pytest.mark.parametrize("printer", ["generic-klipper", "generic-marlin", "prusa-i3-mk25"])
def test_fast_and_slow_segments_cruise_at_their_target(printer: str) -> None:
    fw = Firmware.KLIPPER if printer == "generic-klipper" else Firmware.MARLIN
    pattern = kline_pattern(PrintSettings(firmware=fw), KLineParams(k_end=0.05))
    check = verify_pattern(pattern, printer=printer)
    assert check.ok
    fast = [c for c in check.segments if c.segment.role == "fast"]
    assert len(fast) == 6
    for c in check.segments:
        # planner speeds are float32; F is written to 0.1 mm/min
        assert c.cruise_v_mm_s == pytest.approx(c.segment.speed_mm_s, rel=1e-5)
        assert c.cruise_t_s > 0.0
    assert {round(c.cruise_v_mm_s, 3) for c in fast} == {70.0}


def test_flow_of_the_fast_segment_from_reader_e_and_planner_speed() -> None:
    pattern = kline_pattern(PrintSettings(), KLineParams(k_end=0.02))
    check = verify_pattern(pattern, printer="generic-klipper")
    area = PrintSettings().bead_area_mm2()
    for c in check.segments:
        # E rounded to 1e-5 mm on 0.73-1.5 mm of filament: relative error < 2e-5
        assert c.flow_mm3_s == pytest.approx(area * c.segment.speed_mm_s, rel=5e-5)


def test_unreachable_fast_speed_is_reported() -> None:
    # 300 mm/s from 20 mm/s at 500 mm/s² needs (300² − 20²)/(2·500) = 89.6 mm per ramp,
    # far more than the 40 mm fast segment
    s = PrintSettings(accel_mm_s2=500.0)
    pattern = kline_pattern(s, KLineParams(k_end=0.01, fast_speed_mm_s=300.0))
    check = verify_pattern(pattern, printer="generic-klipper")
    assert not check.ok
    assert {c.segment.role for c in check.shortfalls} == {"fast"}
    top = max(c.cruise_v_mm_s for c in check.shortfalls)
    # with a triangle profile over 40 mm starting and ending at 20 mm/s:
    # v_peak² = 20² + 2·a·(40/2) → v_peak ≈ 144 mm/s (Klipper's minimum cruise ratio
    # lowers it further)
    assert top <= math.sqrt(20.0 ** 2 + 500.0 * 40.0) + 1e-3


def test_geometry_lines_are_straight_and_evenly_spaced(gc: Any) -> None:
    pattern = kline_pattern(PrintSettings(), KLineParams(k_end=0.03, mark_every=0))
    table = gc.read_pattern(pattern)
    m = table.moves
    ext = gc.extruding(table)
    ys = []
    for i in range(4):
        sel = ext & (m["feature"] == table.features.index(f"K-line {i}"))
        assert np.count_nonzero(sel) == 3                      # slow, fast, slow
        assert np.ptp(m["y"][sel]) == 0.0                      # straight along X
        assert m["x"][sel][-1] - m["x"][sel][0] == pytest.approx(60.0)  # ends 20+40 mm on
        ys.append(float(m["y"][sel][0]))
    assert np.diff(ys) == pytest.approx([5.0, 5.0, 5.0])


def test_invalid_parameters_name_the_field() -> None:
    from flowtwin.errors import CalibrationError

    with pytest.raises(CalibrationError, match=r"\[slow_speed_mm_s\]"):
        KLineParams(slow_speed_mm_s=80.0, fast_speed_mm_s=70.0)
    with pytest.raises(CalibrationError, match=r"\[k_step\]"):
        KLineParams(k_step=0.0).k_values  # noqa: B018
    with pytest.raises(CalibrationError, match=r"\[k_end\]"):
        KLineParams(k_start=0.1, k_end=0.05).k_values  # noqa: B018
