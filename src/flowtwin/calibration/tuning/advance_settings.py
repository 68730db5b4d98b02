"""Firmware settings from the twin: the best single advance factor and an adaptive table.

Where the firmware has pressure advance, the right setting is better than a rewritten
file. The twin predicts the flow error of a print for any advance factor ``K`` of the
printer's own algorithm (Klipper's smoothed advance, Marlin's linear advance 1.5 with its
planner cap, RepRapFirmware's, Prusa's; :mod:`flowtwin.dynamics.advance`), so:

* :func:`best_pressure_advance` finds the ``K`` that minimises the twin's volume-weighted
  RMS flow error (:mod:`flowtwin.compensation.metrics`) over a print — the user's file, or
  the built-in example print as a representative one — by a coarse scan and a bounded
  scalar refinement, and explains the number: [001] says ``K_LA = K`` restores the command
  when the firmware applies Eq. 11 exactly; the firmware's smoothing window, its
  acceleration cap, the slip loop (which damps the column) and the spread of the twin's
  ``K`` over layer heights and temperatures move the optimum away from the lag factor;
* :func:`adaptive_pa_table` does the same on a short test print per volumetric flow and
  acceleration and returns OrcaSlicer's adaptive pressure advance table
  (:class:`flowtwin.calibration.tuning.adaptive_pa.AdaptivePaTable`, rows ``PA, flow, accel``).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from flowtwin.dynamics import AdvanceSettings, predict
from flowtwin.errors import CalibrationError, DataError, GcodeError
from flowtwin.firmware import (
    DEFAULT_SMOOTH_TIME_S,
    AdvanceAlgorithm,
    Firmware,
    accel_command,
    pa_command,
)
from flowtwin.gcode.emitter import GcodeEmitter, NumberFormat, WordFormats, format_number
from flowtwin.gcode.moves import MoveKind, MoveTable
from flowtwin.gcode.reader import read_gcode
from flowtwin.physics.deposition import bead_area_mm2
from flowtwin.planner.from_profile import read_options
from flowtwin.planner.plan_file import PlanResult, plan_for_profile, plan_gcode
from flowtwin.profiles.machine import Machine, load_machine
from flowtwin.profiles.setup import SetupProfile
from flowtwin.scalar_search import bounded_minimum
from flowtwin.simulation import DEFAULT_MACHINE, move_parameters

if TYPE_CHECKING:
    from flowtwin.calibration.tuning.adaptive_pa import AdaptivePaTable

__all__ = ["AdvanceFit", "adaptive_pa_table", "best_pressure_advance", "pa_test_gcode"]

#: Number formats of the test prints (feed rates to 0.1 mm/min).
_TEST_FORMATS = WordFormats(xyz=NumberFormat(3, trim=True), e=NumberFormat(5),
                            f=NumberFormat(1))


@dataclass(slots=True)
class AdvanceFit:
    """The best single advance factor for a print on a machine.

    Attributes
    ----------
    k_s
        Best advance factor, s.
    command
        The firmware command that sets it.
    firmware
        Firmware whose algorithm was simulated.
    rms_at_best, rms_without, rms_at_lag
        Twin RMS flow error with ``k_s``, without advance, and with ``K`` = the twin's
        volume-weighted lag factor.
    peak_at_best, peak_without
        Peak over-extrusion with ``k_s`` and without advance.
    lag_k_s, lag_k_range_s
        The twin's lag factor: volume-weighted mean and (min, max) over printing moves, s.
    curve
        ``(K, RMS)`` pairs evaluated.
    source
        The print the fit used.
    explanation
        Why this number, in words.
    """

    k_s: float
    command: str
    firmware: str
    rms_at_best: float
    rms_without: float
    rms_at_lag: float
    peak_at_best: float
    peak_without: float
    lag_k_s: float
    lag_k_range_s: tuple[float, float]
    curve: list[tuple[float, float]] = field(default_factory=list)
    source: str = ""
    explanation: str = ""

    def as_dict(self) -> dict[str, object]:
        """Plain dict (JSON-ready)."""
        return {name: getattr(self, name) for name in self.__slots__}


class _Scorer:
    """The twin's flow error of one print for any advance factor."""

    def __init__(self, source: str | os.PathLike[str] | bytes, machine: Machine,
                 klipper_config: str | os.PathLike[str] | None) -> None:
        self.source = source
        self.machine = machine
        self.klipper_config = klipper_config
        self.firmware = Firmware.KLIPPER if klipper_config is not None else \
            machine.printer.firmware
        # Marlin's planner caps the acceleration by K: every K is planned anew
        self.replan = (self.firmware.advance is AdvanceAlgorithm.LINEAR_ADVANCE
                       and klipper_config is None)
        printer = machine.printer
        self.smooth = (printer.pa_smooth_time_s or printer.pressure_advance.smooth_time_s
                       or DEFAULT_SMOOTH_TIME_S)
        self._plans: dict[float, tuple[PlanResult, object]] = {}
        self._table: MoveTable | None = None
        self._scores: dict[float, tuple[float, float]] = {}
        base = self._plan(0.0)[0]
        mv = base.table.moves
        if not np.any((mv["kind"] & MoveKind.EXTRUDE) != 0):
            raise GcodeError("the print has no extruding moves to fit an advance to",
                             source=base.table.source)

    def _plan(self, k: float) -> tuple[PlanResult, object]:
        key = round(k, 9) if self.replan else 0.0
        if key not in self._plans:
            if self.klipper_config is not None:
                plan = plan_gcode(self.source, klipper_config=self.klipper_config)
            else:
                pr = self.machine.printer
                printer = pr.model_copy(update={"pressure_advance": pr.pressure_advance
                                                .model_copy(update={"k_s": key})})
                if self._table is None:  # K changes the planning, not the reading
                    self._table = read_gcode(self.source, options=read_options(printer))
                plan = plan_for_profile(self._table, printer)
            params = move_parameters(self.machine, plan.table, plan.timeline)
            if len(self._plans) > 64:
                self._plans.clear()
            self._plans[key] = (plan, params)
        return self._plans[key]

    def lag(self) -> tuple[float, float, float]:
        plan, params = self._plan(0.0)
        mv = plan.table.moves
        ext = ((mv["kind"] & MoveKind.EXTRUDE) != 0) & ((mv["kind"] & MoveKind.XY) != 0)
        if not np.any(ext):
            raise DataError("no printing moves (extruding XY moves) to fit the advance on",
                            source=plan.table.source, field="moves", value=0,
                            allowed="at least one extruding XY move")
        k = params.params.lag_k_s[ext]  # type: ignore[attr-defined]
        w = np.maximum(mv["de"][ext], 0.0)
        mean = float(np.sum(k * w) / np.sum(w)) if np.sum(w) > 0 else float(np.mean(k))
        return mean, float(np.min(k)), float(np.max(k))

    def score(self, k: float) -> tuple[float, float]:
        """RMS and peak flow error at ``k`` (each ``k`` is simulated once)."""
        if k not in self._scores:
            self._scores[k] = self._score(k)
        return self._scores[k]

    def _score(self, k: float) -> tuple[float, float]:
        plan, params = self._plan(k)
        adv = AdvanceSettings(self.firmware, k_s=float(k), smooth_time_s=self.smooth,
                              use_gcode=False)
        dyn = predict(plan.table, plan.timeline, params.params,  # type: ignore[attr-defined]
                      advance=adv if k > 0 else None)
        mv = plan.table.moves
        d = dyn.moves
        ext = (((mv["kind"] & MoveKind.EXTRUDE) != 0) & ((mv["kind"] & MoveKind.XY) != 0)
               & (d["cmd_mm3"] > 0) & (d["duration_s"] > 0))
        cmd = d["cmd_mm3"][ext]
        err = d["out_mm3"][ext] / cmd - 1.0
        rms = float(np.sqrt(np.sum(cmd * err * err) / np.sum(cmd))) if cmd.size else 0.0
        return rms, float(np.max(err, initial=0.0))


