"""Where the loop's slip measurements come from: one small interface, and a synthetic source.

A :class:`MeasurementSource` is polled by the supervisor once per loop tick. ``read()``
returns the newest measurement not yet returned (or None when nothing new arrived) and
must not block; a source whose camera or file is gone raises :class:`MeasurementLost`.
The camera and video sources (:mod:`flowtwin.control.loop.video`) and the twin's camera
(:mod:`flowtwin.control.simulated.camera`) implement the same interface on top of
:mod:`flowtwin.vision`.

:class:`SyntheticSlipSource` produces a slip signal for exercising the loop without a
camera: a three-phase profile after Greeff & Schilling's print test (low slip, high slip,
low slip, as at 230/190/230 °C [003 §3.3, Fig. 11]) with seeded Gaussian noise, reduced
when the loop lowers the speed. It is **synthetic**, not the twin's physics: the coupling
``s = s_base(t) × (speed/100 × flow/100)^gain`` only mimics the observed trend that slip
falls with feed rate [003 §3.1, Fig. 6].
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from flowtwin.control.loop.clock import Clock
from flowtwin.control.printer import Factors
from flowtwin.errors import ProfileError, VisionError

__all__ = [
    "Measurement",
    "MeasurementLost",
    "MeasurementSource",
    "SyntheticSlipSource",
    "greeff_profile",
]


class MeasurementLost(VisionError):
    """The measurement source is gone (camera unplugged, video ended, device error)."""


@dataclass(frozen=True)
class Measurement:
    """One slip measurement.

    Attributes
    ----------
    t_s
        Clock time the measurement refers to (s, same clock as the loop).
    slip
        Drive slip as a fraction (0.1 = 10 %).
    filament_speed_mm_s
        Measured filament speed (mm/s), if known.
    valid
        False when the source produced a frame but no usable measurement.
    idle
        The source works but the gear is at rest (a heater wait, a pause): slip is
        undefined, which is not a fault — the supervisor holds the multiplier and its
        watchdog counts the source as alive. ``valid`` is False.
    gear_speed_mm_s
        Measured gear surface speed (mm/s), if known.
    """

    t_s: float
    slip: float
    filament_speed_mm_s: float | None = None
    valid: bool = True
    idle: bool = False
    gear_speed_mm_s: float | None = None


@runtime_checkable
class MeasurementSource(Protocol):
    """Something that yields slip measurements (camera, video, synthetic, twin)."""

    def read(self) -> Measurement | None:
        """The newest measurement not returned before, or None; never blocks."""
        ...

    def close(self) -> None:
        """Release the device."""
        ...


def greeff_profile(t_s: float, duration_s: float, *, low: float = 0.05,
                   high: float = 0.20) -> float:
    """Base slip of the synthetic signal: ``low`` / ``high`` / ``low`` in thirds.

    The thirds stand for the 230/190/230 °C layer sets of Greeff's print test; 5 % and 20 %
    are of the order seen at 2 mm/s [003 Figs. 6, 11].
    """
    third = duration_s / 3.0
    return high if third <= t_s < 2.0 * third else low


class SyntheticSlipSource:
    """Synthetic slip at a fixed rate, coupled to the multipliers in force.

    Parameters
    ----------
    clock
        The loop's clock.
    duration_s
        Length of the three-phase profile (s).
    rate_hz
        Measurements per second (the paper's camera ran at 14.3 fps [003 §2.1]).
    noise
        Standard deviation of the additive Gaussian noise (fraction).
    seed
        Seed of the noise generator.
    factors
        Callable returning the multipliers acting on the extrusion now (e.g. the twin's
        ``factors_at(clock.now())``); None means 100 %.
    gain
        Exponent of the feed-rate coupling.
    stop_after_s
        Produce nothing after this time (simulates a frozen camera → stale data).
    lost_after_s
        Raise :class:`MeasurementLost` after this time (simulates a lost camera).
    """

    def __init__(self, clock: Clock, *, duration_s: float = 60.0, rate_hz: float = 10.0,
                 noise: float = 0.01, seed: int = 0,
                 factors: Callable[[], Factors] | None = None, gain: float = 1.0,
                 stop_after_s: float | None = None, lost_after_s: float | None = None,
                 low: float = 0.05, high: float = 0.20) -> None:
        if not (math.isfinite(rate_hz) and rate_hz > 0):
            raise ProfileError("measurement rate must be positive", field="rate_hz",
                               value=rate_hz, allowed="> 0")
        if not (math.isfinite(duration_s) and duration_s > 0):
            raise ProfileError("duration must be positive", field="duration_s",
                               value=duration_s, allowed="> 0")
        self.clock = clock
        self.duration_s = duration_s
        self.period_s = 1.0 / rate_hz
        self.noise = noise
        self.gain = gain
        self.low, self.high = low, high
        self.stop_after_s = stop_after_s
        self.lost_after_s = lost_after_s
        self._factors = factors
        self._rng = np.random.default_rng(seed)
        self._t0 = clock.now()
        self._last: float | None = None

    def slip_at(self, t_rel_s: float, factors: Factors) -> float:
        """Noise-free slip at ``t_rel_s`` after the start under ``factors``."""
        base = greeff_profile(t_rel_s, self.duration_s, low=self.low, high=self.high)
        feed = (factors.speed_pct / 100.0) * (factors.flow_pct / 100.0)
        return base * feed ** self.gain

    def read(self) -> Measurement | None:
        """A new measurement once per period (the newest one if several are due)."""
        now = self.clock.now()
        t_rel = now - self._t0
        if self.lost_after_s is not None and t_rel >= self.lost_after_s:
            raise MeasurementLost("synthetic camera lost", source="synthetic",
                                  value=round(t_rel, 3))
        if self.stop_after_s is not None and t_rel >= self.stop_after_s:
            return None
        if self._last is not None and now - self._last < self.period_s - 1e-12:
            return None
        self._last = now
        factors = self._factors() if self._factors is not None else Factors(100.0, 100.0)
        s = self.slip_at(t_rel, factors) + float(self._rng.normal(0.0, self.noise))
        return Measurement(now, min(max(s, -0.2), 0.95))

    def close(self) -> None:
        """Nothing to release."""
