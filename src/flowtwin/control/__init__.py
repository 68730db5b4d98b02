"""Closed-loop slip control on a real or simulated printer [003 §2.3].

Printer connections behind one small interface (:class:`Printer`): OctoPrint, Moonraker,
a serial port (Marlin) and the twin; per-firmware command encoding; pure controllers
(Greeff's, feed-forward, PI) with limits and rate limits; a supervisor that returns the
printer to 100 % on every exit path. See ``docs/control.md``.
"""

from __future__ import annotations

from flowtwin.control.clock import AcceleratedClock, Clock, RealClock, SimClock
from flowtwin.control.connect import open_printer
from flowtwin.control.controllers import (
    FeedForwardController,
    GreeffController,
    Limits,
    PIController,
    limit_command,
    make_controller,
)
from flowtwin.control.credentials import ApiKey, load_api_key
from flowtwin.control.firmware import Channel, Firmware, encode_factor
from flowtwin.control.log import ControlLog
from flowtwin.control.measurement import (
    Measurement,
    MeasurementLost,
    MeasurementSource,
    SyntheticSlipSource,
)
from flowtwin.control.printer import CommandRejected, ConnectionLost, Factors, Printer, Response
from flowtwin.control.supervisor import Fault, FaultKind, LoopSettings, RunSummary, run_control
from flowtwin.control.twin import TwinPrinter

__all__ = [
    "AcceleratedClock",
    "ApiKey",
    "Channel",
    "Clock",
    "CommandRejected",
    "ConnectionLost",
    "ControlLog",
    "Factors",
    "Fault",
    "FaultKind",
    "FeedForwardController",
    "Firmware",
    "GreeffController",
    "Limits",
    "LoopSettings",
    "Measurement",
    "MeasurementLost",
    "MeasurementSource",
    "PIController",
    "Printer",
    "RealClock",
    "Response",
    "RunSummary",
    "SimClock",
    "SyntheticSlipSource",
    "TwinPrinter",
    "encode_factor",
    "limit_command",
    "load_api_key",
    "make_controller",
    "open_printer",
    "run_control",
]
