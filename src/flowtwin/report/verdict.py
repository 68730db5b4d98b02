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
:data:`SLIP_NOTABLE`, :data:`OOZE_NOTABLE_MM3`); they are reporting conventions, not
physics, and are stated in ``docs/report.md``. The grinding safety share is the grinding
guard's (:class:`flowtwin.compensation.GuardOptions`), so the advice and the guard agree.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from flowtwin.compensation.guard import GuardOptions
from flowtwin.errors import DataError
from flowtwin.gcode.moves import MoveKind
from flowtwin.simulation import SimulationResult
from flowtwin.simulation.windowed import Window, WindowedFlow, path_lengths_mm, windowed_flow

if TYPE_CHECKING:
    from flowtwin.compensation.settings import AdvanceFit

__all__ = ["FLOW_OK", "FLOW_VISIBLE", "OOZE_NOTABLE_MM3", "SLIP_NOTABLE", "Advice",
           "FeatureFlow", "GrindingRisk", "Spot", "Verdict", "build_verdict",
           "locate_spots", "result_windowed"]

#: Windowed flow errors within ±5 % are called fine.
FLOW_OK = 0.05
#: Beyond ±15 % a window is called a visible defect (bulge or gap).
FLOW_VISIBLE = 0.15
#: Mean drive slip above 1 % is worth feeding forward (``compensate --slip``).
SLIP_NOTABLE = 0.01
#: Ooze above 1 mm³ over the print is mentioned with its worst place.
OOZE_NOTABLE_MM3 = 1.0
_BEAD = 1.0 - math.pi / 4.0
_PRINTING = int(MoveKind.EXTRUDE | MoveKind.XY)


@dataclass(frozen=True, slots=True)
class Spot:
    """One window of one nozzle diameter of path, located in the G-code.

    Attributes
    ----------
    error
        Flow error over the window, delivered / commanded − 1 (fraction).
    excess_mm3
        Delivered − commanded melt over the window, mm³.
    length_mm
        Path length of the window, mm.
    line, line_first, line_last
        G-code line of the move at the window's middle, of its first and its last move.
    layer, z_mm, feature
        Where it is.
    width_nominal_mm, width_predicted_mm
        Bead width the G-code means and the twin predicts over the window, mm.
    after_retraction
        The window starts a printed stretch that follows a retraction (a seam or a restart).
    """

    error: float
    excess_mm3: float
    length_mm: float
    line: int
    line_first: int
    line_last: int
    layer: int
    z_mm: float
    feature: str
    width_nominal_mm: float
    width_predicted_mm: float
    after_retraction: bool


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


