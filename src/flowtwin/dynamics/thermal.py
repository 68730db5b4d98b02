"""Nozzle temperature over the print from M104/M109, with an optional first-order heater lag.

Viscosity — hence the lag factor ``K`` and the feed force — depends on temperature
(``μ(T) = μ0·exp(−b·T)`` [002]). The nozzle follows its set point ``T_set`` as a
first-order system with time constant ``τ`` (``heater_tau_s``; 0 = instantaneous)::

    dT/dt = (T_set − T)/τ   →   T(t) = T_set + (T_i − T_set)·exp(−(t − t_i)/τ)

* ``M104 S<T>`` (and Klipper's ``SET_HEATER_TEMPERATURE HEATER=extruder TARGET=``) changes
  the set point; the nozzle approaches it with the lag.
* ``M109 S<T>`` / ``M109 R<T>`` change the set point and wait: the planner's timeline does
  not contain the wait, so the nozzle is taken to be at the set point when the next move
  starts.
* ``T<n>`` addresses that tool's heater (ignored unless it is the tool asked for); a
  command without ``T`` addresses the active extruder, taken to be the one simulated.
  ``S0`` switches the heater off (set point = ``ambient_c``).

A command takes effect at the start of the move that follows it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.errors import ProfileError
from flowtwin.gcode.moves import MoveTable
from flowtwin.planner.timeline import Timeline

__all__ = ["TemperatureSchedule", "move_temperatures", "temperature_schedule"]


@dataclass(frozen=True, slots=True)
class TemperatureSchedule:
    """Piecewise first-order nozzle temperature.

    Attributes
    ----------
    t_s
        Times of set-point changes, s, shape ``(m,)`` (first entry: start of the print).
    set_c
        Set point from each time on, °C, shape ``(m,)``.
    start_c
        Nozzle temperature at each change, °C, shape ``(m,)``.
    tau_s
        Heater time constant, s (0: the nozzle follows the set point at once).
    """

    t_s: npt.NDArray[np.float64]
    set_c: npt.NDArray[np.float64]
    start_c: npt.NDArray[np.float64]
    tau_s: float

    def at(self, t_s: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Nozzle temperature at times ``t_s``, °C (same shape as ``t_s``)."""
        t = np.asarray(t_s, dtype=np.float64)
        return self._at(t, self._index(t))

    def _index(self, t: npt.NDArray[np.float64]) -> npt.NDArray[np.intp]:
        """Index of the set point in force at each time."""
        return np.clip(np.searchsorted(self.t_s, t, side="right") - 1, 0,
                       self.t_s.shape[0] - 1)

    def _at(self, t: npt.NDArray[np.float64], i: npt.NDArray[np.intp]
            ) -> npt.NDArray[np.float64]:
        if self.tau_s == 0.0:
            return self.set_c[i]
        dt = np.maximum(t - self.t_s[i], 0.0)
        return self.set_c[i] + (self.start_c[i] - self.set_c[i]) * np.exp(-dt / self.tau_s)

    def mean(self, t0_s: npt.ArrayLike, t1_s: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Mean temperature over ``[t0, t1]`` (exact), °C; ``T(t0)`` where ``t1 <= t0``.

        The intervals must not contain a set-point change (moves never do: commands act
        between moves).
        """
        a = np.asarray(t0_s, dtype=np.float64)
        b = np.asarray(t1_s, dtype=np.float64)
        i = self._index(a)
        start = self._at(a, i)
        if self.tau_s == 0.0:
            return start
        dur = b - a
        setp = self.set_c[i]
        frac = np.ones_like(dur)
        pos = dur > 0.0
        z = dur[pos] / self.tau_s
        frac[pos] = -np.expm1(-z) / z
        return setp + (start - setp) * frac


def _as_float(val: object) -> float | None:
    if isinstance(val, bool) or not isinstance(val, (int, float)):
        return None
    return float(val)


def temperature_schedule(moves: MoveTable, timeline: Timeline, *, initial_c: float,
                         heater_tau_s: float = 0.0, tool: int | None = None,
                         ambient_c: float = 25.0) -> TemperatureSchedule:
    """Nozzle temperature schedule of a planned print.

    Parameters
    ----------
    moves
        Move table (its events carry M104/M109).
    timeline
        Planner output aligned with ``moves``.
    initial_c
        Nozzle temperature before the first command, °C.
    heater_tau_s
        First-order heater time constant, s (``>= 0``; 0: no lag).
    tool
        Heater of this tool (``None``: tool 0 / the only one).
    ambient_c
        Temperature a switched-off heater tends to, °C.

    Returns
    -------
    TemperatureSchedule

    Raises
    ------
    ProfileError
        Negative time constant.
    """
    if not (heater_tau_s >= 0.0 and np.isfinite(heater_tau_s)):
        raise ProfileError("heater time constant must be >= 0", field="heater_tau_s",
                           value=heater_tau_s, allowed=">= 0 s")
    want = 0 if tool is None else tool
    ts = np.asarray(timeline.phases["t_start"], dtype=np.float64)
    last = timeline.phases[-1:]  # (the end of the print: the last move's duration only)
    dur = np.asarray(last["accel_t"] + last["cruise_t"] + last["decel_t"], dtype=np.float64)
    t_end = float(ts[-1] + dur[-1]) if ts.shape[0] else 0.0
    times = [float(ts[0]) if ts.shape[0] else 0.0]
    sets = [float(initial_c)]
    starts = [float(initial_c)]
    for ev in moves.events:
        target: float | None = None
        wait = False
        if ev.code in ("M104", "M109"):
            t_sel = _as_float(ev.params.get("T"))
            if t_sel is not None and int(t_sel) != want:
                continue
            for key in ("S", "R"):
                target = _as_float(ev.params.get(key))
                if target is not None:
                    break
            wait = ev.code == "M109"
        elif ev.code == "SET_HEATER_TEMPERATURE":
            name = str(ev.params.get("HEATER", ""))
            if name != ("extruder" if want == 0 else f"extruder{want}"):
                continue
            target = _as_float(ev.params.get("TARGET"))
        if target is None:
            continue
        setp = ambient_c if target <= 0.0 else target
        t_ev = float(ts[ev.move_index]) if ev.move_index < ts.shape[0] else t_end
        if wait or heater_tau_s == 0.0:
            now = setp  # M109 waited for it (the wait is not on the timeline)
        else:  # temperature reached at the event under the previous set point
            lapse = max(t_ev - times[-1], 0.0)
            now = sets[-1] + (starts[-1] - sets[-1]) * float(np.exp(-lapse / heater_tau_s))
        times.append(t_ev)
        sets.append(setp)
        starts.append(now)
    return TemperatureSchedule(np.asarray(times), np.asarray(sets), np.asarray(starts),
                               float(heater_tau_s))


def move_temperatures(moves: MoveTable, timeline: Timeline, *, initial_c: float,
                      heater_tau_s: float = 0.0, tool: int | None = None,
                      ambient_c: float = 25.0) -> npt.NDArray[np.float64]:
    """Mean nozzle temperature during every move, °C, shape ``(n_moves,)``.

    Parameters are those of :func:`temperature_schedule`.
    """
    sched = temperature_schedule(moves, timeline, initial_c=initial_c,
                                 heater_tau_s=heater_tau_s, tool=tool, ambient_c=ambient_c)
    ts = np.asarray(timeline.phases["t_start"], dtype=np.float64)
    if sched.tau_s == 0.0:
        return sched.at(ts)  # the set point all through each move: no durations needed
    dur = np.asarray(timeline.phases["accel_t"] + timeline.phases["cruise_t"]
                     + timeline.phases["decel_t"], dtype=np.float64)
    return sched.mean(ts, ts + dur)
