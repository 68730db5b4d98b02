"""Extrusion dynamics: commanded feed, firmware pressure advance, and the lag/slip integrator.

Flow (docs/spec.md §3.4, §3.6)::

    MoveTable + Timeline ─► nominal_feed ─► apply_advance (the firmware's, flowtwin.firmware)
        ─► integrate (state Δl: lag [001], no backflow, slip [000], grinding) ─► DynamicsResult

See ``docs/dynamics.md`` for the model, its assumptions and the public API.
"""

from flowtwin.dynamics.advance import (
    AdvanceSchedule,
    AdvanceSettings,
    advance_eligible,
    advance_schedule,
    apply_advance,
    printer_advance,
)
from flowtwin.dynamics.extrusion_result import (
    MOVE_RESULT_DTYPE,
    SERIES_DTYPE,
    DynamicsResult,
    DynamicsSummary,
)
from flowtwin.dynamics.feed import CommandedFeed, nominal_feed
from flowtwin.dynamics.integrator import integrate
from flowtwin.dynamics.params import ExtrusionParams, resolve_per_move
from flowtwin.dynamics.predict import predict
from flowtwin.dynamics.thermal import TemperatureSchedule, move_temperatures, temperature_schedule

__all__ = [
    "MOVE_RESULT_DTYPE",
    "SERIES_DTYPE",
    "AdvanceSchedule",
    "AdvanceSettings",
    "CommandedFeed",
    "DynamicsResult",
    "DynamicsSummary",
    "ExtrusionParams",
    "TemperatureSchedule",
    "advance_eligible",
    "advance_schedule",
    "apply_advance",
    "integrate",
    "move_temperatures",
    "nominal_feed",
    "predict",
    "printer_advance",
    "resolve_per_move",
    "temperature_schedule",
]