def result_windowed(result: SimulationResult, *, delivered_mm3: npt.ArrayLike | None = None,
                    window_mm: float | None = None, spots: int = 10) -> WindowedFlow:
    """Windowed flow error of a simulation over one nozzle diameter of path.

    The moves scored are the twin's (extruding, with XY motion, a commanded volume and a
    bead), as :func:`flowtwin.compensation.metrics.flow_figures` scores them.

    Parameters
    ----------
    result
        The simulation.
    delivered_mm3
        Delivered melt per move of ``result`` (default: the simulation's own); a
        compensated file's delivery mapped onto the original moves gives its figures
        against the original intent. Shape ``(n_moves,)``.
    window_mm
        Window length, mm (default: the nozzle diameter of the simulated machine).
    spots
        Worst separate windows to locate each way.
    """
    tab = result.plan.table
    m = tab.moves
    xyz = np.column_stack([m["x"], m["y"], m["z"]]).astype(np.float64)
    path = path_lengths_mm(xyz, np.asarray(tab.start_xyze[:3], dtype=np.float64))
    cmd = np.asarray(result.dynamics.moves["cmd_mm3"], dtype=np.float64)
    dlv = (np.asarray(result.dynamics.moves["out_mm3"], dtype=np.float64)
           if delivered_mm3 is None else np.asarray(delivered_mm3, dtype=np.float64))
    kind = m["kind"].astype(np.int64)
    printed = (((kind & _PRINTING) == _PRINTING) & (cmd > 0)
               & np.isfinite(result.metrics["width_nominal_mm"]) & (path > 0))
    w = float(window_mm if window_mm is not None else result.nozzle_diameter_mm)
    if not math.isfinite(w):
        meta = tab.metadata.get("nozzle_diameter_mm", tab.metadata.get("nozzle_diameter"))
        try:
            w = float(str(meta).split(",")[0])
        except ValueError:
            raise DataError("the nozzle diameter of this simulation is unknown",
                            field="nozzle_diameter_mm", value=meta,
                            allowed="a result of flowtwin.simulation.simulate, or window_mm"
                            ) from None
    return windowed_flow(path, cmd, dlv, printed, window_mm=w, spots=spots)


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
    path = _path(result)
    spots_over, spots_under = locate_spots(result, win, path)
    grinding = _grinding(result, ext, s, path)
    k_lag = _lag_k(result, ext)
    ooze = np.asarray(d["ooze_mm3"], dtype=np.float64)
    ooze_line = int(m["line"][int(np.argmax(ooze))]) if ooze.size and ooze.max() > 0 else 0
    by_feature = []
    feat = m["feature"].astype(np.int64)
    for k in np.unique(feat[ext]).tolist():
        sel = ext & (feat == k)
        cmd = d["cmd_mm3"][sel]
        err = result.metrics["flow_error"][sel]
        wsum = float(np.sum(cmd))
        margin = result.metrics["force_margin_n"][sel]
        fin = margin[np.isfinite(margin)]
        by_feature.append(FeatureFlow(
            feature=_name(names, k), time_s=float(np.sum(d["duration_s"][sel])),
            commanded_mm3=wsum,
            rms_flow_error=float(np.sqrt(np.sum(cmd * err * err) / wsum)) if wsum > 0 else 0.0,
            worst_over=_nanext(np.nanmax, win.move_max_error[sel]),
            worst_under=_nanext(np.nanmin, win.move_min_error[sel]),
            min_margin_n=float(fin.min()) if fin.size else math.nan))
    over = spots_over[0] if spots_over else None
    under = spots_under[0] if spots_under else None
    fit_dict = None if fit is None else {
        "k_s": fit.k_s, "command": fit.command, "rms_at_best": fit.rms_at_best,
        "rms_without": fit.rms_without, "peak_at_best": fit.peak_at_best}
    slip = float(s["mean_slip"])  # type: ignore[arg-type]
    advice = _advice(result, grinding, over, under, slip, k_lag, fit)
    headline = _headline(grinding, over, under, float(s["total_time_s"]),  # type: ignore[arg-type]
                         win.window_mm)
    return Verdict(
        file=str(s["file"]), machine=str(s["machine"]), printer=str(s["printer"]),
        firmware=str(s["firmware"]), pressure_advance=str(s["pressure_advance"]),
        print_time_s=float(s["total_time_s"]),  # type: ignore[arg-type]
        window_mm=win.window_mm, headline=headline, grinding=grinding, over=over,
        under=under, worst_over=spots_over, worst_under=spots_under,
        by_feature=tuple(by_feature),
        rms_flow_error=float(s["rms_flow_error"]),  # type: ignore[arg-type]
        volume_error=float(s["volume_error"]),  # type: ignore[arg-type]
        mean_slip=slip, ooze_mm3=float(s["ooze_volume_mm3"]),  # type: ignore[arg-type]
        ooze_line=ooze_line, narrow_beads=int(s["narrow_beads"]),  # type: ignore[call-overload]
        lag_k_s=k_lag, fit=fit_dict, advice=advice)


def locate_spots(result: SimulationResult, windowed: WindowedFlow,
                 path_mm: npt.NDArray[np.float64] | None = None
                 ) -> tuple[tuple[Spot, ...], tuple[Spot, ...]]:
    """The worst windows of ``windowed`` (figures on ``result``'s moves) located in the
    G-code: ``(over, under)``, worst first."""
    path = _path(result) if path_mm is None else path_mm
    return (tuple(_spot(result, w, path) for w in windowed.worst_over),
            tuple(_spot(result, w, path) for w in windowed.worst_under))


# ---- pieces ---------------------------------------------------------------------------------
def _path(result: SimulationResult) -> npt.NDArray[np.float64]:
    m = result.plan.table.moves
    return path_lengths_mm(np.column_stack([m["x"], m["y"], m["z"]]).astype(np.float64),
                           np.asarray(result.plan.table.start_xyze[:3], dtype=np.float64))



def _extruding(result: SimulationResult) -> npt.NDArray[np.bool_]:
    kind = result.plan.table.moves["kind"].astype(np.int64)
    return (((kind & _PRINTING) == _PRINTING) & (result.dynamics.moves["cmd_mm3"] > 0))


