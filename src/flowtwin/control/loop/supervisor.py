"""The control loop's supervisor: runs a controller against a printer and keeps it safe.

Safe state = the controlled multiplier at 100 %. The supervisor returns to it, and logs
why, on every way a run can go wrong or end:

=====================  =========================================================
normal end             after ``duration_s`` or when ``stop()`` says so (a print job
                       finished): restore 100 %, read the factors back
crash                  any exception in the loop (controller, source, bug):
                       ``finally`` restores 100 %, logs ``crash``, re-raises
interrupt              Ctrl-C: as a crash, logged ``interrupted``
lost camera            the source raises :class:`MeasurementLost`: 100 %, run ends
stale measurements     watchdog: nothing fresh for ``watchdog_s`` → 100 % and hold
                       (controller reset) until measurements return; an *idle*
                       measurement (the camera sees the gear at rest, e.g. during a
                       heater wait) counts as fresh but is not fed to the controller:
                       the multiplier is held
lost connection        ``ConnectionLost`` from the printer: reconnect every
                       ``reconnect_interval_s`` up to ``reconnect_timeout_s``; on
                       success set 100 % first, reset the controller, resume
rejected command       the host/firmware refused a multiplier: 100 %, run ends
=====================  =========================================================

At the end the multiplier is restored to 100 % — reconnecting once if the connection is
gone — and read back where the printer can report it; ``RunSummary.restored`` says
whether that worked.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from flowtwin.control.loop.clock import Clock
from flowtwin.control.loop.controllers import Controller
from flowtwin.control.loop.log import ControlLog
from flowtwin.control.loop.measurement import MeasurementLost, MeasurementSource
from flowtwin.control.printer import (
    CommandRejected,
    ConnectionLost,
    Factors,
    Printer,
    Response,
)
from flowtwin.errors import FlowtwinError, PrinterConnectionError
from flowtwin.firmware import Channel, applied_percent, encode_factor

__all__ = ["Fault", "FaultKind", "LoopSettings", "RunSummary", "Status", "run_control"]

log = logging.getLogger("flowtwin.control")

SAFE_PCT = 100.0


class FaultKind(StrEnum):
    """Why the loop left normal operation."""

    STALE = "stale"
    CAMERA_LOST = "camera_lost"
    CONNECTION_LOST = "connection_lost"
    COMMAND_REJECTED = "command_rejected"
    RECONNECT_FAILED = "reconnect_failed"
    CRASH = "crash"
    INTERRUPTED = "interrupted"


@dataclass(frozen=True)
class Fault:
    """One fault: loop time (s from the start), kind, and a message."""

    t_s: float
    kind: FaultKind
    detail: str


@dataclass(frozen=True)
class LoopSettings:
    """Timing of the loop.

    Attributes
    ----------
    duration_s
        Run length (s, > 0).
    period_s
        Loop tick (s): one measurement poll and at most one command per tick.
    watchdog_s
        Longest time without a fresh measurement before going to the safe state (s).
    reconnect_interval_s
        Pause between reconnection attempts (s).
    reconnect_timeout_s
        Give up reconnecting after this long (s); the run then ends.
    """

    duration_s: float
    period_s: float = 0.5
    watchdog_s: float = 2.0
    reconnect_interval_s: float = 1.0
    reconnect_timeout_s: float = 30.0

    def __post_init__(self) -> None:
        for name in ("duration_s", "period_s", "watchdog_s", "reconnect_interval_s",
                     "reconnect_timeout_s"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise FlowtwinError("loop timing must be positive", field=name, value=v,
                                    allowed="> 0 s")
        if self.watchdog_s < self.period_s:
            raise FlowtwinError("watchdog shorter than the loop period", field="watchdog_s",
                                value=self.watchdog_s, allowed=f">= period ({self.period_s} s)")


@dataclass(frozen=True)
class Status:
    """Live status handed to the ``on_status`` callback once per tick."""

    t_s: float
    mode: str  # "running", "safe", "reconnecting"
    slip: float | None
    command_pct: float
    samples: int
    faults: int
    last_response: str


@dataclass(frozen=True)
class RunSummary:
    """Outcome of a run (the CLI's ``--json`` object).

    Attributes
    ----------
    samples
        Measurements fed to the controller.
    mean_slip
        Mean measured slip with the loop on (fraction), None without samples.
    multiplier_min_pct, multiplier_max_pct
        Range of the commands acknowledged by the printer (percent).
    commands
        Multiplier commands acknowledged.
    faults
        Faults in order.
    restored
        True when the final 100 % was acknowledged (and read back equal, where readable).
    final_factors
        Factors read at the end (None if they could not be read).
    """

    printer: str
    controller: str
    channel: Channel
    duration_s: float
    samples: int
    mean_slip: float | None
    multiplier_min_pct: float
    multiplier_max_pct: float
    commands: int
    faults: tuple[Fault, ...]
    restored: bool
    final_factors: Factors | None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (slip also in percent)."""
        return {
            "printer": self.printer, "controller": self.controller,
            "channel": str(self.channel), "duration_s": round(self.duration_s, 3),
            "samples": self.samples,
            "mean_slip": self.mean_slip,
            "mean_slip_pct": None if self.mean_slip is None else 100.0 * self.mean_slip,
            "multiplier_min_pct": self.multiplier_min_pct,
            "multiplier_max_pct": self.multiplier_max_pct,
            "commands": self.commands,
            "faults": [{"t_s": round(f.t_s, 3), "kind": str(f.kind), "detail": f.detail}
                       for f in self.faults],
            "fault_kinds": sorted({str(f.kind) for f in self.faults}),
            "restored": self.restored,
            "final_multiplier_restored": self.restored,
            "final_factors": None if self.final_factors is None else {
                "speed_pct": self.final_factors.speed_pct,
                "flow_pct": self.final_factors.flow_pct,
                "source": self.final_factors.source},
        }


@dataclass
class _Run:
    """Mutable bookkeeping of one run (private to :func:`run_control`)."""

    printer: Printer
    channel: Channel
    clock: Clock
    log: ControlLog
    t0: float
    faults: list[Fault] = field(default_factory=list)
    slips: list[float] = field(default_factory=list)
    acked: list[float] = field(default_factory=list)
    last_gcode: str | None = None
    pct: float = SAFE_PCT
    last_response: str = ""

    def t(self) -> float:
        return self.clock.now() - self.t0

    def fault(self, kind: FaultKind, detail: str) -> None:
        f = Fault(self.t(), kind, detail)
        self.faults.append(f)
        log.warning("control fault %s at %.2f s: %s", kind, f.t_s, detail)
        self.log.write(f.t_s, "fault", detail=f"{kind}: {detail}")

    def command(self, pct: float, *, event: str = "command", force: bool = False) -> None:
        gcode = encode_factor(self.printer.firmware, self.channel, pct)
        if gcode == self.last_gcode and not force:
            return
        setter = (self.printer.set_speed_factor if self.channel is Channel.SPEED
                  else self.printer.set_flow_factor)
        resp: Response = setter(pct)
        self.last_response = resp.text()
        self.log.write(self.t(), event, command_pct=pct, gcode=resp.gcode, ack=resp.ok,
                       response=resp.text(), detail=f"latency {resp.latency_s:.3f} s")
        if not resp.ok:
            raise CommandRejected("multiplier not acknowledged", value=resp.gcode)
        self.last_gcode = gcode
        self.pct = applied_percent(self.printer.firmware, pct)
        self.acked.append(self.pct)


def run_control(printer: Printer, source: MeasurementSource, controller: Controller[Any], *,
                clock: Clock, settings: LoopSettings, log_to: ControlLog | None = None,
                on_status: Callable[[Status], None] | None = None,
                stop: Callable[[], bool] | None = None) -> RunSummary:
    """Run ``controller`` on ``printer`` with measurements from ``source``.

    Connects the printer, sets the controlled multiplier to 100 %, then once per
    ``settings.period_s``: polls the source, updates the controller and sends a command
    when its encoding changes. Restores 100 % on every exit path (see module docstring).

    Parameters
    ----------
    printer
        The connection (not yet connected; the supervisor connects and closes it).
    source
        Measurement source (closed at the end).
    controller
        The control law; ``controller.channel`` picks ``M220`` or ``M221``.
    clock
        Time source shared with the source (and the twin).
    settings
        Loop timing.
    log_to
        CSV log to write (an in-memory one is used when None).
    on_status
        Called once per tick with a :class:`Status` (the CLI's live display).
    stop
        Checked once per tick; the run ends normally when it returns True (e.g. the twin
        finished its print job).

    Returns
    -------
    RunSummary
        Samples, mean slip, multiplier range, faults, whether 100 % was restored.

    Raises
    ------
    PrinterConnectionError
        The first connection failed (nothing was changed on the printer).
    Exception
        Whatever crashed the loop, after 100 % was restored and the crash logged.
    """
    run_log = log_to if log_to is not None else ControlLog()
    printer.connect()
    run = _Run(printer, controller.channel, clock, run_log, clock.now())
    run_log.write(0.0, "start", detail=f"{printer.description}; {type(controller).__name__} "
                  f"on {controller.channel} ({controller.channel.mcode})")
    state = controller.initial_state()
    mode = "running"
    samples = 0
    last_fresh = run.t0
    slip_now: float | None = None
    end = run.t0 + settings.duration_s
    restored = False
    final: Factors | None = None
    try:
        run.command(SAFE_PCT, event="safe", force=True)
        next_tick = clock.now()
        while clock.now() < end:
            if stop is not None and stop():
                run.log.write(run.t(), "done", detail="stop condition met")
                break
            try:
                printer.check()
                try:
                    m = source.read()
                except MeasurementLost as exc:
                    run.fault(FaultKind.CAMERA_LOST, exc.message)
                    run.command(SAFE_PCT, event="safe")
                    break
                now = clock.now()
                fresh = (m is not None and m.valid and math.isfinite(m.slip)
                         and now - m.t_s <= settings.watchdog_s)
                if m is not None and m.idle and now - m.t_s <= settings.watchdog_s:
                    # the camera works and sees the gear at rest: hold, no fault
                    if mode == "safe":
                        run.log.write(run.t(), "resume", detail="source alive (idle)")
                        mode = "running"
                    last_fresh = now
                    slip_now = None
                    run.log.write(m.t_s - run.t0, "idle", measurement_age_s=now - m.t_s,
                                  command_pct=run.pct, detail="gear at rest")
                elif fresh and m is not None:
                    if mode == "safe":
                        run.log.write(run.t(), "resume", detail="fresh measurements again")
                        mode = "running"
                    last_fresh = now
                    slip_now = m.slip
                    run.slips.append(m.slip)
                    samples += 1
                    state, pct = controller.update(state, m.t_s, m.slip)
                    run.log.write(m.t_s - run.t0, "sample", slip=m.slip,
                                  measurement_age_s=now - m.t_s, command_pct=pct)
                    run.command(pct)
                elif mode == "running" and now - last_fresh > settings.watchdog_s:
                    run.fault(FaultKind.STALE, f"no fresh measurement for "
                              f"{now - last_fresh:.2f} s (watchdog {settings.watchdog_s} s)")
                    mode = "safe"
                    state = controller.initial_state()
                    slip_now = None
                    run.command(SAFE_PCT, event="safe")
            except ConnectionLost as exc:
                run.fault(FaultKind.CONNECTION_LOST, exc.message)
                if on_status is not None:
                    on_status(Status(run.t(), "reconnecting", None, run.pct, samples,
                                     len(run.faults), run.last_response))
                if not _reconnect(run, settings, end):
                    break
                state = controller.initial_state()
                last_fresh = next_tick = clock.now()
                mode = "running"
                continue
            except CommandRejected as exc:
                run.fault(FaultKind.COMMAND_REJECTED, exc.message)
                break
            if on_status is not None:
                on_status(Status(run.t(), mode, slip_now, run.pct, samples, len(run.faults),
                                 run.last_response))
            next_tick += settings.period_s
            clock.sleep(next_tick - clock.now())
    except KeyboardInterrupt:
        run.fault(FaultKind.INTERRUPTED, "interrupted")
        raise
    except BaseException as exc:
        run.fault(FaultKind.CRASH, f"{type(exc).__name__}: {exc}")
        raise
    finally:
        restored, final = _restore(run)
        printer.close()
        source.close()
        run_log.write(run.t(), "end", detail=f"restored={restored}")
    return RunSummary(
        printer=printer.description, controller=type(controller).__name__,
        channel=controller.channel, duration_s=run.t(), samples=samples,
        mean_slip=(sum(run.slips) / len(run.slips)) if run.slips else None,
        multiplier_min_pct=min(run.acked), multiplier_max_pct=max(run.acked),
        commands=len(run.acked), faults=tuple(run.faults), restored=restored,
        final_factors=final)


def _reconnect(run: _Run, settings: LoopSettings, end: float) -> bool:
    """Reconnect until success, ``reconnect_timeout_s`` or the end of the run."""
    give_up = min(run.clock.now() + settings.reconnect_timeout_s, end)
    attempt = 0
    while True:
        attempt += 1
        try:
            run.printer.connect()
            run.last_gcode = None  # the printer's state is unknown after a reconnect
            run.command(SAFE_PCT, event="safe", force=True)
        except PrinterConnectionError as exc:
            if run.clock.now() + settings.reconnect_interval_s > give_up:
                run.fault(FaultKind.RECONNECT_FAILED,
                          f"gave up after {attempt} attempts: {exc.message}")
                return False
            run.clock.sleep(settings.reconnect_interval_s)
            continue
        run.log.write(run.t(), "recovered", detail=f"reconnected after {attempt} attempt(s)")
        log.info("control: reconnected to %s after %d attempt(s)", run.printer.description,
                 attempt)
        return True


def _restore(run: _Run) -> tuple[bool, Factors | None]:
    """Set 100 % at the end (reconnecting once if needed); read back the factors."""
    for attempt in (1, 2):
        try:
            if attempt == 2:
                run.printer.connect()
            run.command(SAFE_PCT, event="restore", force=True)
            final = run.printer.read_factors()
        except PrinterConnectionError as exc:
            run.log.write(run.t(), "restore_failed", detail=f"attempt {attempt}: {exc.message}")
            log.error("control: could not restore 100 %% on %s (attempt %d): %s",
                      run.printer.description, attempt, exc.message)
            continue
        ok = math.isclose(final.get(run.channel), SAFE_PCT, abs_tol=1e-6)
        run.log.write(run.t(), "read", speed_pct=final.speed_pct, flow_pct=final.flow_pct,
                      detail=f"factors read back ({final.source})")
        log.info("control: %s restored to 100 %% on %s (read back %s %.3f %%, %s)",
                 run.channel.mcode, run.printer.description, run.channel,
                 final.get(run.channel), final.source)
        return ok, final
    return False, None
