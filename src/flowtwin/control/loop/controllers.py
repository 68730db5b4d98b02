"""Slip controllers: pure objects with explicit state, limits and rate limits.

Every controller maps (time, measured slip) to a multiplier command in percent through
``update(state, t_s, slip) -> (new_state, pct)``; the state is an immutable value, so a
controller can be replayed, tested step by step and reset by taking ``initial_state()``.
Slip is a fraction (docs/spec.md §2: 0.10 = 10 %).

* :class:`GreeffController` — Greeff & Schilling's proof-of-concept loop [003 §2.3]:
  "the measured slippage in percentage, if more than a threshold, is averaged over time and
  used directly as the flow and feed rate multiplier", so that "slippage is reduced by
  decreasing the extruder speed". Here: samples at or below the threshold count as zero
  slip, the mean over a time window is taken, and the speed multiplier is
  ``100 % × (1 − mean slip)`` (10 % slip → ``M220 S90``).
* :class:`FeedForwardController` — cancels the slip with the flow multiplier:
  delivered filament is ``(1 − s) × m`` of the G-code's, so ``m = 100 % / (1 − s̄)``
  (beyond the seeds; ``s̄`` measured or predicted by the twin).
* :class:`PIController` — PI with conditional-integration anti-windup, either on the speed
  channel (holds the slip at a set point) or the flow channel (holds the delivered fraction
  ``(1 − s) m`` at 1).
* :class:`OpenLoopController` — the loop turned off: always 100 %, so a run measures the
  slip without acting ([003 §3.3] printed its test part with the control on and off).

All outputs pass :func:`limit_command`: clamped to ``[min_pct, max_pct]`` (default
50–150 %) and rate-limited to ``max_rate_pct_s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Protocol, TypeVar

from flowtwin.errors import ProfileError
from flowtwin.firmware import Channel

__all__ = [
    "Controller",
    "FeedForwardController",
    "GreeffController",
    "Limits",
    "OpenLoopController",
    "PIController",
    "PIState",
    "WindowState",
    "limit_command",
    "make_controller",
    "window_mean",
]

S = TypeVar("S")


@dataclass(frozen=True)
class Limits:
    """Bounds of a multiplier command.

    Attributes
    ----------
    min_pct, max_pct
        Allowed range in percent; must contain 100 (the safe state).
    max_rate_pct_s
        Largest change per second (percent/s, > 0).
    """

    min_pct: float = 50.0
    max_pct: float = 150.0
    max_rate_pct_s: float = 20.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.min_pct) and math.isfinite(self.max_pct)
                and 1.0 <= self.min_pct <= 100.0 <= self.max_pct <= 999.0):
            raise ProfileError("multiplier limits must contain 100 %", field="limits",
                               value=(self.min_pct, self.max_pct),
                               allowed="1 <= min_pct <= 100 <= max_pct <= 999")
        if not (math.isfinite(self.max_rate_pct_s) and self.max_rate_pct_s > 0):
            raise ProfileError("rate limit must be positive", field="max_rate_pct_s",
                               value=self.max_rate_pct_s, allowed="> 0 %/s")


def limit_command(prev_pct: float, target_pct: float, dt_s: float, limits: Limits) -> float:
    """Clamp ``target_pct`` to the limits and move from ``prev_pct`` at most the rate limit.

    Parameters
    ----------
    prev_pct
        The multiplier in force (percent).
    target_pct
        What the control law asks for (percent; NaN is refused).
    dt_s
        Time since ``prev_pct`` was set (s, >= 0).
    limits
        Range and rate limit.

    Returns
    -------
    float
        ``clip(prev + clip(target − prev, ±rate·dt), min, max)``.
    """
    if not math.isfinite(target_pct):
        raise ValueError(f"controller produced a non-finite command: {target_pct!r}")
    step = limits.max_rate_pct_s * max(dt_s, 0.0)
    moved = prev_pct + min(max(target_pct - prev_pct, -step), step)
    return min(max(moved, limits.min_pct), limits.max_pct)


@dataclass(frozen=True)
class WindowState:
    """State of the averaging controllers: recent ``(t_s, slip)`` samples and the output."""

    samples: tuple[tuple[float, float], ...] = ()
    last_t_s: float | None = None
    pct: float = 100.0


def window_mean(samples: tuple[tuple[float, float], ...], t_s: float,
                window_s: float) -> tuple[tuple[tuple[float, float], ...], float]:
    """Drop samples older than ``t_s − window_s``; return the rest and their mean slip."""
    kept = tuple(s for s in samples if s[0] > t_s - window_s)
    return kept, (sum(v for _, v in kept) / len(kept) if kept else 0.0)


class Controller(Protocol[S]):
    """Pure controller: explicit state in, new state and command out."""

    @property
    def channel(self) -> Channel:
        """The multiplier this controller drives."""
        ...

    @property
    def limits(self) -> Limits:
        """Range and rate limit of its commands."""
        ...

    def initial_state(self) -> S:
        """State at 100 % with no history."""
        ...

    def update(self, state: S, t_s: float, slip: float) -> tuple[S, float]:
        """Advance with a slip measurement (fraction) at ``t_s``; return the command (%)."""
        ...


def _check_slip(slip: float) -> float:
    if not math.isfinite(slip):
        raise ValueError(f"slip must be finite, got {slip!r}")
    return slip


@dataclass(frozen=True)
class GreeffController:
    """Greeff & Schilling's loop: thresholded, time-averaged slip as the speed multiplier.

    [003 §2.3]: slip above ``threshold`` is averaged over ``window_s`` and used directly as
    the multiplier: ``pct = 100 × (1 − mean)``. Samples at or below the threshold count as
    zero, so the multiplier returns to 100 % when the slip goes away.

    Parameters
    ----------
    threshold
        Slip (fraction) below which a sample counts as no slip (default 0.02 = 2 %).
    window_s
        Averaging window (s).
    channel
        ``SPEED`` (``M220``, as in the issue) or ``FLOW``; the paper used one multiplier
        for both.
    limits
        Range and rate limit.
    """

    threshold: float = 0.02
    window_s: float = 5.0
    channel: Channel = Channel.SPEED
    limits: Limits = field(default_factory=Limits)

    def initial_state(self) -> WindowState:
        """Empty window, 100 %."""
        return WindowState()

    def update(self, state: WindowState, t_s: float, slip: float) -> tuple[WindowState, float]:
        """Add a sample; command ``100 × (1 − windowed mean of thresholded slip)``."""
        s = _check_slip(slip)
        s_eff = s if s > self.threshold else 0.0
        kept, mean = window_mean((*state.samples, (t_s, s_eff)), t_s, self.window_s)
        dt = 0.0 if state.last_t_s is None else t_s - state.last_t_s
        pct = limit_command(state.pct, 100.0 * (1.0 - mean), dt, self.limits)
        return WindowState(kept, t_s, pct), pct


@dataclass(frozen=True)
class FeedForwardController:
    """Flow multiplier that cancels the (measured or predicted) mean slip.

    The drive delivers ``(1 − s)`` of the commanded filament [000 Eq. 1], so a flow
    multiplier ``m = 100 % / (1 − s̄)`` restores the G-code's volume when ``s`` does not
    depend on ``m`` (beyond the seeds: slip grows with feed force [000 Eq. 6], so this is a
    first-order correction). ``s̄`` is the mean over ``window_s``; slip is clipped to
    ``[0, max_slip]`` before the division.
    """

    window_s: float = 5.0
    max_slip: float = 0.5
    channel: Channel = Channel.FLOW
    limits: Limits = field(default_factory=Limits)

    def __post_init__(self) -> None:
        if self.channel is not Channel.FLOW:
            raise ProfileError("feed-forward acts on the flow multiplier only",
                               field="channel", value=str(self.channel), allowed="flow")
        if not 0.0 < self.max_slip < 1.0:
            raise ProfileError("max_slip must be a fraction", field="max_slip",
                               value=self.max_slip, allowed="0 < max_slip < 1")

    def initial_state(self) -> WindowState:
        """Empty window, 100 %."""
        return WindowState()

    def update(self, state: WindowState, t_s: float, slip: float) -> tuple[WindowState, float]:
        """Add a sample; command ``100 / (1 − windowed mean slip)``."""
        s = min(max(_check_slip(slip), 0.0), self.max_slip)
        kept, mean = window_mean((*state.samples, (t_s, s)), t_s, self.window_s)
        dt = 0.0 if state.last_t_s is None else t_s - state.last_t_s
        pct = limit_command(state.pct, 100.0 / (1.0 - mean), dt, self.limits)
        return WindowState(kept, t_s, pct), pct


@dataclass(frozen=True)
class PIState:
    """PI state: integral term (percent), time of the last update, last command (%)."""

    integral_pct: float = 0.0
    last_t_s: float | None = None
    pct: float = 100.0


@dataclass(frozen=True)
class PIController:
    """PI controller with anti-windup.

    Error (dimensionless) per channel:

    * ``SPEED``: ``e = s − setpoint`` (too much slip → positive → lower speed);
      ``u = 100 − 100·kp·e − I``, ``dI/dt = 100·ki·e``.
    * ``FLOW``: ``e = 1 − (1 − s)·m/100`` with ``m`` the flow multiplier in force
      (under-delivery → positive → more flow); ``u = 100 + 100·kp·e + I``,
      ``dI/dt = 100·ki·e``. At rest ``e = 0`` and ``I = 100/(1 − s) − 100``.

    Anti-windup by conditional integration: the integral is not advanced while the
    output is held by a limit or the rate limit and the error would push it further, so
    leaving saturation takes one step instead of unwinding an overgrown integral.

    Parameters
    ----------
    kp
        Proportional gain (percent per percent of error / 100).
    ki
        Integral gain (1/s).
    setpoint
        Slip set point for the speed channel (fraction).
    anti_windup
        Turn the anti-windup off only to compare (tests do).
    """

    kp: float = 0.5
    ki: float = 0.5
    setpoint: float = 0.02
    channel: Channel = Channel.SPEED
    limits: Limits = field(default_factory=Limits)
    anti_windup: bool = True

    def __post_init__(self) -> None:
        for name in ("kp", "ki"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ProfileError("PI gain must be >= 0", field=name, value=v,
                                   allowed=">= 0")

    def initial_state(self) -> PIState:
        """Zero integral, 100 %."""
        return PIState()

    def update(self, state: PIState, t_s: float, slip: float) -> tuple[PIState, float]:
        """One PI step with the slip measured at ``t_s``."""
        s = _check_slip(slip)
        dt = 0.0 if state.last_t_s is None else max(t_s - state.last_t_s, 0.0)
        if self.channel is Channel.SPEED:
            e, sign = s - self.setpoint, -1.0
        else:
            e, sign = 1.0 - (1.0 - s) * state.pct / 100.0, 1.0
        integral = state.integral_pct + sign * 100.0 * self.ki * e * dt

        def law(i_pct: float) -> float:
            return 100.0 + sign * 100.0 * self.kp * e + i_pct

        raw = law(integral)
        pct = limit_command(state.pct, raw, dt, self.limits)
        if self.anti_windup and not math.isclose(pct, raw, abs_tol=1e-9):
            # Held by a limit: keep the old integral if integrating pushed further out.
            if (raw > pct and integral > state.integral_pct) or \
                    (raw < pct and integral < state.integral_pct):
                integral = state.integral_pct
        return replace(state, integral_pct=integral, last_t_s=t_s, pct=pct), pct


@dataclass(frozen=True)
class OpenLoopController:
    """The loop turned off: every update commands 100 % (measurement only)."""

    channel: Channel = Channel.SPEED
    limits: Limits = field(default_factory=Limits)

    def initial_state(self) -> WindowState:
        """No history, 100 %."""
        return WindowState()

    def update(self, state: WindowState, t_s: float, slip: float) -> tuple[WindowState, float]:
        """Ignore the (finite) slip; command 100 %."""
        _check_slip(slip)
        return WindowState((), t_s, 100.0), 100.0


def make_controller(name: str, *, limits: Limits | None = None,
                    channel: Channel | None = None) -> GreeffController | FeedForwardController \
        | PIController | OpenLoopController:
    """Build a controller by name (``greeff``, ``feedforward``, ``pi``, ``off``)."""
    lim = limits or Limits()
    if name == "off":
        return OpenLoopController(channel=channel or Channel.SPEED, limits=lim)
    if name == "greeff":
        return GreeffController(limits=lim, channel=channel or Channel.SPEED)
    if name == "feedforward":
        return FeedForwardController(limits=lim, channel=channel or Channel.FLOW)
    if name == "pi":
        return PIController(limits=lim, channel=channel or Channel.SPEED)
    raise ProfileError("unknown controller", field="controller", value=name,
                       allowed="greeff, feedforward, pi, off")
