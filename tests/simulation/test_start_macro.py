"""The nozzle temperature a Klipper start macro sets reaches the twin's physics."""

from __future__ import annotations

import numpy as np

from flowtwin.gcode.generator import PrintSpec, generate_print
from flowtwin.gcode.moves import MoveKind
from flowtwin.simulation import simulate


def _klipper_style(target_c: float) -> bytes:
    """The project's example print started like OrcaSlicer's Klipper profiles: heaters
    off, then the start macro with the first layer's temperatures, no M104/M109 after."""
    body = [ln for ln in generate_print(PrintSpec(layers=3))
            if not ln.startswith(("M104", "M109"))]
    head = ["M140 S0", "M104 S0", f"START_PRINT EXTRUDER_TEMP={target_c:g} BED_TEMP=60"]
    return ("\n".join([*head, *body]) + "\n").encode()


def test_start_macro_temperature_is_the_printing_temperature() -> None:
    for target in (205.0, 225.0):  # two values: the twin follows the macro, not a default
        result = simulate(_klipper_style(target))
        m = result.plan.table.moves
        printing = (m["kind"] & MoveKind.EXTRUDE) != 0
        # M109 semantics: the macro waits for its temperature, so every printing move
        # sees it (the heater holds the set point from there on)
        np.testing.assert_allclose(result.parameters.temperature_c[printing], target,
                                   atol=0.5)
        assert any("START_PRINT EXTRUDER_TEMP" in w for w in result.plan.table.warnings)
