"""The twin as a forward model of the bead width along test lines, with a free lag.

A *test line* is a run of consecutive extruding XY moves of a G-code file (a K-factor line
[001 Fig. 10], a flow line, or any line of a print) whose bead width is measured along
its length. For a trial lag ``K`` (and, optionally, a dead time ``τ`` and a gain ``g``) the
model predicts that width:

1. The G-code is read and planned once (:func:`flowtwin.planner.plan_file.plan_gcode`): the
   timeline gives, for every test line, the nozzle's path position ``s(t)`` and speed
   ``v(t)`` (piecewise constant acceleration).
2. The dynamics (:func:`flowtwin.dynamics.predict`) turn the commanded feed — with the
   firmware's pressure advance as the G-code sets it — into the melt flow
   ``Q_twin(t)``: the lag ``dΔl/dt = v_in − Δl/K`` with no backflow [001 Eqs. 10, 15,
   Fig. 8] and, if asked, the drive's slip [000 Eqs. 6, 8] (docs/spec.md §3.4). ``K`` is the free
   parameter; the column compliance and slip law come from the machine profile.
3. Dead time and gain (beyond the seeds; Bellini et al. 2004, cited in [001] after
   Eq. 15: ``G(s) = g·e^(−τs)/(1 + K·s)``) act on the output,
   ``Q(t) = g·Q_twin(t − τ)``; for a time-invariant system a delay at the output equals
   the delay at the input, and the lag with no backflow is homogeneous in the feed, so
   the gain commutes with it too (slip makes the gain approximate).
4. The bead laid at ``x = s(t)`` is ``w = Q(t)/(h·v(t)) + (1 − π/4)·h`` (the slicer bead
   [001 Eq. 7] inverted, docs/spec.md §3.5; :func:`flowtwin.physics.deposition.bead_width_mm`).

Without slip the dynamics are the exact exponential integrator (a few ms per line), so a
least-squares fit can call the model a hundred times. [001] notes that the printed width
is smoother than the flow where the flow spikes (the melt spreads after the nozzle); the
model does not include that (nor does [001]'s simulation).
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import BinaryIO

import numpy as np
import numpy.typing as npt

from flowtwin.dynamics import (
    AdvanceSettings,
    ExtrusionParams,
    advance_schedule,
    predict,
    printer_advance,
)
from flowtwin.errors import CalibrationError
from flowtwin.gcode.moves import MoveKind
from flowtwin.physics.deposition import bead_width_mm
from flowtwin.planner.plan_file import PlanResult, plan_gcode
from flowtwin.profiles.machine import Machine, load_machine
from flowtwin.simulation.parameters import move_parameters

__all__ = [
    "DEAD_TIME_MAX_S",
    "DEFAULT_MACHINE",
    "LagModel",
    "LagParams",
    "TestLine",
    "lag_model",
    "printed_runs",
]

FloatArray = npt.NDArray[np.float64]

#: Set-up used when none is named: Tronvoll's printer [001] with docs/spec.md §4's parts.
DEFAULT_MACHINE = "tronvoll2019"

#: Largest dead time the model accepts, s (the series starts this long before a line).
DEAD_TIME_MAX_S = 0.5

#: Path resolution of the flow series: the sample interval is chosen so the nozzle moves
#: about this far between samples at the line's top speed (mm), within 0.5–2 ms. The flow
#: relaxes with the time constant K, so linear interpolation between samples errs by about
#: (dt/K)²/8 of a flow step: 3e-5 at 1 ms and K = 0.06 s, 0.1 % at 2 ms and K = 0.02 s.
_SAMPLE_PATH_MM = 0.07


@dataclass(frozen=True, slots=True)
class LagParams:
    """Parameters of the extrusion response ``g·e^(−τs)/(1 + K·s)``.

    Attributes
    ----------
    k_s
        Lag factor ``K``, s (> 0) [001 Eq. 15].
    dead_time_s
        Dead time ``τ``, s (0 … :data:`DEAD_TIME_MAX_S`).
    gain
        Flow gain ``g`` (1: the G-code's flow arrives; < 1: slip or a low extrusion
        multiplier).
    """

    k_s: float
    dead_time_s: float = 0.0
    gain: float = 1.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.k_s) and self.k_s > 0.0):
            raise CalibrationError("the lag factor must be > 0", field="k_s", value=self.k_s,
                                   allowed="> 0 s")
        if not (0.0 <= self.dead_time_s <= DEAD_TIME_MAX_S):
            raise CalibrationError("dead time out of range", field="dead_time_s",
                                   value=self.dead_time_s,
                                   allowed=f"0 .. {DEAD_TIME_MAX_S:g} s")
        if not (math.isfinite(self.gain) and 0.0 < self.gain <= 10.0):
            raise CalibrationError("flow gain out of range", field="gain", value=self.gain,
                                   allowed="0 < g <= 10")


@dataclass(frozen=True)
class TestLine:
    """One measured line: a run of consecutive extruding XY moves.

    Attributes
    ----------
    first_move, last_move
        Move indices of the run (inclusive).
    gcode_line
        Source line of the first move.
    layer_height_mm
        Layer height of the line, mm.
    advance_k_s
        Firmware advance factor in force on the line (from the profile and the G-code), s.
    cum_length_mm
        Path length at the start of each move and at the end, mm, shape ``(m + 1,)``.
    min_cruise_mm_s, max_cruise_mm_s
        Slowest and fastest planned cruise speed of the line's moves, mm/s.
    flow_mm3_s
        Commanded volumetric flow at the fastest cruise, mm³/s (the test's flow).
    accel_mm_s2
        Largest acceleration the planner used on the line, mm/s².
    t_start_s, t_end_s
        When the nozzle starts and ends the line, s.
    vertices_xy_mm
        The path: start point and each move's end point, mm, shape ``(m + 1, 2)``.
    cruise_mm_s
        Planned cruise speed of each move, mm/s, shape ``(m,)``.
    """

    first_move: int
    last_move: int
    gcode_line: int
    layer_height_mm: float
    advance_k_s: float
    cum_length_mm: FloatArray
    min_cruise_mm_s: float
    max_cruise_mm_s: float
    flow_mm3_s: float
    accel_mm_s2: float
    t_start_s: float
    t_end_s: float
    vertices_xy_mm: FloatArray
    cruise_mm_s: FloatArray

    @property
    def length_mm(self) -> float:
        """Path length of the line, mm."""
        return float(self.cum_length_mm[-1])


def _path_kinematics(phases: npt.NDArray[np.void], move: npt.NDArray[np.int64],
                     t_s: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Distance into move ``move[j]`` and nozzle speed at times ``t_s[j]`` (mm, mm/s).

    Trapezoid of one move (the planner's phases): accelerate from ``v0`` at ``a`` for
    ``ta``, cruise at ``vc`` for ``tc``, decelerate at ``a`` for ``td``.
    """
    p = phases[move]
    tau = t_s - p["t_start"]
    v0 = p["start_v"].astype(np.float64)
    vc = p["cruise_v"].astype(np.float64)
    a = p["accel"].astype(np.float64)
    ta, tc, td = p["accel_t"], p["cruise_t"], p["decel_t"]
    tau = np.clip(tau, 0.0, ta + tc + td)
    u1 = np.minimum(tau, ta)
    s = v0 * u1 + 0.5 * a * u1 * u1
    v = v0 + a * u1
    u2 = np.clip(tau - ta, 0.0, tc)
    s += vc * u2
    u3 = np.clip(tau - ta - tc, 0.0, td)
    s += vc * u3 - 0.5 * a * u3 * u3
    v = np.where(u3 > 0.0, vc - a * u3, np.where(u2 > 0.0, vc, v))
    return s, np.maximum(v, 0.0)


@dataclass(frozen=True)
class _LineGrid:
    """Dense samples of one line: time, path position, nozzle speed."""

    t_s: FloatArray
    s_mm: FloatArray
    v_mm_s: FloatArray


@dataclass(frozen=True)
class LagModel:
    """A planned G-code with test lines, ready to predict their widths for trial lags.

    Build with :func:`lag_model`. Attributes are read-only inputs; :meth:`widths` is pure.

    Attributes
    ----------
    plan
        The read and planned G-code.
    lines
        The test lines, in the order given.
    machine_name
        Set-up whose printer planned the G-code and whose column (and slip) is used.
    base_params
        Per-move extrusion parameters with the machine's lag (replaced by the trial ``K``).
    advance
        Firmware pressure advance (``None``: the bare G-code).
    slip
        Whether the drive's slip law is included.
    series_dt_s
        Sample interval of the flow series, s.
    """

    plan: PlanResult
    lines: tuple[TestLine, ...]
    machine_name: str
    base_params: ExtrusionParams
    advance: AdvanceSettings | None
    slip: bool
    series_dt_s: float
    _grids: tuple[_LineGrid, ...] = dataclasses.field(repr=False)

    @property
    def machine_lag_s(self) -> float:
        """Median lag factor the machine profile predicts for the test lines, s."""
        idx = np.concatenate([np.arange(ln.first_move, ln.last_move + 1) for ln in self.lines])
        return float(np.median(self.base_params.lag_k_s[idx]))

    def subset(self, indices: Sequence[int]) -> LagModel:
        """The same model restricted to the test lines ``indices`` (in that order)."""
        idx = [int(i) for i in indices]
        return dataclasses.replace(self, lines=tuple(self.lines[i] for i in idx),
                                   _grids=tuple(self._grids[i] for i in idx))

    def flow_series(self, params: LagParams) -> tuple[FloatArray, FloatArray]:
        """Times (s) and melt flow ``Q_twin`` (mm³/s) around the lines for lag ``params.k_s``.

        Dead time and gain are not applied here (see :meth:`widths`).
        """
        n = self.base_params.n_moves
        ext = dataclasses.replace(self.base_params, lag_k_s=np.full(n, float(params.k_s)))
        t_a = min(g.t_s[0] for g in self._grids) - DEAD_TIME_MAX_S - 2 * self.series_dt_s
        t_b = max(g.t_s[-1] for g in self._grids) + self.series_dt_s
        res = predict(self.plan.table, self.plan.timeline, ext, advance=self.advance,
                      series_dt_s=self.series_dt_s, series_window_s=(max(t_a, 0.0), t_b))
        series = res.series
        assert series is not None  # asked for
        # the series' fields are strided views of its records: made contiguous once here,
        # not by ``np.interp`` at every line of every trial (it copies a strided ``xp``)
        return (np.ascontiguousarray(series["t_s"], dtype=np.float64),
                np.ascontiguousarray(series["q_out_mm3_s"], dtype=np.float64))

    def passes(self, positions_mm: Sequence[npt.ArrayLike]
               ) -> list[tuple[FloatArray, FloatArray]]:
        """When the nozzle passes the given positions of each line, and how fast.

        Parameters
        ----------
        positions_mm
            One array per test line (same order as :attr:`lines`): distance along the
            line from its start, mm, each within ``[0, length]``.

        Returns
        -------
        list of tuple
            Per line, the times (s) and nozzle speeds (mm/s) at the positions, each of the
            positions' shape. They do not depend on the lag: a fit that tries many lags at
            the same positions computes them once (``widths(..., passes=...)``).
        """
        if len(positions_mm) != len(self.lines):
            raise CalibrationError("one position array per test line is needed",
                                   field="positions_mm", value=len(positions_mm),
                                   allowed=f"{len(self.lines)} arrays")
        out: list[tuple[FloatArray, FloatArray]] = []
        for grid, pos in zip(self._grids, positions_mm, strict=True):
            t = np.interp(np.asarray(pos, dtype=np.float64), grid.s_mm, grid.t_s)
            out.append((t, np.interp(t, grid.t_s, grid.v_mm_s)))
        return out

    def widths(self, params: LagParams, positions_mm: Sequence[npt.ArrayLike], *,
               series: tuple[FloatArray, FloatArray] | None = None,
               passes: Sequence[tuple[FloatArray, FloatArray]] | None = None
               ) -> list[FloatArray]:
        """Predicted bead width at the given positions of each line, mm.

        Parameters
        ----------
        params
            Lag, dead time and gain.
        positions_mm
            One array per test line (same order as :attr:`lines`): distance along the
            line from its start, mm, each within ``[0, length]``.
        series
            :meth:`flow_series` for ``params`` when already made.
        passes
            :meth:`passes` of ``positions_mm`` when already made.

        Returns
        -------
        list of ndarray
            Width ``w = g·Q_twin(t − τ)/(h·v(t)) + (1 − π/4)·h`` at the time ``t`` the
            nozzle passes each position [001 Eq. 7]; NaN where the nozzle stands still.
        """
        at = self.passes(positions_mm) if passes is None else passes
        if len(at) != len(self.lines):
            raise CalibrationError("one pass array per test line is needed", field="passes",
                                   value=len(at), allowed=f"{len(self.lines)} pairs")
        t_q, q = self.flow_series(params) if series is None else series
        out: list[FloatArray] = []
        for line, (t, v) in zip(self.lines, at, strict=True):
            q_at = params.gain * np.interp(t - params.dead_time_s, t_q, q)
            out.append(np.asarray(bead_width_mm(q_at, line.layer_height_mm, v).width_mm,
                                  dtype=np.float64))
        return out

    def speed_at(self, line_index: int, positions_mm: npt.ArrayLike) -> FloatArray:
        """Nozzle speed when it passes the given positions of line ``line_index``, mm/s."""
        grid = self._grids[line_index]
        t = np.interp(np.asarray(positions_mm, dtype=np.float64), grid.s_mm, grid.t_s)
        return np.asarray(np.interp(t, grid.t_s, grid.v_mm_s), dtype=np.float64)

    def usable(self, line_index: int, positions_mm: npt.ArrayLike, *,
               end_margin_mm: float, min_speed_fraction: float = 0.5
               ) -> npt.NDArray[np.bool_]:
        """Positions where a width measurement can be compared with the model.

        Excluded: within ``end_margin_mm`` of either end of the line (the bead's end caps
        and start blob), and where the nozzle is slower than ``min_speed_fraction`` of the
        line's slowest cruise speed (the width ``Q/(h·v)`` diverges as ``v → 0``).
        """
        line = self.lines[line_index]
        x = np.asarray(positions_mm, dtype=np.float64)
        inside = (x >= end_margin_mm) & (x <= line.length_mm - end_margin_mm)
        fast = self.speed_at(line_index, np.clip(x, 0.0, line.length_mm)) >= (
            min_speed_fraction * line.min_cruise_mm_s)
        return np.asarray(inside & fast, dtype=np.bool_)


def _printing(plan: PlanResult) -> npt.NDArray[np.bool_]:
    kind = plan.table.moves["kind"].astype(np.int64)
    return np.asarray(((kind & int(MoveKind.EXTRUDE)) != 0) & ((kind & int(MoveKind.XY)) != 0))


def printed_runs(plan: PlanResult) -> list[int]:
    """G-code line of the first move of every run of consecutive extruding XY moves."""
    printing = _printing(plan)
    starts = np.flatnonzero(printing & ~np.concatenate(([False], printing[:-1])))
    return [int(v) for v in plan.table.moves["line"][starts]]


def _find_run(plan: PlanResult, gcode_line: int, source: str) -> tuple[int, int]:
    """First and last move of the run of extruding XY moves starting at ``gcode_line``."""
    m = plan.table.moves
    printing = _printing(plan)
    hits = np.flatnonzero(m["line"] == gcode_line)
    if hits.size == 0 or not printing[hits[0]]:
        first_print = m["line"][printing][:5].tolist()
        raise CalibrationError("the test line must start at a move that extrudes while "
                               "moving in X/Y", source=source, line=gcode_line,
                               field="gcode_line", value=gcode_line,
                               allowed="the line of the test line's first extruding move "
                                       f"(the file's first ones are at lines {first_print})")
    first = int(hits[0])
    last = first
    while last + 1 < len(m) and printing[last + 1]:
        last += 1
    return first, last


def _test_line(plan: PlanResult, first: int, last: int, heights: FloatArray,
               k_adv: FloatArray, area_mm2: float) -> tuple[TestLine, _LineGrid]:
    m = plan.table.moves
    ph = plan.timeline.phases
    start = np.empty((last - first + 1, 2))
    if first == 0:
        start[0] = plan.table.start_xyze[:2]
    else:
        start[0] = (m["x"][first - 1], m["y"][first - 1])
    start[1:, 0] = m["x"][first:last]
    start[1:, 1] = m["y"][first:last]
    seg = np.hypot(m["x"][first:last + 1] - start[:, 0], m["y"][first:last + 1] - start[:, 1])
    cum = np.concatenate(([0.0], np.cumsum(seg)))
    cruise = ph["cruise_v"][first:last + 1].astype(np.float64)
    flow = (area_mm2 * m["de"][first:last + 1] * m["flow"][first:last + 1].astype(np.float64)
            / np.maximum(seg, 1e-12) * cruise)
    t0 = float(ph["t_start"][first])
    t1 = float(ph["t_start"][last] + ph["accel_t"][last] + ph["cruise_t"][last]
               + ph["decel_t"][last])
    v_top = float(np.max(cruise))
    dt = _series_dt(v_top)
    n = max(int(math.ceil((t1 - t0) / dt)) + 1, 2)
    t = np.linspace(t0, t1, n)
    ends = np.asarray(ph["t_start"][first:last + 1], dtype=np.float64)
    move = first + np.clip(np.searchsorted(ends, t, side="right") - 1, 0, last - first)
    s_in, v = _path_kinematics(ph, move.astype(np.int64), t)
    s = cum[move - first] + np.minimum(s_in, seg[move - first])
    s = np.maximum.accumulate(s)
    line = TestLine(first_move=first, last_move=last, gcode_line=int(m["line"][first]),
                    layer_height_mm=float(heights[first]), advance_k_s=float(k_adv[first]),
                    cum_length_mm=cum, min_cruise_mm_s=float(np.min(cruise)),
                    max_cruise_mm_s=v_top, flow_mm3_s=float(flow[int(np.argmax(cruise))]),
                    accel_mm_s2=float(np.max(ph["accel"][first:last + 1])),
                    t_start_s=t0, t_end_s=t1,
                    vertices_xy_mm=np.vstack([start[:1], np.column_stack(
                        [m["x"][first:last + 1], m["y"][first:last + 1]])]),
                    cruise_mm_s=cruise)
    return line, _LineGrid(t, s, v)


def _series_dt(v_top_mm_s: float) -> float:
    return float(np.clip(_SAMPLE_PATH_MM / max(v_top_mm_s, 1e-9), 5e-4, 2e-3))


def lag_model(source: str | os.PathLike[str] | bytes | BinaryIO,
              gcode_lines: Sequence[int] | None, *,
              machine: Machine | str | os.PathLike[str] | None = None,
              slip: bool = False, pressure_advance: bool = True,
              layer_height_mm: float | None = None) -> LagModel:
    """Read and plan ``source`` and prepare the test lines starting at ``gcode_lines``.

    Parameters
    ----------
    source
        G-code (path, bytes or binary stream) that printed the test lines.
    gcode_lines
        1-based source line of each test line's first extruding move; the line runs
        over the consecutive extruding XY moves from there. ``None``: every such run of
        the file (:func:`printed_runs`), e.g. to render a whole pattern.
    machine
        Set-up (built-in name, TOML file or :class:`Machine`); its printer plans the file,
        its filament, column and drive feed the dynamics. Default :data:`DEFAULT_MACHINE`.
    slip
        Include the drive's slip law [000] (about 20× slower; the gain absorbs a steady
        slip otherwise, as [001] tunes flow and slip beforehand).
    pressure_advance
        Apply the firmware's pressure advance: the profile's factor and the G-code's
        commands (the factor each test line was printed with).
    layer_height_mm
        Layer height of the lines, mm (default: from the file's layer changes).

    Returns
    -------
    LagModel

    Raises
    ------
    CalibrationError
        No test line, a line that does not start at an extruding XY move.
    GcodeError, ProfileError
        Bad G-code or set-up.
    """
    m = machine if isinstance(machine, Machine) else load_machine(machine or DEFAULT_MACHINE)
    plan = plan_gcode(source, printer=m.printer)
    name = plan.table.source
    if gcode_lines is None:
        gcode_lines = printed_runs(plan)
    if not gcode_lines:
        raise CalibrationError("no test line", source=name, field="gcode_lines",
                               allowed="one or more G-code lines of extruding XY moves")
    params = move_parameters(m, plan.table, plan.timeline)
    base = params.params
    if not slip:
        base = ExtrusionParams.build(len(plan.table), lag_k_s=base.lag_k_s,
                                     compliance_mm_per_n=base.compliance_mm_per_n,
                                     filament_diameter_mm=m.filament.diameter_mm)
    advance = None
    if pressure_advance:
        advance = printer_advance(m.printer)
        k_adv = advance_schedule(plan.table, advance).k_eff_s
    else:
        k_adv = np.zeros(len(plan.table))
    if layer_height_mm is None:
        heights = params.layer_height_mm
    else:
        if not (0.0 < layer_height_mm <= m.hotend.nozzle_diameter_mm):
            raise CalibrationError("layer height out of range", field="layer_height_mm",
                                   value=layer_height_mm,
                                   allowed=f"0 < h <= nozzle ({m.hotend.nozzle_diameter_mm:g} "
                                           "mm)")
        heights = np.full(len(plan.table), float(layer_height_mm))
    lines: list[TestLine] = []
    grids: list[_LineGrid] = []
    seen: set[int] = set()
    for gl in gcode_lines:
        first, last = _find_run(plan, int(gl), name)
        if first in seen:
            raise CalibrationError("the same test line is given twice", source=name,
                                   line=int(gl), field="gcode_line", value=int(gl),
                                   allowed="each test line once")
        seen.add(first)
        line, grid = _test_line(plan, first, last, heights, k_adv, m.filament.area_mm2)
        lines.append(line)
        grids.append(grid)
    dt = min(_series_dt(ln.max_cruise_mm_s) for ln in lines)
    return LagModel(plan=plan, lines=tuple(lines), machine_name=m.name, base_params=base,
                    advance=advance, slip=slip, series_dt_s=dt, _grids=tuple(grids))