def best_pressure_advance(source: str | os.PathLike[str] | bytes | None = None, *,
                          machine: Machine | SetupProfile | str | os.PathLike[str] | None
                          = None, klipper_config: str | os.PathLike[str] | None = None,
                          k_max_s: float | None = None, grid: int = 13) -> AdvanceFit:
    """The single advance factor that minimises the twin's flow error (module docstring).

    Parameters
    ----------
    source
        The print to fit on (path or bytes); ``None``: the built-in example print.
    machine
        The set-up (default the twin's).
    klipper_config
        Klipper ``printer.cfg`` to plan with (its firmware's advance is simulated).
    k_max_s
        Largest factor searched, s (default: 3× the twin's largest lag factor, at most 10).
    grid
        Points of the coarse scan before the bounded refinement.

    Returns
    -------
    AdvanceFit

    Raises
    ------
    GcodeError, ProfileError, CalibrationError
        Unreadable print, bad profiles, or a search range that is not positive.
    """
    m = machine if isinstance(machine, Machine) else load_machine(machine or DEFAULT_MACHINE)
    name = "built-in example print" if source is None else (
        "<bytes>" if isinstance(source, bytes) else os.fspath(source))
    data: str | os.PathLike[str] | bytes = source if source is not None else _example_print()
    scorer = _Scorer(data, m, klipper_config)
    lag_mean, lag_lo, lag_hi = scorer.lag()
    hi = min(10.0, 3.0 * lag_hi) if k_max_s is None else float(k_max_s)
    if not (hi > 0 and math.isfinite(hi)):
        raise CalibrationError("the search range for K must be positive", field="k_max_s",
                               value=hi, allowed="0 < K <= 10 s")
    ks = np.linspace(0.0, hi, max(grid, 3))
    curve = [(float(k), scorer.score(float(k))[0]) for k in ks]
    i = int(np.argmin([c[1] for c in curve]))
    lo_b = float(ks[max(i - 1, 0)])
    hi_b = float(ks[min(i + 1, ks.size - 1)])
    best_k, best_rms = curve[i]
    if hi_b > lo_b:
        k_min, rms_min = bounded_minimum(lambda k: scorer.score(k)[0], lo_b, hi_b,
                                         xatol=1e-4 * max(hi, 1e-3))
        if rms_min < best_rms:
            best_k, best_rms = k_min, rms_min
            curve.append((best_k, best_rms))
    curve.sort()
    rms0, peak0 = scorer.score(0.0)
    rms_lag, _ = scorer.score(lag_mean)
    _, peak_best = scorer.score(best_k)
    fw = scorer.firmware
    k_round = float(format_number(best_k, 4))
    command = pa_command(fw, k_round)
    fit = AdvanceFit(k_s=k_round, command=command, firmware=fw.value, rms_at_best=best_rms,
                     rms_without=rms0, rms_at_lag=rms_lag, peak_at_best=peak_best,
                     peak_without=peak0, lag_k_s=lag_mean, lag_k_range_s=(lag_lo, lag_hi),
                     curve=curve, source=name)
    fit.explanation = _explain(fit, fw, scorer.smooth)
    return fit


