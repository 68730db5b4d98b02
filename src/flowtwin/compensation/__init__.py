"""Compensation: make a G-code extrude what it means, or tune the firmware to.

* :func:`compensate` rewrites a G-code (pressure advance baked in [001], slip feed-forward
  [000 §6], grinding guard [000 §4], flow pacing, strand-lag trajectory [004]) and reports
  what the twin predicts before and after (:class:`CompensationReport`);
* :func:`best_pressure_advance` and :func:`adaptive_pa_table` compute firmware settings.

See ``docs/compensation.md``.
"""

from flowtwin.compensation.advance import AdvanceLaw, AdvanceOptions
from flowtwin.compensation.guard import GuardOptions
from flowtwin.compensation.limits import ExtruderLimits, extruder_limits
from flowtwin.compensation.metrics import FlowFigures, flow_figures
from flowtwin.compensation.outcome import AdvancePassSummary, CompensationReport
from flowtwin.compensation.pace import PaceOptions, PaceReport
from flowtwin.compensation.pipeline import compensate
from flowtwin.compensation.refine import RefineOptions
from flowtwin.compensation.settings import AdvanceFit, adaptive_pa_table, best_pressure_advance
from flowtwin.compensation.slip import SlipOptions
from flowtwin.compensation.trajectory import TrajectoryOptions, TrajectoryReport

__all__ = [
    "AdvanceFit",
    "AdvanceLaw",
    "AdvanceOptions",
    "AdvancePassSummary",
    "CompensationReport",
    "ExtruderLimits",
    "FlowFigures",
    "GuardOptions",
    "PaceOptions",
    "PaceReport",
    "RefineOptions",
    "SlipOptions",
    "TrajectoryOptions",
    "TrajectoryReport",
    "adaptive_pa_table",
    "best_pressure_advance",
    "compensate",
    "extruder_limits",
    "flow_figures",
]
