"""Ellis-style chevrons: one advance factor per chevron, never changed inside a corner."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from flowtwin.calibration.patterns.chevron import ChevronParams, chevron_pattern
from flowtwin.calibration.patterns.pattern import PrintSettings
from flowtwin.calibration.patterns.verify import verify_pattern
from flowtwin.firmware import Firmware

PARAMS = ChevronParams(k_start=0.0, k_end=0.03, k_step=0.01, layers=3, walls=3)


def _chevron_moves(table: Any, gc: Any, j: int) -> np.ndarray:
    m = table.moves
    return np.nonzero(gc.extruding(table)
                      & (m["feature"] == table.features.index(f"Chevron {j}")))[0]


def test_read_back(gc: Any, firmware: Firmware) -> None:
    pattern = chevron_pattern(PrintSettings(firmware=firmware), PARAMS)
    table = gc.read_pattern(pattern)
    assert table.unknown_commands == {}
    assert table.net_filament_mm()[0] == pytest.approx(pattern.filament_mm,
                                                       abs=gc.e_tolerance(pattern))


def test_one_advance_command_per_chevron_never_inside_a_corner(gc: Any, firmware: Firmware) -> None:
    pattern = chevron_pattern(PrintSettings(firmware=firmware), PARAMS)
    table = gc.read_pattern(pattern)
    events = gc.pa_events(table)
    # once per chevron per layer, in order
    assert len(events) == 4 * 3
    assert [k for _, _, k in events] == pytest.approx([0.0, 0.01, 0.02, 0.03] * 3)
    m = table.moves
    layer = m["layer"]
    for j, k in enumerate([0.0, 0.01, 0.02, 0.03]):
        moves = _chevron_moves(table, gc, j)
        for lay in range(3):
            block = moves[layer[moves] == lay]
            assert block.size == 2 * PARAMS.walls          # two arms per wall
            first, last = int(block[0]), int(block[-1])
            before = [e for e in events if e[0] <= first]
            inside = [e for e in events if first < e[0] <= last]
            # the factor in force for every move of the chevron is its own ...
            assert before[-1][2] == pytest.approx(k)
            # ... and no command comes between its first and last move (corners included)
            assert inside == []


def test_corners_are_right_angles_and_walls_touch(gc: Any) -> None:
    s = PrintSettings()
    pattern = chevron_pattern(s, PARAMS)
    table = gc.read_pattern(pattern)
    m = table.moves
    start = np.vstack([np.concatenate(([0.0], m["x"][:-1])), np.concatenate(([0.0],
                                                                              m["y"][:-1]))])
    end = np.vstack([m["x"], m["y"]])
    moves = _chevron_moves(table, gc, 1)
    moves = moves[m["layer"][moves] == 1]
    d = end[:, moves] - start[:, moves]
    d = d / np.linalg.norm(d, axis=0)
    for w in range(PARAMS.walls):
        a, b = d[:, 2 * w], d[:, 2 * w + 1]
        # 3-decimal coordinates: cos of the corner angle within ~1e-4 of 0
        assert float(a @ b) == pytest.approx(0.0, abs=2e-4)
    # neighbouring walls: parallel arms one line spacing apart (w − (1 − π/4)·h)
    u = d[:, 0]
    normal = np.array([-u[1], u[0]])
    p0 = start[:, moves[0]]
    for w in (1, 2):
        (arm,) = [k for k in (2 * w, 2 * w + 1) if abs(float(d[:, k] @ normal)) < 1e-3]
        offset = abs(float((start[:, moves[arm]] - p0) @ normal))
        assert offset == pytest.approx(w * s.line_spacing_mm, abs=2e-3)


@pytest.mark.parametrize("printer", ["generic-klipper", "generic-marlin"])
def test_arms_cruise_at_print_speed(printer: str) -> None:
    fw = Firmware.KLIPPER if printer == "generic-klipper" else Firmware.MARLIN
    pattern = chevron_pattern(PrintSettings(firmware=fw), PARAMS)
    check = verify_pattern(pattern, printer=printer)
    assert check.ok
    arms = [c for c in check.segments if c.segment.role == "arm"]
    assert len(arms) == 4 * 2 * 3 * 2          # chevrons × layers 1-2 × walls × arms
    assert all(c.cruise_v_mm_s == pytest.approx(100.0, rel=1e-5) for c in arms)
