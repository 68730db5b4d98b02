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

from typing import TYPE_CHECKING

from flowtwin._lazy import lazy_exports

if TYPE_CHECKING:
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
    from flowtwin.control.loop.supervisor import (
        Fault,
        FaultKind,
        LoopSettings,
        RunSummary,
        run_control,
    )
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

# names resolve on first use (importing the package stays light)
__getattr__, __dir__ = lazy_exports(__name__, {
    "open_printer": "flowtwin.control.connect",
    "AcceleratedClock": "flowtwin.control.loop.clock",
    "Clock": "flowtwin.control.loop.clock",
    "RealClock": "flowtwin.control.loop.clock",
    "SimClock": "flowtwin.control.loop.clock",
    "FeedForwardController": "flowtwin.control.loop.controllers",
    "GreeffController": "flowtwin.control.loop.controllers",
    "Limits": "flowtwin.control.loop.controllers",
    "OpenLoopController": "flowtwin.control.loop.controllers",
    "PIController": "flowtwin.control.loop.controllers",
    "limit_command": "flowtwin.control.loop.controllers",
    "make_controller": "flowtwin.control.loop.controllers",
    "ControlLog": "flowtwin.control.loop.log",
    "Measurement": "flowtwin.control.loop.measurement",
    "MeasurementLost": "flowtwin.control.loop.measurement",
    "MeasurementSource": "flowtwin.control.loop.measurement",
    "SyntheticSlipSource": "flowtwin.control.loop.measurement",
    "Fault": "flowtwin.control.loop.supervisor",
    "FaultKind": "flowtwin.control.loop.supervisor",
    "LoopSettings": "flowtwin.control.loop.supervisor",
    "RunSummary": "flowtwin.control.loop.supervisor",
    "run_control": "flowtwin.control.loop.supervisor",
    "CommandRejected": "flowtwin.control.printer",
    "ConnectionLost": "flowtwin.control.printer",
    "Factors": "flowtwin.control.printer",
    "Printer": "flowtwin.control.printer",
    "Response": "flowtwin.control.printer",
    "ExtruderState": "flowtwin.control.simulated.extruder",
    "StepFlux": "flowtwin.control.simulated.extruder",
    "StepParams": "flowtwin.control.simulated.extruder",
    "step_extrusion": "flowtwin.control.simulated.extruder",
    "step_params": "flowtwin.control.simulated.extruder",
    "PrintJob": "flowtwin.control.simulated.job",
    "JobHistory": "flowtwin.control.simulated.runner",
    "JobRunner": "flowtwin.control.simulated.runner",
    "JobTotals": "flowtwin.control.simulated.runner",
    "TwinPrinter": "flowtwin.control.simulated.twin",
    "ApiKey": "flowtwin.control.transports.credentials",
    "load_api_key": "flowtwin.control.transports.credentials",
    "Channel": "flowtwin.firmware",
})
