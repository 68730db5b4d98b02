"""The twin printer printing a job: program time, heater, extruder physics, history.

:class:`JobRunner` advances a :class:`~flowtwin.control.simulated.job.PrintJob` on the loop's clock
in steps of at most ``step_s``:

* **speed multiplier** (``M220``): program time runs at ``speed/100`` of clock time — the
  firmware scales every move's feed rate, extruder moves included, so the gear turns
  slower by the same factor (accelerations are not rescaled: a small error on short
  moves);
* **flow multiplier** (``M221``): scales every extruder move (Marlin and Klipper apply the
  factor to retractions too);
* **heater**: the nozzle follows its set point as a first-order system
  ``dT/dt = (T_set − T)/τ`` (:mod:`flowtwin.dynamics.thermal`); ``M109 S`` stops program
  time while the nozzle is colder than the set point, ``M109 R`` also while it is hotter
  (by more than ``window_c``);
* **extruder**: the commanded gear surface speed of the step,
  ``v = ΔE(τ)·flow/Δt``, drives the state equation of docs/spec.md §3.4
  (:func:`~flowtwin.control.simulated.extruder.step_extrusion`) with the parameters of the
  machine at the nozzle's temperature and the move's layer height — so slip follows the
  machine's physics: it grows as the nozzle cools and falls when ``M220`` lowers the
  speed, as [003 §2.3, §3.1] observed.

It records the gear speed, filament speed, temperature and multipliers of every step
(what the twin camera films) and totals the filament commanded, fed and deposited.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.control.printer import Factors
from flowtwin.control.simulated.extruder import (
    ExtruderState,
    StepParams,
    step_extrusion,
    step_params,
)
from flowtwin.control.simulated.job import PrintJob, WaitMode
from flowtwin.errors import ProfileError
from flowtwin.profiles.machine import Machine

__all__ = ["DEFAULT_HEATER_TAU_S", "JobHistory", "JobRunner", "JobTotals"]

#: Heater time constant of the twin when the hot-end profile gives none, s. Beyond the
#: seeds: [003] only says the printer waited for each new set point; a first-order nozzle
#: with τ = 15 s takes ~55 s to settle within 1 °C after a 40 °C change.
DEFAULT_HEATER_TAU_S = 15.0
#: Temperature resolution of the parameter cache, °C (viscosity changes ~0.5 % per 0.1 °C).
_T_QUANTUM_C = 0.05


@dataclass(frozen=True)
class JobTotals:
    """Filament totals of a job so far (mm of filament; × area × density gives mass).

    Attributes
    ----------
    commanded_mm
        Net filament the gear surface moved (retractions cancel).
    commanded_forward_mm
        Forward filament the gear surface moved (the denominator of the mean slip).
    fed_mm
        Filament that entered the column.
    out_mm
        Melt out of the nozzle (filament-equivalent).
    part_out_mm
        Melt out from the start of layer 0 on (the printed object).
    grind_s
        Time the drive spent grinding, s.
    wait_s
        Time spent waiting for the heater, s.
    """

    commanded_mm: float
    commanded_forward_mm: float
    fed_mm: float
    out_mm: float
    part_out_mm: float
    grind_s: float
    wait_s: float


@dataclass(frozen=True)
class JobHistory:
    """Per-step record of a job (arrays of shape ``(n_steps,)``; values over each step).

    Attributes
    ----------
    t_s
        Clock time at the end of each step, s.
    dt_s
        Step length, s.
    gear_speed_mm_s
        Gear surface speed ``ω·r`` (commanded filament speed), mm/s.
    filament_speed_mm_s
        Filament speed into the column, mm/s.
    temperature_c
        Nozzle temperature at the start of the step, °C.
    speed_pct, flow_pct
        Multipliers acting during the step, %.
    layer
        Layer of the running move (``-1`` before the first layer or while waiting there).
    """

    t_s: npt.NDArray[np.float64]
    dt_s: npt.NDArray[np.float64]
    gear_speed_mm_s: npt.NDArray[np.float64]
    filament_speed_mm_s: npt.NDArray[np.float64]
    temperature_c: npt.NDArray[np.float64]
    speed_pct: npt.NDArray[np.float64]
    flow_pct: npt.NDArray[np.float64]
    layer: npt.NDArray[np.int64]

    def slip(self) -> npt.NDArray[np.float64]:
        """Slip of each step ``1 − v_fil/v_gear`` [000 Eq. 1]; NaN where the gear does not
        feed forward."""
        g = self.gear_speed_mm_s
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(g > 0.0, 1.0 - self.filament_speed_mm_s / g, np.nan)


class JobRunner:
    """Advances a print job on the loop's clock (see the module docstring).

    Parameters
    ----------
    job
        The planned G-code.
    machine
        The set-up whose physics the twin follows.
    start_s
        Clock time at which the print starts, s.
    heater_tau_s
        Heater time constant, s (default: the hot end's, else
        :data:`DEFAULT_HEATER_TAU_S`).
    initial_temperature_c
        Nozzle temperature at the start, °C (default: the job's first set point, as if
        preheated).
    window_c
        ``M109`` waits until the nozzle is within this of its set point, °C.
    step_s
        Longest integration step, s.
    """

    def __init__(self, job: PrintJob, machine: Machine, *, start_s: float,
                 heater_tau_s: float | None = None,
                 initial_temperature_c: float | None = None, window_c: float = 1.0,
                 step_s: float = 0.01) -> None:
        tau = heater_tau_s if heater_tau_s is not None else (
            machine.hotend.heater_time_constant_s or DEFAULT_HEATER_TAU_S)
        if not (math.isfinite(tau) and tau >= 0.0):
            raise ProfileError("heater time constant must be >= 0", field="heater_tau_s",
                               value=tau, allowed=">= 0 s")
        if not (math.isfinite(step_s) and 0.0 < step_s <= 1.0):
            raise ProfileError("integration step out of range", field="step_s", value=step_s,
                               allowed="0 < step_s <= 1 s")
        if not (math.isfinite(window_c) and window_c > 0.0):
            raise ProfileError("temperature window must be positive", field="window_c",
                               value=window_c, allowed="> 0 °C")
        self.job = job
        self.machine = machine
        self.heater_tau_s = float(tau)
        self.window_c = float(window_c)
        self.step_s = float(step_s)
        first = job.first_set_point_c()
        t_init = initial_temperature_c if initial_temperature_c is not None else (
            first if first is not None else machine.temperature_c)
        self.temperature_c = float(t_init)
        self.set_c = float(t_init)
        self.t_s = float(start_s)
        self.start_s = float(start_s)
        self.tau_s = float(job.feed.t_begin_s) if job.feed.n_segments else 0.0
        self.tau_s = min(self.tau_s, 0.0)
        self.waiting: WaitMode = WaitMode.NONE
        self.state = ExtruderState()
        self._e_now = job.position_mm(self.tau_s)
        self._next_heater = 0
        self._params: dict[tuple[int, float], StepParams] = {}
        self._tot = {"cmd": 0.0, "fwd": 0.0, "fed": 0.0, "out": 0.0, "part": 0.0,
                     "grind": 0.0, "wait": 0.0}
        self._hist: dict[str, list[float]] = {k: [] for k in (
            "t", "dt", "gear", "fil", "temp", "speed", "flow", "layer")}
        self.end_s: float | None = None

    # -- state ------------------------------------------------------------------------
    @property
    def done(self) -> bool:
        """True once the whole G-code has run (program time at its end, no wait)."""
        return self.end_s is not None

    @property
    def area_mm2(self) -> float:
        """Filament cross-section, mm²."""
        return float(self.machine.filament.area_mm2)

    def totals(self) -> JobTotals:
        """Filament totals so far."""
        t = self._tot
        return JobTotals(t["cmd"], t["fwd"], t["fed"], t["out"], t["part"], t["grind"],
                         t["wait"])

    def part_mass_g(self) -> float:
        """Mass of the printed object so far: melt out since layer 0 × density, g."""
        return self._tot["part"] * self.area_mm2 * self.machine.material.density_g_mm3

    def history(self) -> JobHistory:
        """Everything recorded so far."""
        h = self._hist
        return JobHistory(
            t_s=np.asarray(h["t"]), dt_s=np.asarray(h["dt"]),
            gear_speed_mm_s=np.asarray(h["gear"]), filament_speed_mm_s=np.asarray(h["fil"]),
            temperature_c=np.asarray(h["temp"]), speed_pct=np.asarray(h["speed"]),
            flow_pct=np.asarray(h["flow"]), layer=np.asarray(h["layer"], dtype=np.int64))

    def motion(self, t0_s: float, t1_s: float
               ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64],
                          npt.NDArray[np.float64]]:
        """Gear and filament speed over ``[t0_s, t1_s]`` as piecewise-linear knots.

        Each step is represented by its mean speeds at its midpoint (plus the window's
        ends, held), which is what a camera integrating over frames sees.

        Returns
        -------
        (t_s, gear_speed_mm_s, filament_speed_mm_s)
            Knot times (strictly increasing, from ``t0_s`` to ``t1_s``) and speeds, mm/s.
        """
        h = self._hist
        times = h["t"]
        i0 = max(bisect.bisect_left(times, t0_s) - 1, 0)
        i1 = min(bisect.bisect_right(times, t1_s) + 1, len(times))
        t_end = np.asarray(times[i0:i1])
        dt = np.asarray(h["dt"][i0:i1])
        mid = t_end - 0.5 * dt
        gear = np.asarray(h["gear"][i0:i1])
        fil = np.asarray(h["fil"][i0:i1])
        keep = (mid > t0_s) & (mid < t1_s)
        mid, gear, fil = mid[keep], gear[keep], fil[keep]
        if mid.size == 0:
            idx = min(bisect.bisect_left(times, t1_s), len(times) - 1) if times else -1
            g0 = h["gear"][idx] if idx >= 0 else 0.0
            f0 = h["fil"][idx] if idx >= 0 else 0.0
            return (np.array([t0_s, t1_s]), np.array([g0, g0]), np.array([f0, f0]))
        t = np.concatenate(([t0_s], mid, [t1_s]))
        g = np.concatenate(([gear[0]], gear, [gear[-1]]))
        f = np.concatenate(([fil[0]], fil, [fil[-1]]))
        ok = np.concatenate(([True], np.diff(t) > 1e-12))
        return t[ok], g[ok], f[ok]

    # -- stepping ---------------------------------------------------------------------
    def params_at(self, temperature_c: float, layer_height_mm: float) -> StepParams:
        """State-equation parameters at a temperature and layer height (cached)."""
        key = (round(temperature_c / _T_QUANTUM_C), round(layer_height_mm, 4))
        p = self._params.get(key)
        if p is None:
            p = step_params(self.machine, temperature_c=key[0] * _T_QUANTUM_C,
                            layer_height_mm=key[1])
            self._params[key] = p
        return p

    def advance_to(self, t_s: float, factors: Callable[[float], Factors]) -> None:
        """Run the job up to clock time ``t_s`` (no-op if already there).

        Parameters
        ----------
        t_s
            Target clock time, s.
        factors
            Multipliers acting on the extrusion at a clock time (the twin's
            ``factors_at``, which includes the planner-queue delay).
        """
        while self.t_s < t_s - 1e-12:
            self._step(min(self.step_s, t_s - self.t_s), factors(self.t_s))

    def _heater_events(self) -> None:
        """Apply every heater command whose program time has come."""
        heater = self.job.heater
        while self._next_heater < len(heater) and heater[self._next_heater].tau_s \
                <= self.tau_s + 1e-12:
            cmd = heater[self._next_heater]
            self._next_heater += 1
            self.set_c = cmd.set_c if cmd.set_c > 0.0 else 25.0
            self.waiting = cmd.wait

    def _wait_over(self) -> bool:
        if self.waiting is WaitMode.NONE:
            return True
        if self.waiting is WaitMode.HEAT:
            return self.temperature_c >= self.set_c - self.window_c
        return abs(self.temperature_c - self.set_c) <= self.window_c

    def _step(self, dt: float, f: Factors) -> None:
        job = self.job
        self._heater_events()
        if not self._wait_over():
            v, tau_new = 0.0, self.tau_s
            self._tot["wait"] += dt
        else:
            self.waiting = WaitMode.NONE
            rate = f.speed_pct / 100.0
            tau_new = self.tau_s + rate * dt
            nxt = self._next_heater
            if nxt < len(job.heater) and job.heater[nxt].tau_s < tau_new:
                # stop at the heater command; the rest of the step comes next time
                tau_new = max(job.heater[nxt].tau_s, self.tau_s)
                dt = max((tau_new - self.tau_s) / rate, 1e-9) if rate > 0 else dt
            if tau_new >= job.end_s and self.end_s is None and nxt >= len(job.heater):
                self.end_s = self.t_s + dt
            e_new = job.position_mm(tau_new)
            v = (e_new - self._e_now) * (f.flow_pct / 100.0) / dt
            self._e_now = e_new
        mid_tau = 0.5 * (self.tau_s + tau_new)
        p = self.params_at(self.temperature_c, job.layer_height_at(mid_tau))
        self.state, flux = step_extrusion(self.state, v, dt, p)
        tot = self._tot
        tot["cmd"] += flux.commanded_mm
        tot["fwd"] += max(flux.commanded_mm, 0.0)
        tot["fed"] += flux.fed_mm
        tot["out"] += flux.out_mm
        tot["grind"] += flux.grind_s
        if mid_tau >= job.part_start_s:
            tot["part"] += flux.out_mm
        h = self._hist
        h["t"].append(self.t_s + dt)
        h["dt"].append(dt)
        h["gear"].append(v)
        h["fil"].append(flux.fed_mm / dt)
        h["temp"].append(self.temperature_c)
        h["speed"].append(f.speed_pct)
        h["flow"].append(f.flow_pct)
        h["layer"].append(job.layer_at(mid_tau))
        if self.heater_tau_s > 0.0:
            self.temperature_c = self.set_c + (self.temperature_c - self.set_c) * math.exp(
                -dt / self.heater_tau_s)
        else:
            self.temperature_c = self.set_c
        self.tau_s = tau_new
        self.t_s += dt
