"""The one small interface every printer connection implements.

A :class:`Printer` connects, sends single G-code commands and waits for the firmware's
acknowledgement, sets the speed (``M220``) and flow (``M221``) multipliers with the
firmware's own encoding (:mod:`flowtwin.firmware.factors`), reads them back where the
firmware can report them, and closes. Connections: OctoPrint, Moonraker, a serial port
(Marlin line protocol) and the twin as a simulated printer.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from flowtwin.errors import PrinterConnectionError
from flowtwin.firmware import (
    Channel,
    Firmware,
    applied_percent,
    check_factor_commands,
    encode_factor,
)

__all__ = [
    "CommandRejected",
    "ConnectionLost",
    "FactorTracker",
    "Factors",
    "Printer",
    "Response",
]


class ConnectionLost(PrinterConnectionError):
    """The connection to the printer (or the printer to its host) went away."""


class CommandRejected(PrinterConnectionError):
    """The printer host or firmware refused a command (the reply is in the message)."""


@dataclass(frozen=True)
class Response:
    """What the printer said to one command.

    Attributes
    ----------
    gcode
        The command as sent (without line number and checksum).
    ok
        True when the firmware acknowledged it (``ok`` / HTTP result ``"ok"``).
    lines
        Other lines the firmware printed in reply (``echo:E0 Flow: 95%`` ...).
    latency_s
        Wall-clock seconds from sending to the acknowledgement.
    """

    gcode: str
    ok: bool
    lines: tuple[str, ...] = ()
    latency_s: float = 0.0

    def text(self) -> str:
        """One-line summary for logs: ``ok`` plus the reply lines."""
        parts = (["ok"] if self.ok else ["no ack"]) + list(self.lines)
        return " | ".join(parts)


@dataclass(frozen=True)
class Factors:
    """Speed and flow multipliers in percent, and where they were read.

    ``source`` is ``"printer"`` when the firmware or host reported them, ``"commanded"``
    when the connection cannot read them back (OctoPrint's virtual printer, Klipper behind
    OctoPrint) and they are the last acknowledged commands.
    """

    speed_pct: float
    flow_pct: float
    source: str = "printer"

    def get(self, channel: Channel) -> float:
        """The multiplier of ``channel`` in percent."""
        return self.speed_pct if channel is Channel.SPEED else self.flow_pct


@runtime_checkable
class Printer(Protocol):
    """A printer connection (OctoPrint, Moonraker, serial or the twin).

    Every method that talks to the printer raises
    :class:`~flowtwin.errors.PrinterConnectionError` (:class:`ConnectionLost`,
    :class:`CommandRejected`) rather than returning a silently wrong value.
    """

    firmware: Firmware
    #: Human-readable target (``octoprint://127.0.0.1:5000``), never containing a secret.
    description: str

    def connect(self) -> None:
        """Open (or re-open after a loss) the connection; ready to take commands."""
        ...

    def check(self) -> None:
        """Raise :class:`ConnectionLost` if the connection is known to be gone (no I/O)."""
        ...

    def send_gcode(self, line: str) -> Response:
        """Send one command and wait for its acknowledgement."""
        ...

    def set_speed_factor(self, pct: float) -> Response:
        """Set the speed multiplier (``M220``) to ``pct`` percent."""
        ...

    def set_flow_factor(self, pct: float) -> Response:
        """Set the flow multiplier (``M221``) to ``pct`` percent."""
        ...

    def read_factors(self) -> Factors:
        """The multipliers now in force (see :class:`Factors` for ``source``)."""
        ...

    def close(self) -> None:
        """Close the connection (never disconnects a host from its printer)."""
        ...


@dataclass
class FactorTracker:
    """Encode multiplier commands for a firmware and remember the acknowledged values.

    Shared by the connections: ``set(channel, pct, send)`` encodes, sends through
    ``send`` and, when acknowledged, records the value the firmware applies.
    """

    firmware: Firmware
    speed_pct: float = 100.0
    flow_pct: float = 100.0

    def __post_init__(self) -> None:
        check_factor_commands(self.firmware)

    def set(self, channel: Channel, pct: float, send: SendFn) -> Response:
        """Send the encoded command for ``channel``; record it if acknowledged."""
        gcode = encode_factor(self.firmware, channel, pct)
        response = send(gcode)
        if response.ok:
            self.record(channel, applied_percent(self.firmware, pct))
        return response

    def record(self, channel: Channel, pct: float) -> None:
        """Remember that ``channel`` is now ``pct`` percent."""
        if channel is Channel.SPEED:
            self.speed_pct = pct
        else:
            self.flow_pct = pct

    def reset(self) -> None:
        """Forget the values (a firmware restart sets both to 100 %)."""
        self.speed_pct = 100.0
        self.flow_pct = 100.0

    def factors(self) -> Factors:
        """The last acknowledged values, marked ``source="commanded"``."""
        return Factors(self.speed_pct, self.flow_pct, "commanded")


class SendFn(Protocol):
    def __call__(self, line: str, /) -> Response: ...
