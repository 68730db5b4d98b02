"""Closed-loop slip control on a real or simulated printer [003 §2.3].

Printer connections behind one small interface (:class:`Printer`): OctoPrint, Moonraker,
a serial port (Marlin) and the twin; per-firmware command encoding; pure controllers
(Greeff's, feed-forward, PI) with limits and rate limits; a supervisor that returns the
printer to 100 % on every exit path. The twin prints G-code physically
(:class:`PrintJob`, :class:`JobRunner`: slip from the machine's physics at the current
temperature and multipliers). See ``docs/control.md``.

Measurement sources built on :mod:`flowtwin.vision` (OpenCV) live in submodules so that
importing the package stays light: :mod:`flowtwin.control.video` (``VideoSource``,
``CameraSource``), :mod:`flowtwin.control.twin_camera` (``TwinCameraSource``) and the
simulated print-job test [003 §3.3] :mod:`flowtwin.control.printjob`.
"""

from __future__ import annotations

from flowtwin.control.clock import AcceleratedClock, Clock, RealClock, SimClock
from flowtwin.control.connect import open_printer
from flowtwin.control.controllers import (
    FeedForwardController,
    GreeffController,
    Limits,
    OpenLoopController,
    PIController,
    limit_command,
    make_controller,
)
from flowtwin.control.credentials import ApiKey, load_api_key
from flowtwin.control.extrusion import (
    ExtruderState,
    StepFlux,
    StepParams,
    step_extrusion,
    step_params,
)
from flowtwin.control.job import PrintJob
from flowtwin.control.log import ControlLog
from flowtwin.control.measurement import (
    Measurement,
    MeasurementLost,
    MeasurementSource,
    SyntheticSlipSource,
)
from flowtwin.control.polygon import PolygonSpec, polygon_gcode
from flowtwin.control.printer import CommandRejected, ConnectionLost, Factors, Printer, Response
from flowtwin.control.supervisor import Fault, FaultKind, LoopSettings, RunSummary, run_control
from flowtwin.control.twin import TwinPrinter
from flowtwin.control.twinjob import JobHistory, JobRunner, JobTotals
from flowtwin.firmware import Channel

__all__ = [
    "AcceleratedClock",
    "ApiKey",
    "Channel",
    "Clock",
    "CommandRejected",
    "ConnectionLost",
    "ControlLog",
    "ExtruderState",
    "Factors",
    "Fault",
    "FaultKind",
    "FeedForwardController",
    "GreeffController",
    "JobHistory",
    "JobRunner",
    "JobTotals",
    "Limits",
    "LoopSettings",
    "Measurement",
    "MeasurementLost",
    "MeasurementSource",
    "OpenLoopController",
    "PIController",
    "PolygonSpec",
    "PrintJob",
    "Printer",
    "RealClock",
    "Response",
    "RunSummary",
    "SimClock",
    "StepFlux",
    "StepParams",
    "SyntheticSlipSource",
    "TwinPrinter",
    "limit_command",
    "load_api_key",
    "make_controller",
    "open_printer",
    "polygon_gcode",
    "run_control",
    "step_extrusion",
    "step_params",
]
