"""The stages of ``compensate``, each a function from the current draft to the next.

Every stage takes the :class:`Setting` (the machine, the original file simulated, its
lines and the firmware's limits), the :class:`Current` draft with its simulation, and its
own options, and returns a typed outcome holding the next :class:`Current` and its
figures. :func:`flowtwin.compensation.pipeline.compensate` runs them in order:
trajectory, guard, pace, advance, slip.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import numpy.typing as npt

from flowtwin.compensation.advance import AdvanceOptions, eligible_rows
from flowtwin.compensation.bake import advance_pass
from flowtwin.compensation.budget import largest_fitting
from flowtwin.compensation.draft import Draft
from flowtwin.compensation.emit import Layout
from flowtwin.compensation.guard import GuardOptions, guard_feeds
from flowtwin.compensation.limits import ExtruderLimits
from flowtwin.compensation.metrics import Intent, extruding_moves, flow_figures, flow_score
from flowtwin.compensation.original import OriginalFile
from flowtwin.compensation.outcome import AdvancePassSummary
from flowtwin.compensation.pace import PaceOptions, PaceReport, pace_feeds
from flowtwin.compensation.passes import pass_kept, retimed_share, row_times
from flowtwin.compensation.spots import SpotRanking, count_spots, rank_spots, spot_pieces
from flowtwin.compensation.trajectory import TrajectoryOptions, TrajectoryReport, bend_paths
from flowtwin.errors import DataError
from flowtwin.gcode.moves import MoveKind, MoveTable
from flowtwin.gcode.reader import ReadOptions
from flowtwin.planner.klipper_config import KlipperSettings
from flowtwin.planner.marlin import MarlinSettings
from flowtwin.planner.plan_file import PlanResult, plan_table
from flowtwin.profiles.machine import Machine
from flowtwin.simulation import SimulationResult, simulate, simulate_plan

__all__ = ["AdvanceOutcome", "Current", "GuardOutcome", "PaceOutcome", "Setting",
           "TrajectoryOutcome", "Twin", "advance_stage", "guard_stage", "pace_stage",
           "printing_pieces", "trajectory_stage"]

BoolArray = npt.NDArray[np.bool_]
FloatArray = npt.NDArray[np.float64]

#: The advance keeps the predicted feed force below this share of the grinding limit.
_GRIND_MARGIN = 0.9


@dataclass(frozen=True, slots=True)
class Twin:
    """The machine a draft is simulated on.

    Attributes
    ----------
    machine
        The set-up.
    klipper_config
        A Klipper ``printer.cfg`` to plan with instead of the set-up's printer, or ``None``.
    pressure_advance
        Simulate the firmware's own pressure advance (by default).
    settings
        The firmware settings the original was planned with (drafts are planned with the
        same), ``None`` until the original is read.
    printer
        Name of the printer.
    """

    machine: Machine
    klipper_config: str | os.PathLike[str] | None
    pressure_advance: bool
    settings: KlipperSettings | MarlinSettings | None = None
    printer: str = ""

    def simulate(self, path: Path, *, pressure_advance: bool | None = None
                 ) -> SimulationResult:
        """Simulate a G-code file (with the firmware's advance unless told otherwise)."""
        pa = self.pressure_advance if pressure_advance is None else pressure_advance
        return simulate(path, machine=self.machine, klipper_config=self.klipper_config,
                        pressure_advance=pa)

    def simulate_table(self, table: MoveTable, *, pressure_advance: bool | None = None
                       ) -> SimulationResult:
        """Plan a move table with the original's firmware settings and simulate it."""
        if self.settings is None:
            raise DataError("the twin has no firmware settings yet", field="settings",
                            allowed="a twin made from the original's plan")
        pa = self.pressure_advance if pressure_advance is None else pressure_advance
        plan = plan_table(table, self.settings, printer=self.printer)
        return simulate_plan(plan, machine=self.machine, klipper_config=self.klipper_config,
                             pressure_advance=pa)

    def simulate_draft(self, draft: Draft, *, pressure_advance: bool | None = None,
                       layout: Layout | None = None) -> SimulationResult:
        """Simulate the draft as its written file would read (its move table, in memory;
        from ``layout``, the draft's, when given)."""
        return self.simulate_table(draft.to_table(layout), pressure_advance=pressure_advance)

    def plan_draft(self, draft: Draft) -> PlanResult:
        """Plan the draft as its written file would read, with the original's firmware
        settings (what :meth:`simulate_draft` plans)."""
        if self.settings is None:
            raise DataError("the twin has no firmware settings yet", field="settings",
                            allowed="a twin made from the original's plan")
        return plan_table(draft.to_table(), self.settings, printer=self.printer)

    def simulate_planned(self, plan: PlanResult) -> SimulationResult:
        """Simulate a plan of :meth:`plan_draft` (with the twin's default advance)."""
        return simulate_plan(plan, machine=self.machine, klipper_config=self.klipper_config,
                             pressure_advance=self.pressure_advance)


@dataclass(frozen=True, slots=True)
class Setting:
    """What every stage reads and none changes.

    Attributes
    ----------
    twin
        The machine and the work file.
    original
        What is kept of the original file's simulation (the intent every figure is
        measured against).
    original_file
        The original file's text and the modes of its rows.
    limits
        The firmware's extruder limits.
    read_options
        How the original was read (the written file is read the same way).
    """

    twin: Twin
    original: Intent
    original_file: OriginalFile
    limits: ExtruderLimits
    read_options: ReadOptions


@dataclass(frozen=True, slots=True)
class Current:
    """A draft and its simulation (the draft's rendered file, with the twin's default
    pressure advance); with the draft's layout (made without the check,
    :meth:`Draft.layout`) when the stage kept it: the file is then written from it;
    ``from_file``: the simulation is the original file's, simulated as read (the twin
    would not make it again from the draft to the bit)."""

    draft: Draft
    sim: SimulationResult
    layout: Layout | None = None
    from_file: bool = False


@dataclass(frozen=True, slots=True)
class TrajectoryOutcome:
    """The bent draft and the trajectory figures."""

    current: Current
    report: TrajectoryReport


@dataclass(frozen=True, slots=True)
class GuardOutcome:
    """The guarded draft, the original rows it slowed and the print time it cost, s."""

    current: Current
    slowed: BoolArray
    time_cost_s: float


@dataclass(frozen=True, slots=True)
class PaceOutcome:
    """The paced draft, the pacing figures and the print time it cost, s (0 when nothing
    was paced); with the spots, also the one-pass advance of that draft the pacing was
    judged by (the advance stage's first pass: it resumes from it)."""

    current: Current
    report: PaceReport
    time_cost_s: float
    advanced: AdvanceOutcome | None = None

    @property
    def applied(self) -> bool:
        """Some piece was paced."""
        return bool(self.report.paced_rows.size)


@dataclass(frozen=True, slots=True)
class AdvanceOutcome:
    """The advanced draft (or the one before, when no pass was kept), every pass tried,
    and the warnings."""

    current: Current
    passes: tuple[AdvancePassSummary, ...]
    applied: bool
    warnings: tuple[str, ...]


def printing_pieces(sim: SimulationResult, draft: Draft) -> BoolArray:
    """Pieces that print: of a printing original move, with XY motion and positive E."""
    kind = sim.plan.table.moves["kind"]
    orig = eligible_rows(draft.table, draft.row_e)
    return orig[draft.row] & ((kind & MoveKind.XY) != 0) & (draft.e_grid > 0)


def trajectory_stage(setting: Setting, current: Current,
                     options: TrajectoryOptions) -> TrajectoryOutcome:
    """Nozzle paths that lay the intended road (:mod:`flowtwin.compensation.trajectory`)."""
    draft, report = bend_paths(current.draft, current.sim, options)
    return TrajectoryOutcome(Current(draft, setting.twin.simulate_draft(draft)), report)


def guard_stage(setting: Setting, current: Current, options: GuardOptions) -> GuardOutcome:
    """Slow the moves that would grind, in up to ``options.iterations`` rounds
    (:mod:`flowtwin.compensation.guard`)."""
    time0 = current.sim.plan.timeline.total_time_s
    slowed = np.zeros(setting.original.table.moves.shape[0], dtype=bool)
    for _ in range(options.iterations):
        draft, now = _guard_step(current, setting.original_file, options)
        if not np.any(now):
            break
        slowed |= now
        current = Current(draft, setting.twin.simulate_draft(draft))
    return GuardOutcome(current, slowed, current.sim.plan.timeline.total_time_s - time0)


def _guard_step(current: Current, original: OriginalFile,
                options: GuardOptions) -> tuple[Draft, BoolArray]:
    draft, sim = current.draft, current.sim
    d = sim.dynamics.moves
    ph = sim.plan.timeline.phases
    printing = printing_pieces(sim, draft)
    length = np.maximum(sim.plan.timeline.move_time_s, 0.0)
    mv = sim.plan.table.moves
    path = np.hypot(np.diff(np.concatenate(([sim.plan.table.start_xyze[0]], mv["x"]))),
                    np.diff(np.concatenate(([sim.plan.table.start_xyze[1]], mv["y"]))))
    cruise = np.asarray(ph["cruise_v"], dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        flow = np.where((path > 0) & (length > 0), d["cmd_mm3"] / path * cruise, 0.0)
    speed_factor = original.speed_factor
    pp = sim.parameters.params
    with np.errstate(divide="ignore", invalid="ignore"):
        v_e = np.where(path > 0, draft.e_grid * original.e_unit / path * cruise, 0.0)
    steady = np.asarray(pp.lag_k_s, dtype=np.float64) * v_e / np.asarray(
        pp.compliance_mm_per_n, dtype=np.float64)
    return guard_feeds(draft, cruise, d["peak_force_n"], steady, pp.max_feed_force_n, flow,
                       printing, speed_factor, options)


def pace_stage(setting: Setting, current: Current, options: PaceOptions,
               advance: AdvanceOptions | None = None) -> PaceOutcome:
    """Flow pacing on the current draft with the twin's lag factors and the plan's speeds
    (:mod:`flowtwin.compensation.pace`).

    With ``options.spots``, only near the moves that ``advance`` (one pass, when given)
    leaves beyond ``options.spot_error`` (:mod:`flowtwin.compensation.spots`); then again
    with the spots the paced and advanced draft still has added, up to
    ``options.spot_rounds`` times (pacing one junction can move the error to the next).
    Where a round's paced draft would add more than ``options.time_budget`` of the print
    time (planned), only its worst spots are paced: the most that fit, found by bisection
    (:mod:`flowtwin.compensation.budget`). Of these drafts, and the one not paced, the one
    whose advanced trial scores best is kept: the score is the larger of two ratios, after
    over before, of the RMS flow error and of the windowed peak over-extrusion over one
    nozzle diameter (smaller is better).
    """
    pull = 0.0 if advance is None or advance.is_identity else advance.retract_ratio
    if options.pull_ratio > pull:  # the envelope may count only on the pull-back there is
        options = replace(options, pull_ratio=pull)
    twin = setting.twin
    draft, sim = current.draft, current.sim
    time0 = sim.plan.timeline.total_time_s
    ph = sim.plan.timeline.phases
    start = draft.start_xyz()
    length = np.sqrt(np.sum((draft.xyz_mm - start) ** 2, axis=1))
    cmd = np.asarray(sim.dynamics.moves["cmd_mm3"], dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        area = np.where(length > 0, cmd / length, 0.0)
    speed_factor = setting.original_file.speed_factor[draft.row]
    limits = setting.limits
    push = (float(twin.machine.filament.area_mm2)
            * min(limits.jump_mm_s, limits.max_e_speed_mm_s))
    printing = printing_pieces(sim, draft)

    def pace(only: BoolArray | None, no_pull: BoolArray | None) -> tuple[Draft, PaceReport]:
        return pace_feeds(
            draft, printing=printing, cross_section_mm2=area,
            lag_k_s=np.asarray(sim.parameters.params.lag_k_s, dtype=np.float64),
            volume_mm3=cmd, start_v_mm_s=np.asarray(ph["start_v"], dtype=np.float64),
            cruise_v_mm_s=np.asarray(ph["cruise_v"], dtype=np.float64),
            end_v_mm_s=np.asarray(ph["end_v"], dtype=np.float64),
            t_start_s=np.asarray(ph["t_start"], dtype=np.float64),
            t_end_s=np.asarray(sim.plan.timeline.end_time_s, dtype=np.float64),
            speed_factor=speed_factor, push_mm3_s=push, options=options, only=only,
            no_pull=no_pull)

    def outcome(paced: Draft, report: PaceReport, plan: PlanResult | None = None
                ) -> PaceOutcome:
        if not report.paced_rows.size:
            return PaceOutcome(Current(paced, sim), report, 0.0)
        after = twin.simulate_draft(paced) if plan is None else twin.simulate_planned(plan)
        cost = after.plan.timeline.total_time_s - time0
        report.time_added_s = cost
        return PaceOutcome(Current(paced, after), report, cost)

    if not options.spots:  # everywhere: no spots to rank, no budget
        return outcome(*pace(None, None))

    def advanced(cur: Current) -> AdvanceOutcome:
        if advance is None or advance.is_identity:
            return AdvanceOutcome(cur, (), False, ())
        return advance_stage(setting, cur, advance, passes=1)

    original = setting.original
    window = float(twin.machine.hotend.nozzle_diameter_mm)
    before = original.before

    def judged(trial: AdvanceOutcome) -> tuple[float, FloatArray]:
        """The trial's :func:`flow_score` and its flow error per original move."""
        f = flow_figures(original, trial.current.sim, trial.current.draft.row,
                         window_mm=window)
        return flow_score(before, f), f.flow_error

    def near(err: FloatArray) -> BoolArray:
        return spot_pieces(err, draft.row, length, printing, tolerance=options.spot_error,
                           reach_mm=options.spot_reach_mm)

    def worst_that_fit(ranking: SpotRanking, err: FloatArray, only: BoolArray,
                       stubborn: BoolArray | None, left: BoolArray
                       ) -> tuple[int, tuple[BoolArray, BoolArray, Draft, PaceReport,
                                             PlanResult] | None]:
        """The most of the worst spots whose paced draft adds at most ``cap_s``
        (``stubborn``: after a paced round, the spots are paced without the pull-back
        except where the budget left them before), with its pieces allowed, its pieces
        paced without the pull-back, the paced draft, its report and its plan."""
        kept: list[tuple[BoolArray, BoolArray, Draft, PaceReport, PlanResult]] = []

        def fits(count: int) -> bool:
            f = near(np.where(ranking.worst(count), err, 0.0))
            o = only | f
            s = np.zeros_like(f) if stubborn is None else stubborn | (f & ~left)
            d, r = pace(o, s)
            p = twin.plan_draft(d)
            if p.timeline.total_time_s - time0 > cap_s:
                return False
            kept[:] = [(o, s, d, r, p)]
            return True

        count, _ = largest_fitting(ranking.count, fits)
        return count, (kept[0] if count else None)

    cap_s = options.budget_cap * time0  # the time the pacing may add, s (inf: no cap)
    scored = extruding_moves(original)
    volume = original.cmd_mm3
    only = np.zeros(len(draft), dtype=bool)
    stubborn = np.zeros(len(draft), dtype=bool)  # spots left after a paced round
    left = np.zeros(len(draft), dtype=bool)  # near spots the budget left unpaced
    seen = np.zeros(scored.size, dtype=bool)  # moves of the spots found so far
    chosen = np.zeros(scored.size, dtype=bool)  # and of those paced near
    trial = advanced(current)
    best_score, err = judged(trial)
    spots0 = count_spots(scored & (np.abs(err) > options.spot_error), scored, chosen)[0]
    over0 = 0  # spots of the first round the budget left
    # nothing paced: the draft as it is (what pace_feeds gives with no piece allowed)
    best = PaceOutcome(current, PaceReport(paced_rows=np.zeros(0, dtype=np.int64)), 0.0,
                       advanced=trial)
    for k in range(options.spot_rounds):
        found = near(err)
        fresh = found & ~stubborn if k else found
        if not np.any(fresh):
            break
        bad = scored & (np.abs(err) > options.spot_error)
        # still wrong after a paced round: pace there without the pull-back (not where
        # the budget left a spot unpaced: it was never paced)
        new_only, new_stubborn = only | found, stubborn | (found & ~left) if k else stubborn
        paced, report = pace(new_only, new_stubborn)
        plan = None
        picked = bad
        if math.isfinite(cap_s) and report.paced_rows.size:
            plan = twin.plan_draft(paced)
            if plan.timeline.total_time_s - time0 > cap_s:
                ranking = rank_spots(err, volume, scored, tolerance=options.spot_error)
                count, kept = worst_that_fit(ranking, err, only, stubborn if k else None, left)
                if k == 0:
                    over0 = ranking.count - count
                if kept is None:  # not one more spot fits the budget
                    break
                new_only, new_stubborn, paced, report, plan = kept
                picked = ranking.worst(count)
        left = (left | found) & ~new_only
        only, stubborn = new_only, new_stubborn
        seen |= bad
        chosen |= picked
        out = outcome(paced, report, plan)
        trial = advanced(out.current)
        score, err = judged(trial)
        if score < best_score:
            n_spots, n_paced = count_spots(seen, scored, chosen)
            report.spots, report.spots_paced = n_spots, n_paced
            report.spots_over_budget = n_spots - n_paced
            best_score, best = score, replace(out, advanced=trial)
    if not best.applied:
        best.report.spots, best.report.spots_over_budget = spots0, over0
    best.report.time_budget = options.time_budget
    return best


def advance_stage(setting: Setting, current: Current, options: AdvanceOptions, *,
                  passes: int, resume: AdvanceOutcome | None = None) -> AdvanceOutcome:
    """Pressure advance baked into the E, in ``passes`` passes
    (:mod:`flowtwin.compensation.bake`).

    Every pass after the first is tried with the twin's correction of the model, and
    again without it when that raised the twin's RMS flow error; a pass that raises it
    all the same is dropped and ends the stage — except the first: its ratio steps
    re-time the plan most, so the second pass starts from its draft all the same, and
    the stage keeps the best of the file and the passes. A pass after the second is made
    only when the last kept pass moved the plan off the timeline it modelled
    (``options.retime_share``), and kept only when it raises neither the RMS flow error
    nor the :func:`~flowtwin.compensation.metrics.flow_score` (the weaker of the
    improvements of the RMS and of the windowed peak over-extrusion). The advance is
    computed and judged on the file without the firmware's own advance. ``resume``: the
    outcome of one pass of this stage on the same ``current`` (the pacing's trial); the
    stage goes on from it.
    """
    twin = setting.twin
    first = current.draft
    # the file's own simulation is kept while it is the kept one (it is not made again)
    hold = current.from_file and not twin.pressure_advance
    start = (current.sim if not twin.pressure_advance
             else twin.simulate_draft(current.draft, pressure_advance=False,
                                      layout=current.layout))
    cur: SimulationResult | None = start
    kept_draft = first
    kept_sim: SimulationResult | None = start
    kept_layout, lay = current.layout, current.layout  # (of the kept draft, of draft)
    kept_rms = flow_figures(setting.original, start, first.row).rms_flow_error
    del start, current  # (the caller hands the draft over: nothing else holds its sim)
    draft = first
    attempts = [(k, ilc) for k in range(passes) for ilc in ((True, False) if k else (False,))]
    done: set[int] = set()
    summaries: list[AdvancePassSummary] = []
    warnings: list[str] = []
    # a trial first pass that raised the RMS is not resumed but made again, so that the
    # second pass can start from it (below); with one pass the stage ends there
    if (resume is not None and resume.passes and not twin.pressure_advance
            and (resume.applied or passes == 1)):
        summaries, warnings = list(resume.passes), list(resume.warnings)
        done.add(0)
        if resume.applied:
            kept_draft, kept_sim = resume.current.draft, resume.current.sim
            kept_layout = lay = resume.current.layout
            kept_rms = summaries[-1].rms_flow_error
            draft, cur = kept_draft, kept_sim
        else:
            attempts = []
    printing = extruding_moves(setting.original)
    window = float(twin.machine.hotend.nozzle_diameter_mm)
    kept_score: float | None = None  # flow_score of the kept draft, from pass 3 on
    kept_share = summaries[-1].retimed_share if summaries else math.nan  # of the kept pass
    # a first pass that raised the RMS is still where the second starts: its ratio steps
    # re-timed the plan, and the second models that plan (and corrects by the twin)
    base: tuple[Draft, SimulationResult, Layout | None] | None = None
    for k, ilc in attempts:
        if k in done:
            continue
        if k >= 2 and ilc and not kept_share > options.retime_share:
            break  # the kept pass kept to the timeline it modelled: nothing new to model
        if cur is None:  # (the kept draft's simulation was let go: simulate it again)
            cur = kept_sim = twin.simulate_draft(kept_draft, pressure_advance=False,
                                                 layout=kept_layout)
        if k >= 2 and kept_score is None:  # (cur, draft: the kept ones here)
            kept_score = flow_score(setting.original.before, flow_figures(
                setting.original, cur, draft.row, window_mm=window))
        modelled = row_times(cur, draft)
        plan, lag_k_s = cur.plan, cur.parameters.params.lag_k_s
        state_max = _grinding_state(cur, setting)
        delivered = _delivered_grid(setting.original, cur, draft) if ilc else None
        if not (hold and kept_draft is first):
            # the pass needs the plan, the lag factors, the cap and what was delivered:
            # the rest of the simulation (dynamics, deposition) and the layout are let go
            # while it runs
            cur = kept_sim = None
            kept_layout = lay = None
        draft, rep = advance_pass(
            draft, plan.table, plan.timeline, lag_k_s, setting.limits, options,
            e_unit_mm=setting.original_file.e_unit, split=k == 0,
            relief=(k == 0 and options.relief), state_max=state_max, delivered=delivered)
        del plan, lag_k_s, state_max, delivered
        lay = draft.layout(check=False)
        cur = twin.simulate_draft(draft, pressure_advance=False, layout=lay)
        # a pass after the second (made because the plan moved) must not weaken the
        # weaker of the two improvements, RMS and windowed peak (flow_score)
        figures = flow_figures(setting.original, cur, draft.row,
                               window_mm=window if k >= 2 else None)
        rms = figures.rms_flow_error
        score = (None if kept_score is None
                 else flow_score(setting.original.before, figures))
        retry = ilc and rms > kept_rms
        fail = not retry and not pass_kept(rms, kept_rms, score, kept_score)
        share = retimed_share(modelled, row_times(cur, draft), printing)
        summaries.append(AdvancePassSummary.of(
            rep, rms_flow_error=rms, twin_correction=ilc, kept=not (retry or fail),
            retimed_share=share))
        del figures
        if retry:  # the same pass again, without the correction
            draft, cur, lay = base or (kept_draft, kept_sim, kept_layout)
            continue
        done.add(k)
        if fail and k == 0 and passes > 1:
            base = (draft, cur, lay)
            continue
        if fail:
            # (a later pass is a trial: its summary says it was not kept; after a first
            # pass that raised the RMS, one warning below says what both did)
            if k < 2 and base is None:
                warnings.append(f"advance pass {k + 1} raised the twin's RMS flow error "
                                f"(to {100 * rms:.2f} % from {100 * kept_rms:.2f} %): "
                                "its result is not used")
            break
        kept_draft, kept_sim, kept_rms, kept_layout = draft, cur, rms, lay
        kept_share, base = share, None
        if score is not None:
            kept_score = score
    applied = kept_draft is not first
    if base is not None and not applied:
        warnings.insert(0, f"advance pass 1 raised the twin's RMS flow error (to "
                        f"{100 * summaries[0].rms_flow_error:.2f} % from {100 * kept_rms:.2f} "
                        "%) and the second, which starts from it, did not make it better "
                        "than the file: nothing is used")
    del base
    if kept_sim is None:
        if kept_layout is None:
            kept_layout = kept_draft.layout(check=False)
        kept_sim = twin.simulate_draft(kept_draft, pressure_advance=False, layout=kept_layout)
    sim = (kept_sim if not twin.pressure_advance
           else twin.simulate_draft(kept_draft, layout=kept_layout))
    return AdvanceOutcome(Current(kept_draft, sim, kept_layout), tuple(summaries), applied,
                          tuple(warnings))


def _grinding_state(sim: SimulationResult, setting: Setting) -> npt.NDArray[np.float64]:
    """Compression at which the feed force reaches the grinding limit (with the margin),
    E grid units, per row of ``sim``."""
    pp = sim.parameters.params
    return (_GRIND_MARGIN * np.asarray(pp.max_feed_force_n, dtype=np.float64)
            * np.asarray(pp.compliance_mm_per_n, dtype=np.float64)
            / setting.original_file.e_unit)


def _delivered_grid(original: Intent, sim: SimulationResult,
                    draft: Draft) -> npt.NDArray[np.float64]:
    """Melt the twin predicts every original row delivers in ``sim`` without the drive's
    slip, in E grid units of the row's intent (``delivered/commanded · row E``)."""
    d = sim.dynamics.moves
    out = np.asarray(d["out_mm3"], dtype=np.float64) + np.asarray(d["slip_loss_mm3"],
                                                                   dtype=np.float64)
    delivered = np.bincount(draft.row, weights=out, minlength=draft.n_rows)
    cmd = original.cmd_mm3
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(cmd > 0, delivered / cmd * draft.row_e, draft.row_e.astype(float))
