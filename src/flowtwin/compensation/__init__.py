"""Compensation: make a G-code extrude what it means, or tune the firmware to.

* :func:`compensate` rewrites a G-code (pressure advance baked in [001], slip feed-forward
  [000 §6], grinding guard [000 §4], flow pacing, strand-lag trajectory [004]) and reports
  what the twin predicts before and after (:class:`CompensationReport`).

Firmware settings (the best advance factor, an adaptive table) are calibration's:
:mod:`flowtwin.calibration.tuning.advance_settings`.

See ``docs/compensation.md``.
"""

from typing import TYPE_CHECKING

from flowtwin._lazy import lazy_exports

if TYPE_CHECKING:
    from flowtwin.compensation.advance import AdvanceLaw, AdvanceOptions
    from flowtwin.compensation.guard import GuardOptions
    from flowtwin.compensation.limits import ExtruderLimits, extruder_limits
    from flowtwin.compensation.metrics import FlowFigures, flow_figures
    from flowtwin.compensation.outcome import AdvancePassSummary, CompensationReport
    from flowtwin.compensation.pace import PaceOptions, PaceReport
    from flowtwin.compensation.pipeline import compensate
    from flowtwin.compensation.refine import RefineOptions
    from flowtwin.compensation.slip import SlipOptions
    from flowtwin.compensation.trajectory import TrajectoryOptions, TrajectoryReport

__all__ = [
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
    "compensate",
    "extruder_limits",
    "flow_figures",
]

# names resolve on first use: importing one submodule (the verdict's
# flowtwin.compensation.guard) does not load the whole pipeline
__getattr__, __dir__ = lazy_exports(__name__, {
    "AdvanceLaw": "flowtwin.compensation.advance",
    "AdvanceOptions": "flowtwin.compensation.advance",
    "AdvancePassSummary": "flowtwin.compensation.outcome",
    "CompensationReport": "flowtwin.compensation.outcome",
    "ExtruderLimits": "flowtwin.compensation.limits",
    "FlowFigures": "flowtwin.compensation.metrics",
    "GuardOptions": "flowtwin.compensation.guard",
    "PaceOptions": "flowtwin.compensation.pace",
    "PaceReport": "flowtwin.compensation.pace",
    "RefineOptions": "flowtwin.compensation.refine",
    "SlipOptions": "flowtwin.compensation.slip",
    "TrajectoryOptions": "flowtwin.compensation.trajectory",
    "TrajectoryReport": "flowtwin.compensation.trajectory",
    "compensate": "flowtwin.compensation.pipeline",
    "extruder_limits": "flowtwin.compensation.limits",
    "flow_figures": "flowtwin.compensation.metrics",
})
