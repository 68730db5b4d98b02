"""The verdict of a simulation in plain words and units, and what to do about it.

:func:`build_verdict` turns a :class:`~flowtwin.simulation.SimulationResult` into a small
frozen :class:`Verdict`: will the drive grind (the smallest force margin in N and as a
share of the roller's grip), where the print over- and under-extrudes most over one nozzle
diameter of path (:mod:`flowtwin.simulation.windowed`, the figure ``compensate`` reports),
with G-code lines, layer and feature, how much oozes, how long it takes, and the advice:
the pressure advance that fits, the flow or speed limit that removes a grinding risk, and
the ``flowtwin compensate`` flags. The HTML report, ``flowtwin simulate`` and any other
command print the same object.

The words follow thresholds of this module (:data:`FLOW_OK`, :data:`FLOW_VISIBLE`,
:data:`SLIP_NOTABLE`); they are reporting conventions, not physics, and are stated in
``docs/report.md``. Where the windows are is :mod:`flowtwin.report.spots`. The grinding
safety share is the grinding guard's (:class:`flowtwin.compensation.GuardOptions`), so the
advice and the guard agree.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from flowtwin.compensation.guard import GuardOptions
from flowtwin.gcode.moves import MoveKind
from flowtwin.report.spots import Spot, locate_spots, move_paths_mm, result_windowed
from flowtwin.simulation import SimulationResult
from flowtwin.simulation.windowed import WindowedFlow

if TYPE_CHECKING:
    from flowtwin.calibration.tuning.advance_settings import AdvanceFit
    from flowtwin.simulation.summary import SimulationSummary

__all__ = ["FLOW_OK", "FLOW_VISIBLE", "SLIP_NOTABLE", "Advice", "FeatureFlow", "GrindingRisk",
           "Spot", "Verdict", "build_verdict"]

#: Windowed flow errors within ±5 % are called fine.
FLOW_OK = 0.05
#: Beyond ±15 % a window is called a visible defect (bulge or gap).
FLOW_VISIBLE = 0.15
#: Mean drive slip above 1 % is worth feeding forward (``compensate --slip``).
SLIP_NOTABLE = 0.01
_BEAD = 1.0 - math.pi / 4.0
_PRINTING = int(MoveKind.EXTRUDE | MoveKind.XY)


@dataclass(frozen=True, slots=True)
class GrindingRisk:
    """Will the drive grind the filament.

    Attributes
    ----------
    level
        ``"grinds"`` (the twin predicts grinding), ``"at risk"`` (a move needs more than
        the safety share of the grip) or ``"safe"``.
    min_margin_n, min_margin_share
        Smallest margin of the feed force to the roller's maximum, N and as a share of that
        maximum (``nan`` when no move extrudes).
    max_force_n, grip_n
        Largest predicted feed force, and the roller's maximum at that move, N.
    grinding_moves, grinding_events
        Moves the twin flags as grinding, and separate episodes.
    line, layer, feature
        Where the margin is smallest (``0``, ``-1``, ``""`` when no move extrudes).
    safety
        Share of the grip the advice keeps to (the grinding guard's).
    flow_limit_mm3_s
        Steady volumetric flow whose feed force ``K·Q/(A·k)`` reaches ``safety · grip``
        (lag factor ``K``, compliance ``k``, filament area ``A`` [000 §4, 001 Eq. 4]), the
        smallest over the printing moves; ``nan`` when no move extrudes. Transients (the
        pressure advance, accelerations) add to the steady force: ``speed_limit_mm_s``
        covers them for the tightest move.
    speed_limit_mm_s
        Speed of the tightest move (largest force / grip, the peak or the steady force)
        that keeps it below ``safety · grip``, by the guard's ``F ∝ Q`` scaling (its own
        planned speed when it is already below).
    machine_flow_limit_mm3_s
        The machine's maximum volumetric flow at the printing moves' temperature and layer
        height (the melt model and the drive's slip, :mod:`flowtwin.simulation.limits`),
        the smallest over the printing moves; ``nan`` without it. The steady force above
        holds ``K`` at each move's own melt temperature, so above this flow (a colder
        melt) it is optimistic: the advice takes the smaller of the two.
    moves_over_machine_limit
        Printing moves that ask for more than their machine flow limit.
    """

    level: str
    min_margin_n: float
    min_margin_share: float
    max_force_n: float
    grip_n: float
    grinding_moves: int
    grinding_events: int
    line: int
    layer: int
    feature: str
    safety: float
    flow_limit_mm3_s: float
    speed_limit_mm_s: float
    machine_flow_limit_mm3_s: float = math.nan
    moves_over_machine_limit: int = 0


@dataclass(frozen=True, slots=True)
class FeatureFlow:
    """Flow error of one feature type (windowed extremes, RMS per move, time)."""

    feature: str
    time_s: float
    commanded_mm3: float
    rms_flow_error: float
    worst_over: float
    worst_under: float
    min_margin_n: float


@dataclass(frozen=True, slots=True)
class Advice:
    """One thing to do: why, and the command or setting (``""`` when none)."""

    text: str
    command: str = ""


@dataclass(frozen=True, slots=True)
class Verdict:
    """What a simulation says about a print, in plain words and units.

    Attributes
    ----------
    file, machine, printer, firmware, pressure_advance
        What was simulated, on what.
    print_time_s
        Planned print time, s.
    window_mm
        Window of the flow figures: one nozzle diameter of path, mm.
    headline
        One sentence.
    grinding
        The grinding risk.
    over, under
        The worst over- and under-extruding windows (``None``: none).
    worst_over, worst_under
        The worst separate windows each way, worst first.
    by_feature
        Flow figures per feature type.
    rms_flow_error, volume_error
        Volume-weighted RMS of the per-move flow error, and delivered / commanded − 1 of
        the whole print (fractions).
    mean_slip
        Filament lost to drive slip / filament fed (fraction).
    ooze_mm3, ooze_line
        Melt out during travels, retractions and stops, mm³, and the line of the move
        with the most.
    narrow_beads
        Printing moves whose predicted width is below the layer height.
    lag_k_s
        The twin's lag factor, volume-weighted over printing moves, s.
    fit
        The fitted firmware pressure advance, when one was computed.
    advice
        What to do, most important first.
    """

    file: str
    machine: str
    printer: str
    firmware: str
    pressure_advance: str
    print_time_s: float
    window_mm: float
    headline: str
    grinding: GrindingRisk
    over: Spot | None
    under: Spot | None
    worst_over: tuple[Spot, ...]
    worst_under: tuple[Spot, ...]
    by_feature: tuple[FeatureFlow, ...]
    rms_flow_error: float
    volume_error: float
    mean_slip: float
    ooze_mm3: float
    ooze_line: int
    narrow_beads: int
    lag_k_s: float
    fit: dict[str, object] | None
    advice: tuple[Advice, ...]

    def as_dict(self) -> dict[str, object]:
        """Plain JSON-able dict (non-finite numbers as ``None``)."""
        return _clean(asdict(self))  # type: ignore[return-value]

    def sentences(self) -> list[str]:
        """The verdict as plain sentences with units (headline first)."""
        g = self.grinding
        out = [self.headline]
        if math.isfinite(g.min_margin_n):
            out.append(f"Grinding: {g.level}. The smallest margin of the feed force to the "
                       f"roller's grip is {g.min_margin_n:.1f} N ({100 * g.min_margin_share:.0f} %"
                       f" of {g.grip_n:.0f} N) at line {g.line} (layer {g.layer}, "
                       f"{g.feature or 'no feature'}); peak force {g.max_force_n:.1f} N.")
        w = f"{self.window_mm:g} mm"
        for name, spot in (("over", self.over), ("under", self.under)):
            if spot is None:
                out.append(f"No window of {w} of path {name}-extrudes.")
                continue
            out.append(f"Worst {name}-extrusion over {w} of path: {_pct(spot.error)} "
                       f"({spot.excess_mm3:+.3f} mm³; bead {spot.width_nominal_mm:.2f} → "
                       f"{spot.width_predicted_mm:.2f} mm) at {_lines(spot)} "
                       f"(layer {spot.layer}, {spot.feature or 'no feature'}"
                       f"{', right after a retraction' if spot.after_retraction else ''}).")
        out.append(f"Volume: {_pct(self.volume_error)} over the print; RMS flow error per move "
                   f"{100 * self.rms_flow_error:.1f} %; drive slip {100 * self.mean_slip:.2f} %.")
        out.append(f"Ooze during travels and stops: {self.ooze_mm3:.2f} mm³"
                   + (f" (most at line {self.ooze_line})." if self.ooze_line > 0 else "."))
        out.append(f"Print time: {_duration(self.print_time_s)}.")
        return out


def build_verdict(result: SimulationResult, *, fit: AdvanceFit | None = None,
                  windowed: WindowedFlow | None = None) -> Verdict:
    """The verdict of ``result`` (see the module docstring).

    Parameters
    ----------
    result
        The simulation.
    fit
        The firmware pressure advance fitted on the same file and machine
        (:func:`flowtwin.compensation.best_pressure_advance`), if computed.
    windowed
        The windowed flow figures of ``result`` (default: :func:`result_windowed`).

    Returns
    -------
    Verdict
    """
    s = result.summary()
    win = windowed if windowed is not None else result_windowed(result)
    tab = result.plan.table
    m = tab.moves
    d = result.dynamics.moves
    names = tab.features
    ext = _extruding(result)
    path = move_paths_mm(result)
    spots_over, spots_under = locate_spots(result, win, path)
    grinding = _grinding(result, ext, s, path)
    k_lag = _lag_k(result, ext)
    ooze = np.asarray(d["ooze_mm3"], dtype=np.float64)
    ooze_line = int(m["line"][int(np.argmax(ooze))]) if ooze.size and ooze.max() > 0 else 0
    by_feature = []
    # one stable sort groups the extruding moves by feature, each group in move order: the
    # sums over a group's slice are those over its mask (the same values, the same order)
    rows = np.flatnonzero(ext)
    feat = m["feature"][rows].astype(np.int64)
    order = rows[np.argsort(feat, kind="stable")]
    keys, starts = np.unique(feat[np.argsort(feat, kind="stable")], return_index=True)
    bounds = np.append(starts, order.size)
    cmd_all = np.asarray(d["cmd_mm3"], dtype=np.float64)[order]
    err_all = np.asarray(result.metrics["flow_error"], dtype=np.float64)[order]
    dur_all = np.asarray(d["duration_s"], dtype=np.float64)[order]
    margin_all = np.asarray(result.metrics["force_margin_n"], dtype=np.float64)[order]
    over_all, under_all = win.move_max_error[order], win.move_min_error[order]
    for j, k in enumerate(keys.tolist()):
        g = slice(int(bounds[j]), int(bounds[j + 1]))
        cmd = cmd_all[g]
        err = err_all[g]
        wsum = float(np.sum(cmd))
        margin = margin_all[g]
        fin = margin[np.isfinite(margin)]
        by_feature.append(FeatureFlow(
            feature=_name(names, k), time_s=float(np.sum(dur_all[g])),
            commanded_mm3=wsum,
            rms_flow_error=float(np.sqrt(np.sum(cmd * err * err) / wsum)) if wsum > 0 else 0.0,
            worst_over=_nanext(np.nanmax, over_all[g]),
            worst_under=_nanext(np.nanmin, under_all[g]),
            min_margin_n=float(fin.min()) if fin.size else math.nan))
    over = spots_over[0] if spots_over else None
    under = spots_under[0] if spots_under else None
    fit_dict = None if fit is None else {
        "k_s": fit.k_s, "command": fit.command, "rms_at_best": fit.rms_at_best,
        "rms_without": fit.rms_without, "peak_at_best": fit.peak_at_best}
    slip = s.mean_slip
    advice = _advice(result, grinding, over, under, slip, k_lag, fit)
    headline = _headline(grinding, over, under, s.total_time_s, win.window_mm, bool(np.any(ext)))
    return Verdict(
        file=s.file, machine=s.machine, printer=s.printer, firmware=s.firmware,
        pressure_advance=s.pressure_advance, print_time_s=s.total_time_s,
        window_mm=win.window_mm, headline=headline, grinding=grinding, over=over,
        under=under, worst_over=spots_over, worst_under=spots_under,
        by_feature=tuple(by_feature),
        rms_flow_error=s.rms_flow_error, volume_error=s.volume_error,
        mean_slip=slip, ooze_mm3=s.ooze_volume_mm3,
        ooze_line=ooze_line, narrow_beads=s.narrow_beads,
        lag_k_s=k_lag, fit=fit_dict, advice=advice)


# ---- pieces ---------------------------------------------------------------------------------
def _extruding(result: SimulationResult) -> npt.NDArray[np.bool_]:
    kind = result.plan.table.moves["kind"].astype(np.int64)
    return (((kind & _PRINTING) == _PRINTING) & (result.dynamics.moves["cmd_mm3"] > 0))


def _name(names: list[str], k: int) -> str:
    return names[k] if 0 <= k < len(names) else ""


def _nanext(fn: object, a: npt.NDArray[np.float64]) -> float:
    fin = a[np.isfinite(a)]
    return float(fn(fin)) if fin.size else math.nan  # type: ignore[operator]


def _grinding(result: SimulationResult, ext: npt.NDArray[np.bool_], s: SimulationSummary,
              path: npt.NDArray[np.float64]) -> GrindingRisk:
    tab = result.plan.table
    m = tab.moves
    d = result.dynamics.moves
    pp = result.parameters.params
    grip = np.broadcast_to(np.asarray(pp.max_feed_force_n, dtype=np.float64), d.shape)
    safety = GuardOptions().safety
    margin = result.metrics["force_margin_n"]
    fin = np.flatnonzero(np.isfinite(margin))   # every move, as the summary's minimum
    if fin.size == 0:
        return GrindingRisk("safe", math.nan, math.nan, s.max_feed_force_n,
                            math.nan, 0, 0, 0, -1, "", safety, math.nan, math.nan)
    i = int(fin[np.argmin(margin[fin])])
    # force of every printing move: the larger of the predicted peak and the steady
    # K·Q/(A·k) of its intended flow Q (the guard's measure; the peak saturates when
    # grinding); the steady force follows the flow, so Q·safety·grip/F keeps it below
    cruise = np.asarray(result.plan.timeline.phases["cruise_v"], dtype=np.float64)
    cmd = np.asarray(d["cmd_mm3"], dtype=np.float64)
    lag = np.broadcast_to(np.asarray(pp.lag_k_s, dtype=np.float64), d.shape)
    comp = np.broadcast_to(np.asarray(pp.compliance_mm_per_n, dtype=np.float64), d.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.where(ext & (path > 0), cmd / path * cruise, 0.0)
        steady = lag * q / pp.filament_area_mm2 / comp
        q_steady_limit = safety * grip * pp.filament_area_mm2 * comp / lag
    force = np.maximum(np.asarray(d["peak_force_n"], dtype=np.float64), steady)
    use = ext & (q > 0) & (force > 0) & np.isfinite(grip)
    flow_limit = speed_limit = math.nan
    if np.any(use):
        flow_limit = float(np.min(q_steady_limit[use]))
        j = int(np.argmax(force[use] / grip[use]))
        speed_limit = float(cruise[use][j] * min(1.0, safety * grip[use][j] / force[use][j]))
    grinding_moves = s.grinding_moves
    share = float(margin[i] / grip[i]) if grip[i] > 0 else math.nan
    if grinding_moves > 0:
        level = "grinds"
    elif share < 1.0 - safety:
        level = "at risk"
    else:
        level = "safe"
    machine_limit = math.nan
    over = 0
    limits = result.parameters.flow_limit_mm3_s
    if limits is not None and np.any(use & np.isfinite(limits)):
        machine_limit = float(np.min(limits[use & np.isfinite(limits)]))
        flags = result.parameters.over_flow_limit
        over = int(np.count_nonzero(flags & ext)) if flags is not None else 0
    return GrindingRisk(level, float(margin[i]), share, s.max_feed_force_n,
                        float(grip[i]), grinding_moves,
                        s.grinding_events, int(m["line"][i]),
                        int(m["layer"][i]), _name(tab.features, int(m["feature"][i])), safety,
                        flow_limit, speed_limit, machine_limit, over)


def _lag_k(result: SimulationResult, ext: npt.NDArray[np.bool_]) -> float:
    k = np.broadcast_to(np.asarray(result.parameters.params.lag_k_s, dtype=np.float64),
                        ext.shape)
    w = np.asarray(result.dynamics.moves["cmd_mm3"], dtype=np.float64)[ext]
    return float(np.sum(k[ext] * w) / np.sum(w)) if w.size and np.sum(w) > 0 else math.nan


def _headline(g: GrindingRisk, over: Spot | None, under: Spot | None, time_s: float,
              window_mm: float, printed: bool) -> str:
    if not printed:
        return (f"Nothing is printed (no extruding move with XY motion); it takes "
                f"{_duration(time_s)}.")
    worst = max((abs(sp.error) for sp in (over, under) if sp is not None), default=0.0)
    if worst <= FLOW_OK:
        flow = f"extrudes within ±{100 * FLOW_OK:.0f} % of what it means everywhere"
    elif worst <= FLOW_VISIBLE:
        flow = (f"extrudes within ±{100 * worst:.0f} % of what it means over every "
                f"{window_mm:g} mm of path")
    else:
        parts = []
        if over is not None and over.error > FLOW_VISIBLE:
            parts.append(f"over-extrudes by up to {_pct(over.error)} (line {over.line})")
        if under is not None and -under.error > FLOW_VISIBLE:
            parts.append(f"under-extrudes by up to {_pct(under.error)} (line {under.line})")
        flow = " and ".join(parts) + f" over {window_mm:g} mm of path"
    grind = {"grinds": f"the drive grinds the filament ({g.grinding_moves} moves)",
             "at risk": (f"the drive comes within {g.min_margin_n:.1f} N of grinding "
                         f"({100 * g.min_margin_share:.0f} % margin)"),
             "safe": (f"no grinding risk ({g.min_margin_n:.0f} N margin)"
                      if math.isfinite(g.min_margin_n) else "no grinding risk")}[g.level]
    text = f"{grind}; the print {flow}; it takes {_duration(time_s)}."
    return text[0].upper() + text[1:]


def _advice(result: SimulationResult, g: GrindingRisk, over: Spot | None, under: Spot | None,
            slip: float, k_lag: float, fit: AdvanceFit | None) -> tuple[Advice, ...]:
    src = result.plan.table.source
    out: list[Advice] = []
    flags: list[str] = []
    if g.level != "safe" and math.isfinite(g.flow_limit_mm3_s):
        out.append(Advice(
            f"Keep the volumetric flow below {g.flow_limit_mm3_s:.1f} mm³/s (slicer: maximum "
            f"volumetric speed), or print {g.feature or 'the tightest move'} at most "
            f"{g.speed_limit_mm_s:.0f} mm/s (line {g.line}), to stay below "
            f"{100 * g.safety:.0f} % of the grip; or let the guard slow those moves.",
            f"flowtwin compensate {src} -o out.gcode --guard"))
        flags.append("--guard")
    elif math.isfinite(g.flow_limit_mm3_s) and not (
            g.machine_flow_limit_mm3_s < g.flow_limit_mm3_s):
        out.append(Advice(f"The drive has headroom up to about {g.flow_limit_mm3_s:.1f} mm³/s "
                          f"(at {100 * g.safety:.0f} % of the grip)."))
    if g.moves_over_machine_limit > 0:
        out.append(Advice(
            f"{g.moves_over_machine_limit} printing moves ask for more than the machine's "
            f"maximum volumetric flow of about {g.machine_flow_limit_mm3_s:.1f} mm³/s (the "
            "hot end's melt and the drive's slip at this layer height): set the slicer's "
            "maximum volumetric speed to that, or slow those moves.",
            f"flowtwin limits --temperature {result.parameters.temperature_c[0]:.0f}"
            if result.parameters.temperature_c.size else "flowtwin limits"))
    elif math.isfinite(g.machine_flow_limit_mm3_s) and (
            g.machine_flow_limit_mm3_s < g.flow_limit_mm3_s):
        out.append(Advice(f"The machine keeps up to about {g.machine_flow_limit_mm3_s:.1f} "
                          "mm³/s (its maximum volumetric flow: the hot end's melt and the "
                          "drive's slip)."))
    worst = max((abs(sp.error) for sp in (over, under) if sp is not None), default=0.0)
    if worst > FLOW_OK:
        if fit is not None:
            out.append(Advice(
                f"Set the firmware's pressure advance to K = {fit.k_s:.4g} s: the twin's RMS "
                f"flow error falls to {100 * fit.rms_at_best:.1f} % "
                f"(from {100 * fit.rms_without:.1f} % without advance).", fit.command))
        elif math.isfinite(k_lag):
            out.append(Advice(
                f"The melt lags the command by K ≈ {k_lag:.3f} s (the twin's lag factor); "
                "fit the firmware's pressure advance to this print.", f"flowtwin tune {src}"))
        out.append(Advice("Or bake the advance into the file (turn the firmware's off), "
                          "paced where the flow changes faster than the melt follows.",
                          f"flowtwin compensate {src} -o out.gcode --advance --pace"))
        flags += ["--advance", "--pace"]
    if slip > SLIP_NOTABLE:
        out.append(Advice(f"The drive slips {100 * slip:.1f} % on average: feed it forward.",
                          f"flowtwin compensate {src} -o out.gcode --slip"))
        flags.append("--slip")
    if len(flags) > 1:
        out.append(Advice("All together:",
                          f"flowtwin compensate {src} -o out.gcode " + " ".join(
                              dict.fromkeys(flags))))
    if not out:
        out.append(Advice("Nothing to change."))
    return tuple(out)


def _lines(s: Spot) -> str:
    return (f"line {s.line_first}" if s.line_first == s.line_last else
            f"lines {s.line_first}–{s.line_last}")


def _pct(v: float) -> str:
    return f"{100 * v:+.1f} %" if math.isfinite(v) else "–"


def _duration(seconds: float) -> str:
    if not math.isfinite(seconds):
        return "–"
    h, rem = divmod(seconds, 3600.0)
    m, s = divmod(rem, 60.0)
    if h >= 1:
        return f"{int(h)} h {int(m):02d} min"
    if m >= 1:
        return f"{int(m)} min {int(s):02d} s"
    return f"{s:.1f} s"


def _clean(v: object) -> object:
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    if isinstance(v, dict):
        return {k: _clean(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_clean(x) for x in v]
    return v
