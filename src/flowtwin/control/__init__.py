"""Closed-loop slip control on a real or simulated printer [003 §2.3].

Every printer connection implements one small interface (:class:`Printer`,
:mod:`flowtwin.control.printer`; :func:`open_printer` opens one from a URL):

* :mod:`flowtwin.control.transports` — the real printer hosts: OctoPrint, Moonraker
  (Klipper), a serial port (Marlin), their network plumbing and API keys;
* :mod:`flowtwin.control.simulated` — the twin as a printer: it prints G-code physically
  (:class:`PrintJob`, :class:`JobRunner`, the extruder step: slip from the machine's
  physics at the current temperature and multipliers) and films its drive;
* :mod:`flowtwin.control.loop` — the control laws (Greeff's, feed-forward, PI, with limits
  and rate limits), the measurement sources, the clocks, the log and the supervisor that
  returns the printer to 100 % on every exit path.

The firmware's command syntax comes from :mod:`flowtwin.firmware`. Measurement sources
built on :mod:`flowtwin.vision` (OpenCV) are imported from their modules so that importing
the package stays light: :mod:`flowtwin.control.loop.video` (``VideoSource``,
``CameraSource``), :mod:`flowtwin.control.simulated.camera` (``TwinCameraSource``). The
paper's print-job test [003 §3.3] that runs this loop is in :mod:`flowtwin.reproduce`
(``greeff2017_loop``). See ``docs/control.md``.
"""

from __future__ import annotations

from flowtwin.control.connect import open_printer
from flowtwin.control.loop.clock import AcceleratedClock, Clock, RealClock, SimClock
from flowtwin.control.loop.controllers import (
    FeedForwardController,
    GreeffController,
    Limits,
    OpenLoopController,
    PIController,
    limit_command,
    make_controller,
)
from flowtwin.control.loop.log import ControlLog
from flowtwin.control.loop.measurement import (
    Measurement,
    MeasurementLost,
    MeasurementSource,
    SyntheticSlipSource,
)
from flowtwin.control.loop.supervisor import Fault, FaultKind, LoopSettings, RunSummary, run_control
from flowtwin.control.printer import CommandRejected, ConnectionLost, Factors, Printer, Response
from flowtwin.control.simulated.extruder import (
    ExtruderState,
    StepFlux,
    StepParams,
    step_extrusion,
    step_params,
)
from flowtwin.control.simulated.job import PrintJob
from flowtwin.control.simulated.runner import JobHistory, JobRunner, JobTotals
from flowtwin.control.simulated.twin import TwinPrinter
from flowtwin.control.transports.credentials import ApiKey, load_api_key
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
    "run_control",
    "step_extrusion",
    "step_params",
]
