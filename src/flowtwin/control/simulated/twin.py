"""The twin as a simulated printer: takes G-code, applies multipliers as the firmware would.

:class:`TwinPrinter` implements :class:`~flowtwin.control.printer.Printer` on a
:class:`~flowtwin.control.loop.clock.Clock`, in real or accelerated time. It interprets the
multiplier commands with the semantics of the chosen firmware (Marlin: integer ``S``,
bare ``M221`` reports ``echo:E0 Flow: N%``; Klipper: float ``S``, bare ``M221`` resets to
100 %, ``M900`` unknown), and applies a new multiplier to the extrusion only after
``effect_delay_s`` — the time the moves already in the planner queue take to run, since a
multiplier acts on moves queued after it. It records every command it received.

It can lose its connection on purpose (:meth:`drop_connection`) so the supervisor's
recovery path can be exercised.

Given a print job (:class:`~flowtwin.control.simulated.runner.JobRunner`), the twin also prints:
every call first advances the job to the clock's time with the multipliers that acted
meanwhile, so the extrusion — and the slip — follow the machine's physics at the current
temperature and the commanded speed and flow (``M220`` lowers the gear speed, hence the
feed force, hence the slip [003 §2.3]). A lost connection does not stop the print.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass, field

from flowtwin.control.loop.clock import Clock
from flowtwin.control.printer import (
    CommandRejected,
    ConnectionLost,
    Factors,
    FactorTracker,
    Response,
)
from flowtwin.control.simulated.runner import JobRunner
from flowtwin.errors import GcodeError
from flowtwin.firmware import Channel, Firmware, check_command, read_factor_command
from flowtwin.gcode.words import parse_line

__all__ = ["TwinPrinter"]


@dataclass
class _Schedule:
    """Piecewise-constant multiplier history: value[i] holds from time[i] on."""

    times_s: list[float] = field(default_factory=lambda: [float("-inf")])
    values_pct: list[float] = field(default_factory=lambda: [100.0])

    def set(self, t_s: float, pct: float) -> None:
        # A new command supersedes any pending one that would take effect later.
        i = bisect.bisect_right(self.times_s, t_s)
        del self.times_s[i:], self.values_pct[i:]
        self.times_s.append(t_s)
        self.values_pct.append(pct)

    def at(self, t_s: float) -> float:
        return self.values_pct[bisect.bisect_right(self.times_s, t_s) - 1]


class TwinPrinter:
    """Simulated printer with firmware-faithful multiplier commands.

    Parameters
    ----------
    clock
        Time source (real, accelerated or simulated).
    firmware
        Semantics to apply to ``M220``/``M221``.
    effect_delay_s
        Delay from acknowledging a multiplier to it acting on the extrusion (s, >= 0).
    reset_on_connect
        Whether (re)connecting resets both multipliers to 100 % (a Marlin board resets
        when the serial port opens; a Klipper host keeps its state).
    job
        A print job the twin prints physically (None: multipliers only).
    """

    def __init__(self, clock: Clock, *, firmware: Firmware = Firmware.MARLIN,
                 effect_delay_s: float = 0.0, reset_on_connect: bool = True,
                 job: JobRunner | None = None) -> None:
        if not effect_delay_s >= 0:
            raise ValueError(f"effect_delay_s must be >= 0, got {effect_delay_s!r}")
        self.clock = clock
        self.firmware = firmware
        self.effect_delay_s = float(effect_delay_s)
        self.reset_on_connect = reset_on_connect
        self.description = f"twin ({firmware})"
        #: Every command received, as ``(time_s, gcode)``.
        self.received: list[tuple[float, str]] = []
        self.connects = 0
        #: Connection attempts still to refuse (a host that is down for a while).
        self.refuse_connects = 0
        self._connected = False
        self._tracker = FactorTracker(firmware)
        self._schedules = {Channel.SPEED: _Schedule(), Channel.FLOW: _Schedule()}
        self._speed_pct = 100.0
        self._flow_pct = 100.0
        self.job = job

    # -- the print job ----------------------------------------------------------------
    def sync(self) -> None:
        """Advance the print job (if any) to the clock's current time."""
        if self.job is not None:
            self.job.advance_to(self.clock.now(), self.factors_at)

    @property
    def job_done(self) -> bool:
        """True when a print job has finished (False without a job)."""
        self.sync()
        return self.job is not None and self.job.done

    # -- connection -----------------------------------------------------------------
    def connect(self) -> None:
        """Open the (simulated) connection (refused while ``refuse_connects`` > 0)."""
        if self.refuse_connects > 0:
            self.refuse_connects -= 1
            raise ConnectionLost("twin printer refused the connection",
                                 source=self.description)
        self.sync()
        if self.reset_on_connect:
            self._apply(Channel.SPEED, 100.0)
            self._apply(Channel.FLOW, 100.0)
        self._connected = True
        self.connects += 1

    def check(self) -> None:
        """Raise :class:`ConnectionLost` after :meth:`drop_connection`."""
        if not self._connected:
            raise ConnectionLost("twin printer connection lost", source=self.description)

    def drop_connection(self) -> None:
        """Simulate a lost connection (cable pulled); :meth:`connect` restores it."""
        self._connected = False

    def close(self) -> None:
        """Close the connection."""
        self._connected = False

    # -- commands -------------------------------------------------------------------
    def send_gcode(self, line: str) -> Response:
        """Send one command (refused like on a real connection, see ``check_command``)."""
        return self.execute(check_command(self.firmware, line))

    def execute(self, line: str) -> Response:
        """What the firmware does with ``line``, unguarded (a bare Klipper M221 resets)."""
        self.check()
        self.sync()
        text = line.strip()
        self.received.append((self.clock.now(), text))
        try:
            parsed = parse_line(text)
        except GcodeError:
            return Response(text, True)  # not a command the twin acts on
        command = read_factor_command(parsed)
        if command is None:
            if self.firmware is Firmware.KLIPPER and parsed.code == "M900":
                return Response(text, True, ('// Unknown command:"M900"',))
            return Response(text, True)
        channel, s_pct = command
        if self.firmware is Firmware.MARLIN:
            if s_pct is None:
                return Response(text, True, (self._report(channel),))
            self._apply(channel, float(int(s_pct)))  # strtol: "S95.7" -> 95
            return Response(text, True)
        value = 100.0 if s_pct is None else s_pct  # bare M221 resets on Klipper
        if value <= 0:
            raise CommandRejected(f"Error on '{text}': S must be above 0.0",
                                  source=self.description)
        self._apply(channel, value)
        return Response(text, True)

    def set_speed_factor(self, pct: float) -> Response:
        """Set the speed multiplier (``M220``)."""
        return self._tracker.set(Channel.SPEED, pct, self.send_gcode)

    def set_flow_factor(self, pct: float) -> Response:
        """Set the flow multiplier (``M221``)."""
        return self._tracker.set(Channel.FLOW, pct, self.send_gcode)

    def read_factors(self) -> Factors:
        """The multipliers the firmware holds now (reported by the twin itself)."""
        self.check()
        self.sync()
        return Factors(self._speed_pct, self._flow_pct, "printer")

    def held_factors(self) -> Factors:
        """What the (simulated) board holds, readable without a connection (for tests)."""
        return Factors(self._speed_pct, self._flow_pct, "printer")

    def factors_at(self, t_s: float) -> Factors:
        """Multipliers acting on the extrusion at ``t_s`` (after ``effect_delay_s``)."""
        return Factors(self._schedules[Channel.SPEED].at(t_s),
                       self._schedules[Channel.FLOW].at(t_s), "printer")

    # -- internals ------------------------------------------------------------------
    def _apply(self, channel: Channel, pct: float) -> None:
        if channel is Channel.SPEED:
            self._speed_pct = pct
        else:
            self._flow_pct = pct
        self._schedules[channel].set(self.clock.now() + self.effect_delay_s, pct)

    def _report(self, channel: Channel) -> str:
        if channel is Channel.SPEED:
            return f"FR:{int(self._speed_pct)}%"
        return f"echo:E0 Flow: {int(self._flow_pct)}%"