def _example_print() -> bytes:
    """The built-in example print's G-code."""
    from flowtwin.gcode.generator import PrintSpec, generate_print

    return "".join(line + "\n" for line in generate_print(PrintSpec())).encode()


def _explain(fit: AdvanceFit, fw: Firmware, smooth_s: float) -> str:
    why = {
        AdvanceAlgorithm.SMOOTHED: f"{fw.label} averages the advance over {smooth_s:g} s, "
                                   "which delays it, and applies it only to printing moves",
        AdvanceAlgorithm.LINEAR_ADVANCE: "Marlin's linear advance reaches K·v_E through a "
                                         "speed offset limited by the E jerk, and its planner "
                                         "lowers the acceleration of printing moves (E-jerk / "
                                         "(K·e/D))",
        AdvanceAlgorithm.WITHIN_MOVE: f"{fw.label} advances within each move but not across "
                                      "a jump of the extrusion ratio between moves",
    }[fw.advance]
    lo, hi = fit.lag_k_range_s
    text = (f"The twin's lag factor of this print is {fit.lag_k_s:.3f} s "
            f"({lo:.3f}–{hi:.3f} s over its layer heights and temperatures). "
            f"[001] restores the command with K_LA = K when Eq. 11 is applied exactly; "
            f"{why}, and the drive's slip damps the column, so the best single setting is "
            f"K = {fit.k_s:g} s: RMS flow error {100 * fit.rms_at_best:.2f} % "
            f"(without advance {100 * fit.rms_without:.2f} %, with K = lag factor "
            f"{100 * fit.rms_at_lag:.2f} %), peak over-extrusion "
            f"{100 * fit.peak_at_best:.1f} % (without {100 * fit.peak_without:.1f} %). "
            f"Set it with: {fit.command}")
    return text