def _name(names: list[str], k: int) -> str:
    return names[k] if 0 <= k < len(names) else ""


def _nanext(fn: object, a: npt.NDArray[np.float64]) -> float:
    fin = a[np.isfinite(a)]
    return float(fn(fin)) if fin.size else math.nan  # type: ignore[operator]


def _spot(result: SimulationResult, w: Window, path: npt.NDArray[np.float64]) -> Spot:
    tab = result.plan.table
    m = tab.moves
    c = w.centre_move
    h = float(result.parameters.layer_height_mm[c])
    length = max(w.length_mm, 1e-12)

    def width(volume: float) -> float:
        return volume / length / h + _BEAD * h if h > 0 else math.nan

    layer = int(m["layer"][c])
    z = float(m["z"][c])
    after = _after_retraction(m["kind"].astype(np.int64), path, w.first_move)
    return Spot(error=w.error, excess_mm3=w.delivered_mm3 - w.commanded_mm3,
                length_mm=w.length_mm, line=int(m["line"][c]),
                line_first=int(m["line"][w.first_move]), line_last=int(m["line"][w.last_move]),
                layer=layer, z_mm=z, feature=_name(tab.features, int(m["feature"][c])),
                width_nominal_mm=width(w.commanded_mm3),
                width_predicted_mm=width(w.delivered_mm3), after_retraction=after)


#: A window this close (path, mm) to the start of a stretch that follows a retraction is
#: called "right after a retraction".
_RESTART_MM = 2.0


def _after_retraction(kind: npt.NDArray[np.int64], path: npt.NDArray[np.float64],
                      move: int) -> bool:
    """``move`` lies within :data:`_RESTART_MM` of path after the start of a printed stretch
    that a retraction (negative E, among the 50 moves before it) precedes."""
    k = move - 1
    walked = 0.0
    while k >= 0 and (kind[k] & _PRINTING) == _PRINTING:
        walked += float(path[k])
        if walked > _RESTART_MM:
            return False
        k -= 1
    stop = k - 50
    while k >= 0 and k > stop and (kind[k] & _PRINTING) != _PRINTING:
        if kind[k] & int(MoveKind.RETRACT):
            return True
        k -= 1
    return False


def _grinding(result: SimulationResult, ext: npt.NDArray[np.bool_], s: dict[str, object],
              path: npt.NDArray[np.float64]) -> GrindingRisk:
    tab = result.plan.table
    m = tab.moves
    d = result.dynamics.moves
    pp = result.parameters.params
    grip = np.broadcast_to(np.asarray(pp.max_feed_force_n, dtype=np.float64), d.shape)
    safety = GuardOptions().safety
    margin = result.metrics["force_margin_n"]
    fin = np.flatnonzero(np.isfinite(margin))
    if fin.size == 0:
        return GrindingRisk("safe", math.nan, math.nan, float(s["max_feed_force_n"]),  # type: ignore[arg-type]
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
    grinding_moves = int(s["grinding_moves"])  # type: ignore[call-overload]
    share = float(margin[i] / grip[i]) if grip[i] > 0 else math.nan
    if grinding_moves > 0:
        level = "grinds"
    elif share < 1.0 - safety:
        level = "at risk"
    else:
        level = "safe"
    return GrindingRisk(level, float(margin[i]), share, float(s["max_feed_force_n"]),  # type: ignore[arg-type]
                        float(grip[i]), grinding_moves,
                        int(s["grinding_events"]), int(m["line"][i]),  # type: ignore[call-overload]
                        int(m["layer"][i]), _name(tab.features, int(m["feature"][i])), safety,
                        flow_limit, speed_limit)


def _lag_k(result: SimulationResult, ext: npt.NDArray[np.bool_]) -> float:
    k = np.broadcast_to(np.asarray(result.parameters.params.lag_k_s, dtype=np.float64),
                        ext.shape)
    w = np.asarray(result.dynamics.moves["cmd_mm3"], dtype=np.float64)[ext]
    return float(np.sum(k[ext] * w) / np.sum(w)) if w.size and np.sum(w) > 0 else math.nan


def _headline(g: GrindingRisk, over: Spot | None, under: Spot | None, time_s: float,
              window_mm: float) -> str:
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
    elif math.isfinite(g.flow_limit_mm3_s):
        out.append(Advice(f"The drive has headroom up to about {g.flow_limit_mm3_s:.1f} mm³/s "
                          f"(at {100 * g.safety:.0f} % of the grip)."))
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
