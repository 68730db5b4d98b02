"""Compensation: make a G-code extrude what it means, or tune the firmware to.

* :func:`compensate` rewrites a G-code (pressure advance baked in [001], slip feed-forward
  [000 §6], grinding guard [000 §4], flow pacing, strand-lag trajectory [004]) and reports
  what the twin predicts before and after (:class:`CompensationReport`);
* :func:`best_pressure_advance` and :func:`adaptive_pa_table` compute firmware settings.

See ``docs/compensation.md``.
"""

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from flowtwin.compensation.advance import AdvanceLaw, AdvanceOptions
    from flowtwin.compensation.guard import GuardOptions
    from flowtwin.compensation.limits import ExtruderLimits, extruder_limits
    from flowtwin.compensation.metrics import FlowFigures, flow_figures
    from flowtwin.compensation.pace import PaceOptions, PaceReport
    from flowtwin.compensation.pipeline import CompensationReport, compensate
    from flowtwin.compensation.refine import RefineOptions
    from flowtwin.compensation.settings import AdvanceFit, adaptive_pa_table, best_pressure_advance
    from flowtwin.compensation.slip import SlipOptions
    from flowtwin.compensation.trajectory import TrajectoryOptions, TrajectoryReport

#: Public name -> module that defines it: imported on first use (PEP 562), so importing one
#: submodule (``flowtwin.compensation.guard``) does not load the whole pipeline.
_EXPORTS = {
    "AdvanceFit": "flowtwin.compensation.settings",
    "AdvanceLaw": "flowtwin.compensation.advance",
    "AdvanceOptions": "flowtwin.compensation.advance",
    "CompensationReport": "flowtwin.compensation.pipeline",
    "ExtruderLimits": "flowtwin.compensation.limits",
    "FlowFigures": "flowtwin.compensation.metrics",
    "GuardOptions": "flowtwin.compensation.guard",
    "PaceOptions": "flowtwin.compensation.pace",
    "PaceReport": "flowtwin.compensation.pace",
    "RefineOptions": "flowtwin.compensation.refine",
    "SlipOptions": "flowtwin.compensation.slip",
    "TrajectoryOptions": "flowtwin.compensation.trajectory",
    "TrajectoryReport": "flowtwin.compensation.trajectory",
    "adaptive_pa_table": "flowtwin.compensation.settings",
    "best_pressure_advance": "flowtwin.compensation.settings",
    "compensate": "flowtwin.compensation.pipeline",
    "extruder_limits": "flowtwin.compensation.limits",
    "flow_figures": "flowtwin.compensation.metrics",
}


def __getattr__(name: str) -> object:
    where = _EXPORTS.get(name)
    if where is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(where), name)
    globals()[name] = value
    return value


__all__ = [
    "AdvanceFit",
    "AdvanceLaw",
    "AdvanceOptions",
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
