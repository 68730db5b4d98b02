"""``compensate``: make a G-code extrude what it means, on a given machine.

Stages, each optional, each composed on a :class:`~flowtwin.compensation.draft.Draft` of
the original file (untouched lines stay byte for byte):

1. **trajectory** [004] — nozzle paths that lay the intended road at corners
   (:mod:`flowtwin.compensation.trajectory`);
2. **guard** [000 §4] — slower moves where the feed force would grind the filament
   (:mod:`flowtwin.compensation.guard`);
2b. **pace** — slower stretches where the intended flow would change faster than the
   melt's lag lets it follow (:mod:`flowtwin.compensation.pace`);
3. **advance** [001 Eqs. 11, 13] — pressure advance baked into the E of pieces cut at the
   planner's phase boundaries, refined with the twin's lag model, in two passes (the
   second on the re-planned first result) (:mod:`flowtwin.compensation.bake`);
4. **slip** [000 §6] — E scaled by ``1/(1 − s)`` with the slip the twin predicts
   (:mod:`flowtwin.compensation.slip`).

Every stage that needs the twin renders the draft to a temporary file and simulates it
(:func:`flowtwin.simulation.simulate`), so it always sees what the firmware will plan.
The original and the result are simulated on the same machine and compared move by move
against the original intent (:mod:`flowtwin.compensation.metrics`).
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt

from flowtwin.compensation.advance import AdvanceOptions, eligible_rows
from flowtwin.compensation.bake import PassReport, advance_pass
from flowtwin.compensation.draft import Draft
from flowtwin.compensation.guard import GuardOptions, guard_feeds
from flowtwin.compensation.limits import ExtruderLimits, extruder_limits
from flowtwin.compensation.metrics import FlowFigures, flow_figures
from flowtwin.compensation.pace import PaceOptions, PaceReport, pace_feeds
from flowtwin.compensation.slip import SlipOptions, slip_feedforward
from flowtwin.compensation.source import ScannedSource, read_source, row_e_grid, scan_source
from flowtwin.compensation.trajectory import TrajectoryOptions, TrajectoryReport, bend_paths
from flowtwin.errors import DataError, GcodeError
from flowtwin.gcode.moves import MoveKind
from flowtwin.planner.from_profile import read_options
from flowtwin.planner.klipper_config import klipper_read_options, load_printer_cfg
from flowtwin.profiles.machine import Machine, load_machine
from flowtwin.profiles.setup import SetupProfile
from flowtwin.simulation import DEFAULT_MACHINE, SimulationResult, simulate

__all__ = ["CompensationReport", "compensate", "lag_factor_changes"]

Progress = Callable[[str], None]

#: The advance keeps the predicted feed force below this share of the grinding limit.
_GRIND_MARGIN = 0.9


@dataclass(slots=True)
class CompensationReport:
    """What ``compensate`` did and what the twin predicts before and after.

    Attributes
    ----------
    source, destination
        The files.
    machine
        Name of the set-up simulated.
    firmware_pressure_advance
        Whether the simulations include the firmware's own pressure advance.
    transformations
        Names of the stages that ran.
    before, after
        Flow figures of the original and of the compensated file, both against the
        original intent (:class:`~flowtwin.compensation.metrics.FlowFigures`).
    time_before_s, time_after_s
        Planned print time, s.
    commanded_e_before_mm, commanded_e_after_mm
        Total E written in the G-code (before M221), mm of filament.
    added_volume_mm3
        Volume the slip feed-forward added (mm³ of melt; 0 without it).
    slowed_moves
        Source lines the grinding guard slowed.
    guard_time_cost_s
        Print time the guard added (planned with and without it), s.
    grinding_moves_before, grinding_moves_after
        Moves the twin flags as grinding.
    max_force_before_n, max_force_after_n
        Largest predicted feed force, N.
    advance
        Figures of the advance passes (pieces, runs, clipping counts, refinement).
    trajectory
        Figures of the trajectory stage, or ``None``.
    limits
        The firmware limits the advance respected.
    lines_rewritten
        Source lines replaced (motion lines only).
    warnings
        Everything the user should know.
    seconds
        Wall time of the compensation.
    lag_factor_changed_moves
        Original moves some piece of which the twin simulates with a different lag factor
        than the move itself (:func:`lag_factor_changes`; 0 when the twin is consistent).
    paced_moves
        Source lines the flow pacing slowed (part of).
    pace_time_cost_s
        Print time the pacing added (re-planned with and without it), s.
    pace
        Figures of the pacing stage (:class:`~flowtwin.compensation.pace.PaceReport`), or
        ``None``.
    original_result, compensated_result, piece_row
        The two simulations and the original move of every compensated move (for the
        before/after report, :func:`flowtwin.report.write_comparison`).
    """

    source: str
    destination: str
    machine: str
    firmware_pressure_advance: bool
    transformations: list[str]
    before: FlowFigures
    after: FlowFigures
    time_before_s: float
    time_after_s: float
    commanded_e_before_mm: float
    commanded_e_after_mm: float
    added_volume_mm3: float = 0.0
    slowed_moves: list[int] = field(default_factory=list)
    guard_time_cost_s: float = 0.0
    grinding_moves_before: int = 0
    grinding_moves_after: int = 0
    max_force_before_n: float = 0.0
    max_force_after_n: float = 0.0
    advance: list[dict[str, object]] = field(default_factory=list)
    trajectory: dict[str, object] | None = None
    limits: dict[str, object] = field(default_factory=dict)
    lines_rewritten: int = 0
    warnings: list[str] = field(default_factory=list)
    seconds: float = 0.0
    lag_factor_changed_moves: int = 0
    paced_moves: list[int] = field(default_factory=list)
    pace_time_cost_s: float = 0.0
    pace: dict[str, object] | None = None
    original_result: SimulationResult | None = field(default=None, repr=False)
    compensated_result: SimulationResult | None = field(default=None, repr=False)
    piece_row: npt.NDArray[np.int64] | None = field(default=None, repr=False)

    def _repr_html_(self) -> str:
        from flowtwin.report.notebook import compensation_repr
        return compensation_repr(self)

    def summary(self) -> dict[str, object]:
        """The figures as plain JSON-able values (the ``--json`` object)."""
        def ratio(a: float, b: float) -> float | None:
            return a / b if b > 0 else None

        return {
            "file": self.source, "output": self.destination, "machine": self.machine,
            "firmware_pressure_advance": self.firmware_pressure_advance,
            "transformations": list(self.transformations),
            "rms_flow_error_before": self.before.rms_flow_error,
            "rms_flow_error_after": self.after.rms_flow_error,
            "rms_improvement": ratio(self.before.rms_flow_error, self.after.rms_flow_error),
            "peak_overextrusion_before": self.before.peak_overextrusion,
            "peak_overextrusion_after": self.after.peak_overextrusion,
            "peak_improvement": ratio(self.before.peak_overextrusion,
                                      self.after.peak_overextrusion),
            "peak_overextrusion_window_before": self.before.peak_overextrusion_window,
            "peak_overextrusion_window_after": self.after.peak_overextrusion_window,
            "peak_window_improvement": ratio(self.before.peak_overextrusion_window,
                                             self.after.peak_overextrusion_window),
            "peak_window_mm": self.before.window_mm,
            "peak_underextrusion_before": self.before.peak_underextrusion,
            "peak_underextrusion_after": self.after.peak_underextrusion,
            "delivered_volume_before_mm3": self.before.delivered_volume_mm3,
            "delivered_volume_after_mm3": self.after.delivered_volume_mm3,
            "intended_volume_mm3": self.before.intended_volume_mm3,
            "commanded_e_before_mm": self.commanded_e_before_mm,
            "commanded_e_after_mm": self.commanded_e_after_mm,
            "added_volume_mm3": self.added_volume_mm3,
            "slowed_moves": len(self.slowed_moves),
            "slowed_lines": list(self.slowed_moves[:1000]),
            "guard_time_cost_s": self.guard_time_cost_s,
            "paced_moves": len(self.paced_moves),
            "paced_lines": list(self.paced_moves[:1000]),
            "pace_time_cost_s": self.pace_time_cost_s, "pace": self.pace,
            "time_before_s": self.time_before_s, "time_after_s": self.time_after_s,
            "grinding_moves_before": self.grinding_moves_before,
            "grinding_moves_after": self.grinding_moves_after,
            "max_force_before_n": self.max_force_before_n,
            "max_force_after_n": self.max_force_after_n,
            "advance": list(self.advance), "trajectory": self.trajectory,
            "limits": dict(self.limits), "lines_rewritten": self.lines_rewritten,
            "lag_factor_changed_moves": self.lag_factor_changed_moves,
            "warnings": list(self.warnings), "seconds": self.seconds,
        }


def _option(value: object, cls: type) -> object | None:
    if value is None or value is False:
        return None
    if value is True:
        return cls()
    if not isinstance(value, cls):
        raise DataError("invalid option object", field=cls.__name__, value=type(value).__name__,
                        allowed=f"True, False, None or a {cls.__name__}")
    return value


def _printing(sim: SimulationResult, draft: Draft) -> npt.NDArray[np.bool_]:
    """Pieces that print: of a printing original move, with XY motion and positive E."""
    kind = sim.plan.table.moves["kind"]
    orig = eligible_rows(draft.table, draft.row_e)
    return orig[draft.row] & ((kind & MoveKind.XY) != 0) & (draft.e_grid > 0)


def _checked(sim: SimulationResult, draft: Draft, path: Path) -> SimulationResult:
    if len(sim.plan.table) != len(draft):
        raise GcodeError("the rewritten file does not read back as the pieces written "
                         f"({len(sim.plan.table)} moves, {len(draft)} pieces)", source=path,
                         allowed="a reader/writer round trip that keeps every piece")
    return sim


def compensate(source: str | os.PathLike[str], destination: str | os.PathLike[str], *,
               machine: Machine | SetupProfile | str | os.PathLike[str] | None = None,
               klipper_config: str | os.PathLike[str] | None = None,
               advance: AdvanceOptions | bool | None = None,
               slip: SlipOptions | bool | None = None,
               guard: GuardOptions | bool | None = None,
               trajectory: TrajectoryOptions | bool | None = None,
               pace: PaceOptions | bool | None = None,
               firmware_pressure_advance: bool | None = None, advance_passes: int = 2,
               progress: Progress | None = None) -> CompensationReport:
    """Compensate ``source`` for ``machine`` and write ``destination`` (atomically).

    Parameters
    ----------
    source
        The G-code to compensate (plain or gzip; a path).
    destination
        Where to write the result (may be ``source``); written atomically.
    machine
        The set-up (object, built-in name or TOML); default the twin's
        (:data:`flowtwin.simulation.DEFAULT_MACHINE`).
    klipper_config
        Plan with this Klipper ``printer.cfg`` instead of the set-up's printer.
    advance, slip, guard, trajectory
        ``True`` (defaults), an options object, or ``None``/``False`` (off). With all off
        the output is a byte-identical copy.
    pace
        Flow pacing (:mod:`flowtwin.compensation.pace`), after the guard and before the
        advance: ``True``, a :class:`~flowtwin.compensation.pace.PaceOptions`, or off.
    firmware_pressure_advance
        Simulate the firmware's own pressure advance; default: off when the advance is
        baked into the file (the firmware's must then be off), else on.
    advance_passes
        Advance passes (1 or 2; the second corrects for the re-planned timing).
    progress
        Called with the name of each stage as it starts.

    Returns
    -------
    CompensationReport

    Raises
    ------
    GcodeError, ProfileError
        Unreadable or unsupported G-code, bad profiles or options.
    """
    t_start = time.perf_counter()
    step = progress or (lambda _name: None)
    adv = _option(advance, AdvanceOptions)
    sl = _option(slip, SlipOptions)
    gd = _option(guard, GuardOptions)
    tr = _option(trajectory, TrajectoryOptions)
    pc = _option(pace, PaceOptions)
    assert pc is None or isinstance(pc, PaceOptions)
    assert adv is None or isinstance(adv, AdvanceOptions)
    assert sl is None or isinstance(sl, SlipOptions)
    assert gd is None or isinstance(gd, GuardOptions)
    assert tr is None or isinstance(tr, TrajectoryOptions)
    if advance_passes not in (1, 2, 3):
        raise DataError("advance passes must be 1, 2 or 3", field="advance_passes",
                        value=advance_passes, allowed="1, 2, 3")
    m = machine if isinstance(machine, Machine) else load_machine(machine or DEFAULT_MACHINE)
    pa = (adv is None) if firmware_pressure_advance is None else bool(firmware_pressure_advance)
    src = Path(source)
    dst = Path(destination)

    def sim(path: Path) -> SimulationResult:
        return simulate(path, machine=m, klipper_config=klipper_config, pressure_advance=pa)

    step("simulate original")
    original = sim(src)
    table = original.plan.table
    text = read_source(src)
    if klipper_config is not None:
        home = klipper_read_options(load_printer_cfg(klipper_config)).home_xyz
    else:
        home = read_options(m.printer).home_xyz
    scanned = scan_source(text, table, home_xyz=home)
    row_e = row_e_grid(scanned, table)
    draft = Draft.identity(scanned, table, row_e)
    limits = extruder_limits(original.plan.settings)
    names: list[str] = []
    warnings: list[str] = []
    advance_reports: list[dict[str, object]] = []
    traj_report: TrajectoryReport | None = None
    slowed = np.zeros(len(table), dtype=bool)
    guard_cost = 0.0
    pace_cost = 0.0
    pace_report: PaceReport | None = None
    added_grid = 0
    with tempfile.TemporaryDirectory(prefix="flowtwin-compensate-") as tmpdir:
        work = Path(tmpdir) / ("draft" + "".join(src.suffixes[-1:]) if src.suffix else "draft")
        current = original

        def refresh(d: Draft) -> SimulationResult:
            d.render(work)
            return _checked(sim(work), d, work)

        if tr is not None and not tr.is_identity:
            step("trajectory")
            names.append("trajectory")
            draft, traj_report = bend_paths(draft, current, tr)
            current = refresh(draft)
        if gd is not None:
            step("guard")
            names.append("guard")
            time0 = current.plan.timeline.total_time_s
            for _ in range(gd.iterations):
                draft, now = _guard_step(draft, current, scanned, gd)
                if not np.any(now):
                    break
                slowed |= now
                current = refresh(draft)
            guard_cost = current.plan.timeline.total_time_s - time0
        if pc is not None:
            step("pace")
            time0 = current.plan.timeline.total_time_s
            draft, pace_report = _pace_step(draft, current, scanned, limits,
                                            float(m.filament.area_mm2), pc)
            if pace_report.paced_rows.size:
                names.append("pace")
                current = refresh(draft)
                pace_cost = current.plan.timeline.total_time_s - time0
        if adv is not None and not adv.is_identity:
            step("advance")
            # the advance is computed for the file without the firmware's own advance
            cur = current if not pa else simulate(work if names else src, machine=m,
                                                  klipper_config=klipper_config,
                                                  pressure_advance=False)
            pre_advance = draft
            kept_draft, kept_sim = draft, cur
            kept_rms = flow_figures(original, cur, draft.row).rms_flow_error
            # every later pass first with the twin's correction of the model, then (if
            # that raised the twin's RMS) without it
            attempts = [(k, k > 0) for k in range(advance_passes)]
            attempts = [a for k, ilc in attempts for a in ([(k, True), (k, False)] if ilc
                                                          else [(k, False)])]
            done: set[int] = set()
            for k, ilc in attempts:
                if k in done:
                    continue
                pp = cur.parameters.params
                # compression at which the feed force reaches the grinding limit (margin)
                cap = (_GRIND_MARGIN * np.asarray(pp.max_feed_force_n, dtype=np.float64)
                       * np.asarray(pp.compliance_mm_per_n, dtype=np.float64) / scanned.e_unit)
                seen = _delivered_grid(original, cur, draft) if ilc else None
                draft, rep = advance_pass(draft, cur.plan.table, cur.plan.timeline,
                                          pp.lag_k_s, limits, adv, e_unit_mm=scanned.e_unit,
                                          split=k == 0, relief=(k == 0 and adv.relief),
                                          state_max=cap, delivered=seen)
                draft.render(work)
                cur = _checked(simulate(work, machine=m, klipper_config=klipper_config,
                                        pressure_advance=False), draft, work)
                rms = flow_figures(original, cur, draft.row).rms_flow_error
                entry = _pass_dict(rep)
                entry["rms_flow_error"] = rms
                entry["twin_correction"] = ilc
                advance_reports.append(entry)
                if ilc and rms > kept_rms:
                    entry["kept"] = False
                    draft, cur = kept_draft, kept_sim
                    continue  # the same pass again, without the correction
                done.add(k)
                if rms <= kept_rms:
                    kept_draft, kept_sim, kept_rms = draft, cur, rms
                else:
                    entry["kept"] = False
                    warnings.append(f"advance pass {k + 1} raised the twin's RMS flow error "
                                    f"(to {100 * rms:.2f} % from {100 * kept_rms:.2f} %): "
                                    "its result is not used")
                    draft, cur = kept_draft, kept_sim
                    break
            if kept_draft is not pre_advance:
                names.append("advance")
            draft = kept_draft
            current = kept_sim if not pa else refresh(draft)
        if sl is not None and not sl.is_identity:
            step("slip")
            base = draft.e_grid.copy()
            printing = _printing(current, draft)
            before_slip = (draft, current)
            rms0 = flow_figures(original, current, draft.row).rms_flow_error
            for _ in range(sl.iterations):
                draft = slip_feedforward(draft, base, printing,
                                         current.dynamics.moves["slip"], sl)
                current = refresh(draft)
            rms1 = flow_figures(original, current, draft.row).rms_flow_error
            if rms1 > rms0:
                warnings.append(f"the slip feed-forward raised the twin's RMS flow error (to "
                                f"{100 * rms1:.2f} % from {100 * rms0:.2f} %; the drive is "
                                "near grinding, try --guard): it is not used")
                draft, current = before_slip
            else:
                names.append("slip")
                added_grid = int(np.sum(draft.e_grid[printing]) - np.sum(base[printing]))
        step("write")
        result = draft.render(dst)
        step("simulate result")
        after_sim = _checked(sim(dst), draft, dst)
    window = float(m.hotend.nozzle_diameter_mm)
    before = flow_figures(original, original, np.arange(len(table), dtype=np.int64),
                          window_mm=window)
    after = flow_figures(original, after_sim, draft.row, window_mm=window)
    area = m.filament.area_mm2
    flow = after_sim.plan.table.moves["flow"].astype(np.float64)
    pr = _printing(after_sim, draft)
    summary0 = original.summary()
    summary1 = after_sim.summary()
    warnings.extend(str(w) for w in after_sim.warnings if w not in original.warnings)
    changed_k = lag_factor_changes(original, after_sim, draft.row)
    if changed_k.size:
        k0 = np.asarray(original.parameters.params.lag_k_s, dtype=np.float64)
        k1 = np.asarray(after_sim.parameters.params.lag_k_s, dtype=np.float64)
        worst = int(np.argmax(np.abs(np.log(k1 / k0[draft.row]))))
        lines = table.moves["line"][changed_k]
        warnings.append(
            f"the twin's lag factor of {changed_k.size} moves (lines "
            f"{', '.join(str(int(x)) for x in lines[:5])}{' …' if lines.size > 5 else ''}) "
            f"differs between the original and the compensated file (e.g. line "
            f"{int(table.moves['line'][draft.row[worst]])}: K {k0[draft.row[worst]]:.3g} s → "
            f"{k1[worst]:.3g} s): the twin's parameters of a move depend on how it is cut "
            "(a layer height read from where the layer's first extrusion ends, in spiral "
            "layers); before and after are then not predicted on the same physics")
    if adv is not None and (m.printer.pressure_advance.k_s > 0 or _has_pa_commands(original)):
        warnings.append("the advance is baked into the file: turn the firmware's pressure "
                        "advance off (M900 K0 / M572 S0 / SET_PRESSURE_ADVANCE ADVANCE=0) "
                        "when printing it")
    return CompensationReport(
        source=str(src), destination=str(dst), machine=m.name,
        firmware_pressure_advance=pa, transformations=names, before=before, after=after,
        time_before_s=float(original.plan.timeline.total_time_s),
        time_after_s=float(after_sim.plan.timeline.total_time_s),
        commanded_e_before_mm=float(np.sum(row_e) * scanned.e_unit),
        commanded_e_after_mm=float(np.sum(draft.e_grid) * scanned.e_unit),
        added_volume_mm3=float(added_grid * scanned.e_unit * area
                               * (float(np.mean(flow[pr])) if np.any(pr) else 1.0)),
        slowed_moves=[int(x) for x in table.moves["line"][slowed].tolist()],
        guard_time_cost_s=float(guard_cost),
        grinding_moves_before=int(summary0["grinding_moves"]),  # type: ignore[call-overload]
        grinding_moves_after=int(summary1["grinding_moves"]),  # type: ignore[call-overload]
        max_force_before_n=float(summary0["max_feed_force_n"]),  # type: ignore[arg-type]
        max_force_after_n=float(summary1["max_feed_force_n"]),  # type: ignore[arg-type]
        advance=advance_reports,
        trajectory=None if traj_report is None else traj_report.as_dict(),
        limits=limits.as_dict(), lines_rewritten=result.lines_rewritten,
        warnings=warnings, seconds=time.perf_counter() - t_start,
        lag_factor_changed_moves=int(changed_k.size),
        paced_moves=([] if pace_report is None else
                     [int(x) for x in table.moves["line"][pace_report.paced_rows].tolist()]),
        pace_time_cost_s=float(pace_cost),
        pace=None if pace_report is None else pace_report.as_dict(),
        original_result=original, compensated_result=after_sim,
        piece_row=np.asarray(draft.row, dtype=np.int64))


#: Relative change of a piece's lag factor against its original move's that is reported.
_LAG_TOLERANCE = 0.01


def lag_factor_changes(original: SimulationResult, compensated: SimulationResult,
                       piece_row: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
    """Original moves some piece of which the twin gives a different lag factor ``K``.

    Cutting a move into pieces changes no physics, so the twin should give every piece
    its move's ``K`` (temperature and layer height are the same); where it does not (more
    than 1 % apart), before/after figures compare two different models of the printer.

    Parameters
    ----------
    original, compensated
        The original and the compensated file simulated on the same machine.
    piece_row
        Original move of every compensated move, shape ``(n_pieces,)``.

    Returns
    -------
    ndarray of int64
        Sorted indices of the original moves concerned.
    """
    k0 = np.asarray(original.parameters.params.lag_k_s, dtype=np.float64)
    k1 = np.asarray(compensated.parameters.params.lag_k_s, dtype=np.float64)
    if k1.shape != piece_row.shape:
        raise DataError("piece map does not match the compensated moves", field="piece_row",
                        value=piece_row.shape, allowed=str(k1.shape))
    off = np.abs(k1 - k0[piece_row]) > _LAG_TOLERANCE * k0[piece_row]
    return np.unique(piece_row[off]).astype(np.int64)


def _delivered_grid(original: SimulationResult, sim: SimulationResult,
                    draft: Draft) -> npt.NDArray[np.float64]:
    """Melt the twin predicts every original row delivers in ``sim`` without the drive's
    slip, in E grid units of the row's intent (``delivered/commanded · row E``)."""
    d = sim.dynamics.moves
    out = np.asarray(d["out_mm3"], dtype=np.float64) + np.asarray(d["slip_loss_mm3"],
                                                                   dtype=np.float64)
    n = draft.n_rows
    delivered = np.bincount(draft.row, weights=out, minlength=n)
    cmd = np.asarray(original.dynamics.moves["cmd_mm3"], dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(cmd > 0, delivered / cmd * draft.row_e, draft.row_e.astype(float))


def _has_pa_commands(sim: SimulationResult) -> bool:
    for ev in sim.plan.table.events:
        if ev.code in ("M900", "M572", "SET_PRESSURE_ADVANCE"):
            return True
    return False


def _pass_dict(rep: PassReport) -> dict[str, object]:
    return {"pieces": rep.pieces, "runs": rep.runs, "law_clipping": dict(rep.law_counts),
            "refinement": dict(rep.refinement), "relief_travels": rep.relief_travels,
            "relief_mm": rep.relief_mm, "relief_retractions": rep.relief_retractions,
            "relief_retraction_mm": rep.relief_retraction_mm,
            "relief_precharge_mm": rep.relief_precharge_mm}


def _guard_step(draft: Draft, sim: SimulationResult, scanned: ScannedSource,
                options: GuardOptions) -> tuple[Draft, npt.NDArray[np.bool_]]:
    d = sim.dynamics.moves
    ph = sim.plan.timeline.phases
    printing = _printing(sim, draft)
    length = np.maximum(sim.plan.timeline.move_time_s, 0.0)
    mv = sim.plan.table.moves
    path = np.hypot(np.diff(np.concatenate(([sim.plan.table.start_xyze[0]], mv["x"]))),
                    np.diff(np.concatenate(([sim.plan.table.start_xyze[1]], mv["y"]))))
    cruise = np.asarray(ph["cruise_v"], dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        flow = np.where((path > 0) & (length > 0), d["cmd_mm3"] / path * cruise, 0.0)
    lines = draft.table.moves["line"]
    speed_factor = np.array([scanned.motion[int(ln)].speed_factor if int(ln) in scanned.motion
                             else 1.0 for ln in lines.tolist()])
    pp = sim.parameters.params
    with np.errstate(divide="ignore", invalid="ignore"):
        v_e = np.where(path > 0, draft.e_grid * scanned.e_unit / path * cruise, 0.0)
    steady = np.asarray(pp.lag_k_s, dtype=np.float64) * v_e / np.asarray(
        pp.compliance_mm_per_n, dtype=np.float64)
    return guard_feeds(draft, cruise, d["peak_force_n"], steady, pp.max_feed_force_n, flow,
                       printing, speed_factor, options)



def _pace_step(draft: Draft, sim: SimulationResult, scanned: ScannedSource,
               limits: ExtruderLimits, filament_area_mm2: float,
               options: PaceOptions) -> tuple[Draft, PaceReport]:
    """Flow pacing on the current draft with the twin's lag factors and the plan's speeds."""
    ph = sim.plan.timeline.phases
    start = draft.start_xyz()
    length = np.sqrt(np.sum((draft.xyz_mm - start) ** 2, axis=1))
    cmd = np.asarray(sim.dynamics.moves["cmd_mm3"], dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        area = np.where(length > 0, cmd / length, 0.0)
    lines = draft.table.moves["line"][draft.row]
    speed_factor = np.array([scanned.motion[int(ln)].speed_factor if int(ln) in scanned.motion
                             else 1.0 for ln in lines.tolist()])
    push = filament_area_mm2 * min(limits.jump_mm_s, limits.max_e_speed_mm_s)
    return pace_feeds(draft, printing=_printing(sim, draft), cross_section_mm2=area,
                      lag_k_s=np.asarray(sim.parameters.params.lag_k_s, dtype=np.float64),
                      volume_mm3=cmd, start_v_mm_s=np.asarray(ph["start_v"], dtype=np.float64),
                      cruise_v_mm_s=np.asarray(ph["cruise_v"], dtype=np.float64),
                      end_v_mm_s=np.asarray(ph["end_v"], dtype=np.float64),
                      t_start_s=np.asarray(ph["t_start"], dtype=np.float64),
                      t_end_s=np.asarray(sim.plan.timeline.end_time_s, dtype=np.float64),
                      speed_factor=speed_factor, push_mm3_s=push, options=options)