def pa_test_gcode(machine: Machine, *, flow_mm3_s: float, accel_mm_s2: float,
                  firmware: Firmware, lines: int = 3) -> str:
    """A short test print: lines that go slow → fast → slow at one flow and acceleration.

    The fast part runs at ``v = Q / A_bead`` (the slicer bead [001 Eq. 7] of the set-up's
    line width and layer height); slow parts at 10 mm/s, 15 mm each; fast part 60 mm.

    Returns
    -------
    str
        G-code text.
    """
    w = machine.setup.line_width_mm or 0.45
    h = machine.setup.layer_height_mm or 0.2
    area_fil = machine.filament.area_mm2
    bead = float(bead_area_mm2(w, h))
    v = flow_mm3_s / bead
    temp = float(machine.temperature_c)
    out = GcodeEmitter(_TEST_FORMATS)
    out.begin(relative_e=True)
    out.heat_nozzle(temp)
    out.heat_nozzle(temp, wait=True)
    out.line(accel_command(firmware, accel_mm_s2))
    out.reset_e()
    out.move(z=h, f_mm_min=600.0)
    y = 20.0
    for _ in range(lines):
        x = 20.0
        out.move(x=x, y=y, f_mm_min=9000.0)
        for length, speed in ((15.0, 10.0), (60.0, v), (15.0, 10.0)):
            x += length
            out.move(x=x, y=y, e_mm=bead * length / area_fil, f_mm_min=60.0 * speed)
        out.move(e_mm=-0.8, f_mm_min=2100.0)
        y += 5.0
        out.move(x=20.0, y=y, f_mm_min=9000.0)
        out.move(e_mm=0.8, f_mm_min=2100.0)
    out.heat_nozzle(0)
    return out.text()


def adaptive_pa_table(*, machine: Machine | SetupProfile | str | os.PathLike[str] | None = None,
                      klipper_config: str | os.PathLike[str] | None = None,
                      flows_mm3_s: Sequence[float] | None = None,
                      accels_mm_s2: Sequence[float] | None = None
                      ) -> tuple[AdaptivePaTable, list[AdvanceFit]]:
    """OrcaSlicer's adaptive pressure advance table computed with the twin.

    Parameters
    ----------
    machine
        The set-up (default the twin's).
    klipper_config
        Klipper ``printer.cfg`` to plan with.
    flows_mm3_s
        Volumetric flows to measure, mm³/s (default 2, 5, 8, 12, 16; at least two).
    accels_mm_s2
        Accelerations, mm/s², whole numbers (default 1000, 3000, 6000).

    Returns
    -------
    tuple
        The table (rows ``PA, flow, accel``) and the fit at every point.

    Raises
    ------
    CalibrationError
        Fewer than two flows, or a non-positive value.
    """
    m = machine if isinstance(machine, Machine) else load_machine(machine or DEFAULT_MACHINE)
    flows = list(flows_mm3_s) if flows_mm3_s is not None else [2.0, 5.0, 8.0, 12.0, 16.0]
    accels = list(accels_mm_s2) if accels_mm_s2 is not None else [1000.0, 3000.0, 6000.0]
    if len(flows) < 2 or any(not (q > 0) for q in flows) or any(not (a > 0) for a in accels):
        raise CalibrationError("an adaptive table needs at least two positive flows and "
                               "positive accelerations", field="flows_mm3_s",
                               value=(flows, accels), allowed=">= 2 flows > 0, accels > 0")
    fw = Firmware.KLIPPER if klipper_config is not None else m.printer.firmware
    ks: list[float] = []
    qs: list[float] = []
    aa: list[float] = []
    fits: list[AdvanceFit] = []
    for a in accels:
        for q in flows:
            text = pa_test_gcode(m, flow_mm3_s=q, accel_mm_s2=a, firmware=fw)
            fit = best_pressure_advance(text.encode(), machine=m, klipper_config=klipper_config,
                                        grid=9)
            fit.source = f"test lines at {q:g} mm³/s, {a:g} mm/s²"
            fits.append(fit)
            ks.append(fit.k_s)
            qs.append(q)
            aa.append(round(a))
    from flowtwin.calibration.tuning.adaptive_pa import AdaptivePaTable

    return AdaptivePaTable.from_points(ks, qs, aa, source="twin"), fits
