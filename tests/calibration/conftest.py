"""Helpers for the calibration tests: read patterns back with flowtwin's own reader.

(pytest runs in importlib mode, so the helpers reach the tests as the ``gc`` fixture.)
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
import pytest

from flowtwin.calibration.fits.kfit import kline_for_machine
from flowtwin.calibration.fits.lagmodel import LagParams
from flowtwin.calibration.image.twin_render import (
    ImageConditions,
    RenderedImage,
    render_pattern_image,
)
from flowtwin.calibration.patterns.kline import KLineParams
from flowtwin.calibration.patterns.pattern import Pattern, PrintSettings
from flowtwin.firmware import Firmware
from flowtwin.gcode.moves import MoveKind, MoveTable
from flowtwin.gcode.reader import read_gcode
from flowtwin.profiles.machine import Machine, load_machine

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


# --- the K-line images (fit-k / from-image tests) --------------------------------------

@pytest.fixture(scope="session")
def tronvoll() -> Machine:
    """Tronvoll's set-up [001 Table I] (Prusa firmware: M572 advance with smoothing)."""
    return load_machine("tronvoll2019")


@pytest.fixture(scope="session")
def kline7(tronvoll: Machine) -> Pattern:
    """Seven K-lines, K = 0.02 … 0.08 s, ticks on lines 0 and 5, for Tronvoll's printer."""
    return kline_for_machine(tronvoll, PrintSettings(),
                             KLineParams(k_start=0.02, k_end=0.08, k_step=0.01))


@pytest.fixture(scope="session")
def render_kline7(tronvoll: Machine, kline7: Pattern
                  ) -> Callable[[float, ImageConditions], RenderedImage]:
    """Render ``kline7`` for a lag under image conditions (cached per session)."""

    @functools.lru_cache(maxsize=16)
    def render(k_s: float, conditions: ImageConditions) -> RenderedImage:
        return render_pattern_image(kline7.text().encode(), LagParams(k_s), machine=tronvoll,
                                    conditions=conditions)

    return render
