"""Helpers for the calibration tests: read patterns back with flowtwin's own reader.

(pytest runs in importlib mode, so the helpers reach the tests as the ``gc`` fixture.)
"""

from __future__ import annotations

import numpy as np
import pytest

from flowtwin.calibration.firmware import Firmware
from flowtwin.calibration.pattern_base import Pattern
from flowtwin.gcode.moves import MoveKind, MoveTable
from flowtwin.gcode.reader import read_gcode

#: Advance-factor parameter of each firmware's command, as the reader stores it.
PA_EVENTS = {"SET_PRESSURE_ADVANCE": "ADVANCE", "M900": "K", "M572": "S"}


def read_pattern(pattern: Pattern) -> MoveTable:
    """The pattern's G-code read by :func:`flowtwin.gcode.reader.read_gcode`."""
    return read_gcode(pattern.text().encode())


def pa_events(table: MoveTable) -> list[tuple[int, int, float]]:
    """``(move_index, line, K)`` of every advance command the reader found."""
    out = []
    for ev in table.events:
        key = PA_EVENTS.get(ev.code)
        if key is not None:
            value = ev.params[key]
            assert isinstance(value, float)
            out.append((ev.move_index, ev.line, value))
    return out


def e_tolerance(pattern: Pattern) -> float:
    """Worst-case sum of the E rounding: each E word is written to 5 decimals (±5e-6 mm)."""
    return pattern.e_words * 5e-6 + 1e-9


def extruding(table: MoveTable) -> np.ndarray:
    """Boolean mask of moves that extrude while moving in XY (not unretractions)."""
    kind = table.moves["kind"]
    return ((kind & MoveKind.EXTRUDE) != 0) & ((kind & MoveKind.XY) != 0)


class _Helpers:
    """The helper functions above, as attributes."""

    read_pattern = staticmethod(read_pattern)
    pa_events = staticmethod(pa_events)
    e_tolerance = staticmethod(e_tolerance)
    extruding = staticmethod(extruding)


@pytest.fixture
def gc() -> _Helpers:
    """Read-back helpers (``gc.read_pattern(p)``, ``gc.pa_events(t)``, …)."""
    return _Helpers()


@pytest.fixture(params=list(Firmware), ids=[f.value for f in Firmware])
def firmware(request: pytest.FixtureRequest) -> Firmware:
    """Each firmware the patterns support."""
    fw = request.param
    assert isinstance(fw, Firmware)
    return fw
