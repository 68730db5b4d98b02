"""Pressure-advance tower: K = start + step·z changes at the right Z."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from flowtwin.calibration.patterns.pattern import PrintSettings
from flowtwin.calibration.patterns.tower import TowerParams, tower_k_at, tower_pattern
from flowtwin.calibration.patterns.verify import verify_pattern
from flowtwin.errors import CalibrationError
from flowtwin.firmware import Firmware

PARAMS = TowerParams(k_start=0.02, k_step_per_mm=0.01, height_mm=3.0, size_mm=20.0, walls=2)


def test_factor_changes_at_the_right_z(gc: Any, firmware: Firmware) -> None:
    pattern = tower_pattern(PrintSettings(firmware=firmware), PARAMS)
    table = gc.read_pattern(pattern)
    assert table.unknown_commands == {}
    assert table.net_filament_mm()[0] == pytest.approx(pattern.filament_mm,
                                                       abs=gc.e_tolerance(pattern))
    events = gc.pa_events(table)
    assert len(events) == 15                            # 3 mm / 0.2 mm layers
    m = table.moves
    ext = gc.extruding(table)
    bounds = [e[0] for e in events] + [len(m)]
    for i, (first, _, k) in enumerate(events):
        seg = np.arange(first, bounds[i + 1])
        z_values = np.unique(m["z"][seg[ext[seg]]])
        # every extrusion until the next command is on one layer, at that layer's z
        assert z_values.size == 1
        z = float(z_values[0])
        assert z == pytest.approx(0.2 * (i + 1), abs=1e-9)
        # K written with 5 decimals
        assert k == pytest.approx(0.02 + 0.01 * z, abs=5e-6)
        assert k == pytest.approx(tower_k_at(PARAMS, z), abs=5e-6)


def test_walls_cruise(gc: Any) -> None:
    pattern = tower_pattern(PrintSettings(), PARAMS)
    check = verify_pattern(pattern, printer="generic-klipper")
    assert check.ok
    assert len(check.segments) == 15 * 2 * 4


def test_top_factor_bounded() -> None:
    with pytest.raises(CalibrationError, match=r"\[k_step_per_mm\]"):
        TowerParams(k_start=0.0, k_step_per_mm=0.5, height_mm=30.0)
