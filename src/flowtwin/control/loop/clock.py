"""Clocks for the control loop: real time, accelerated time and simulated time.

The loop, the twin printer and the synthetic measurement source all read time from one
:class:`Clock`, so the same code runs against a real printer in real time, against the twin
``speedup`` times faster than real time, or instantly in tests (:class:`SimClock`, whose
``sleep`` advances the time without waiting).
"""

from __future__ import annotations

import math
import threading
import time
from typing import Protocol, runtime_checkable

from flowtwin.errors import FlowtwinError

__all__ = ["AcceleratedClock", "Clock", "RealClock", "SimClock"]


@runtime_checkable
class Clock(Protocol):
    """Source of time in seconds (monotonic) and a way to wait."""

    def now(self) -> float:
        """Current time in s (monotonic; the origin is arbitrary)."""
        ...

    def sleep(self, dt_s: float) -> None:
        """Wait ``dt_s`` seconds of this clock's time (no-op for ``dt_s <= 0``)."""
        ...


class RealClock:
    """Wall-clock time (``time.monotonic``)."""

    def now(self) -> float:
        """Current monotonic time in s."""
        return time.monotonic()

    def sleep(self, dt_s: float) -> None:
        """Sleep ``dt_s`` real seconds."""
        if dt_s > 0:
            time.sleep(dt_s)


class AcceleratedClock:
    """Time that runs ``speedup`` times faster than the wall clock.

    ``now()`` = ``speedup`` × elapsed wall time; ``sleep(dt)`` waits ``dt/speedup`` real s.

    Parameters
    ----------
    speedup
        Ratio of clock time to wall time (> 0; 1 is real time).
    """

    def __init__(self, speedup: float) -> None:
        if not math.isfinite(speedup) or speedup <= 0:
            raise FlowtwinError("speed-up must be a positive number", field="speedup",
                                value=speedup, allowed="> 0")
        self.speedup = float(speedup)
        self._t0 = time.monotonic()

    def now(self) -> float:
        """Accelerated time in s since the clock was made."""
        return (time.monotonic() - self._t0) * self.speedup

    def sleep(self, dt_s: float) -> None:
        """Wait ``dt_s`` accelerated seconds."""
        if dt_s > 0:
            time.sleep(dt_s / self.speedup)


class SimClock:
    """Simulated time: ``sleep`` advances the time immediately (infinitely accelerated).

    Thread-safe, so a measurement source and the loop may share it.

    Parameters
    ----------
    start_s
        Initial time in s.
    """

    def __init__(self, start_s: float = 0.0) -> None:
        self._t = float(start_s)
        self._lock = threading.Lock()

    def now(self) -> float:
        """Current simulated time in s."""
        with self._lock:
            return self._t

    def sleep(self, dt_s: float) -> None:
        """Advance the time by ``dt_s`` (no-op for ``dt_s <= 0``)."""
        if dt_s > 0:
            with self._lock:
                self._t += dt_s

    def advance(self, dt_s: float) -> None:
        """Same as :meth:`sleep` (reads better in tests)."""
        self.sleep(dt_s)
