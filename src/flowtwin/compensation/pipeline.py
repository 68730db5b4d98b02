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

Each stage is a function of :mod:`flowtwin.compensation.stages` from the current draft
(and its simulation) to the next, with typed options and outcome. Every stage that needs
the twin renders the draft to a temporary file and simulates it
(:meth:`flowtwin.compensation.stages.Twin.simulate_draft`), so it always sees what the
firmware will plan. The original and the result are simulated on the same machine and
compared move by move against the original intent (:mod:`flowtwin.compensation.metrics`);
the figures are a :class:`~flowtwin.compensation.outcome.CompensationReport`.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import TypeVar

import numpy as np
import numpy.typing as npt

from flowtwin.compensation.advance import AdvanceOptions
from flowtwin.compensation.ahead import Pending, WriteAhead
from flowtwin.compensation.corner import corner_velocity_cost
from flowtwin.compensation.draft import Draft
from flowtwin.compensation.guard import GuardOptions
from flowtwin.compensation.limits import extruder_limits
from flowtwin.compensation.metrics import Intent, flow_figures
from flowtwin.compensation.original import read_original
from flowtwin.compensation.outcome import AdvancePassSummary, CompensationReport
from flowtwin.compensation.pace import PaceOptions, PaceReport
from flowtwin.compensation.readback import ReadBack, read_back
from flowtwin.compensation.slip import SlipOptions
from flowtwin.compensation.slip_stage import SlipStart, slip_stage
from flowtwin.compensation.stages import (
    Current,
    Setting,
    Twin,
    advance_stage,
    guard_stage,
    pace_stage,
    printing_pieces,
    trajectory_stage,
)
from flowtwin.compensation.trajectory import TrajectoryOptions, TrajectoryReport
from flowtwin.errors import DataError, GcodeError
from flowtwin.gcode.moves import MoveTable
from flowtwin.gcode.reader import read_gcode
from flowtwin.planner.from_profile import read_options
from flowtwin.planner.klipper_config import klipper_read_options, load_printer_cfg
from flowtwin.profiles.machine import Machine, load_machine
from flowtwin.profiles.setup import SetupProfile
from flowtwin.simulation import DEFAULT_MACHINE, SimulationResult

__all__ = ["compensate", "lag_factor_changes"]

Progress = Callable[[str], None]
_O = TypeVar("_O")


def _option(value: _O | bool | None, cls: type[_O]) -> _O | None:
    if value is None or value is False:
        return None
    if value is True:
        return cls()
    if not isinstance(value, cls):
        raise DataError("invalid option object", field=cls.__name__, value=type(value).__name__,
                        allowed=f"True, False, None or a {cls.__name__}")
    return value


@dataclass(frozen=True, slots=True)
class _Stages:
    """The stages asked for, with their options (``None``: off)."""

    advance: AdvanceOptions | None
    slip: SlipOptions | None
    guard: GuardOptions | None
    trajectory: TrajectoryOptions | None
    pace: PaceOptions | None


@dataclass(slots=True)
class _Record:
    """What the stages did, gathered as they run (the report's raw material)."""

    names: list[str]
    warnings: list[str]
    passes: tuple[AdvancePassSummary, ...] = ()
    trajectory: TrajectoryReport | None = None
    slowed: npt.NDArray[np.bool_] | None = None
    guard_cost_s: float = 0.0
    pace: PaceReport | None = None
    pace_cost_s: float = 0.0
    added_grid: int = 0
    slip_rounds: int = 0
    slip_change: float = 0.0


def compensate(source: str | os.PathLike[str], destination: str | os.PathLike[str], *,
               machine: Machine | SetupProfile | str | os.PathLike[str] | None = None,
               klipper_config: str | os.PathLike[str] | None = None,
               advance: AdvanceOptions | bool | None = None,
               slip: SlipOptions | bool | None = None,
               guard: GuardOptions | bool | None = None,
               trajectory: TrajectoryOptions | bool | None = None,
               pace: PaceOptions | bool | None = None,
               firmware_pressure_advance: bool | None = None, advance_passes: int = 3,
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
        Most advance passes, 1 to 4. The second corrects for the re-planned timing and
        by the twin; every later one is made only while the pass before it moved the
        plan off the timeline it modelled
        (:attr:`~flowtwin.compensation.advance.AdvanceOptions.retime_share`).
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
    stages = _Stages(_option(advance, AdvanceOptions), _option(slip, SlipOptions),
                     _option(guard, GuardOptions), _option(trajectory, TrajectoryOptions),
                     _option(pace, PaceOptions))
    if advance_passes not in (1, 2, 3, 4):
        raise DataError("advance passes must be 1 to 4", field="advance_passes",
                        value=advance_passes, allowed="1, 2, 3, 4")
    m = machine if isinstance(machine, Machine) else load_machine(machine or DEFAULT_MACHINE)
    pa = ((stages.advance is None) if firmware_pressure_advance is None
          else bool(firmware_pressure_advance))
    src = Path(source)
    dst = Path(destination)
    step("simulate original")
    twin = Twin(m, klipper_config, pa)
    # the original's simulation is handed to the stages (the advance lets it go), and
    # simulated again only if the report's original_result is read
    setting, handed = _read(src, twin)
    record = _Record([], [])
    with WriteAhead(setting.read_options) as ahead:
        current = _run_stages(setting, handed.pop(), stages, advance_passes, record, step,
                              ahead)
        step("write")
        pending = ahead.take(current.draft, current.layout)
        store: Callable[[], None] | None = None
        if pending is None or pending.text() is None:  # no bytes made ahead: written now
            layout = (current.draft.layout() if current.layout is None
                      else current.draft.check(current.layout))
            current.draft.render(dst, layout)
            read: Callable[[], ReadBack] = partial(read_back, dst, layout, setting.read_options)
        else:  # the worker read the text back; the report is made while it compresses
            layout = pending.layout
            store = _storer(current.draft, dst, pending)
            read = pending.checked
        step("simulate result")
        try:
            after = _written(setting, current, dst, read, flush=store)
            report = _report(setting, current.draft, after, record, src, dst,
                             lines_rewritten=layout.lines_rewritten,
                             baked_advance=stages.advance is not None, seconds=0.0,
                             original=partial(twin.simulate, src))
        finally:
            if store is not None:
                store()
    return replace(report, seconds=time.perf_counter() - t_start)


def _storer(draft: Draft, dst: Path, pending: Pending) -> Callable[[], None]:
    """Store the bytes ``pending`` makes of ``draft`` at ``dst``, on the first call only."""
    done = False

    def store() -> None:
        nonlocal done
        if not done:
            draft.render(dst, pending.layout, encoded=pending.stored())
            done = True

    return store


def _read(src: Path, twin: Twin) -> tuple[Setting, list[Current]]:
    """Simulate the original, read its text and modes: the setting and the identity
    draft with the original's simulation (in a list: the caller hands it on with
    ``pop`` and holds no reference to it)."""
    original = twin.simulate(src)
    table = original.plan.table
    if twin.klipper_config is not None:
        options = klipper_read_options(load_printer_cfg(twin.klipper_config))
    else:
        options = read_options(twin.machine.printer)
    text = read_original(src, table, home_xyz=options.home_xyz)
    draft = Draft.identity(text, table)
    twin = replace(twin, settings=original.plan.settings, printer=original.plan.printer)
    intent = Intent.of(original, window_mm=float(twin.machine.hotend.nozzle_diameter_mm))
    return Setting(twin, intent, text, extruder_limits(original.plan.settings),
                   options), [Current(draft, original, from_file=True)]


def _written(setting: Setting, current: Current, dst: Path, read: Callable[[], ReadBack], *,
             flush: Callable[[], None] | None = None) -> SimulationResult:
    """The twin's simulation of the written file.

    ``read`` gives the file read back (:func:`~flowtwin.compensation.readback.read_back`:
    the stored file, or its text while ``flush`` stores it, read back by the write-ahead
    worker); where its moves are the draft's table bit for bit (always, but for relative
    coordinates after a rewritten line), the draft's simulation is the file's, else the
    file is simulated as read.

    Raises
    ------
    GcodeError
        The written file does not read back as the pieces written.
    """
    back = read()
    if back.moves != len(current.draft):
        raise GcodeError("the rewritten file does not read back as the pieces written "
                         f"({back.moves} moves, {len(current.draft)} pieces)", source=dst,
                         allowed="a reader/writer round trip that keeps every piece")
    if back.same:
        return current.sim
    if flush is not None:  # (simulate the file as stored and named)
        flush()
    return setting.twin.simulate_table(read_gcode(dst, options=setting.read_options))


def _run_stages(setting: Setting, current: Current, stages: _Stages, advance_passes: int,
                record: _Record, step: Progress, ahead: WriteAhead) -> Current:
    """Trajectory, guard, pace, advance, slip: each that is asked for, in this order
    (the slip's last draft is encoded by ``ahead`` while it is simulated)."""
    tr, gd, pc, adv, sl = (stages.trajectory, stages.guard, stages.pace, stages.advance,
                           stages.slip)
    if tr is not None and not tr.is_identity:
        step("trajectory")
        record.names.append("trajectory")
        bent = trajectory_stage(setting, current, tr)
        current, record.trajectory = bent.current, bent.report
    if gd is not None:
        step("guard")
        record.names.append("guard")
        guarded = guard_stage(setting, current, gd)
        current, record.slowed = guarded.current, guarded.slowed
        record.guard_cost_s = guarded.time_cost_s
    resume = None
    if pc is not None:
        step("pace")
        # (the pacing holds the draft's simulation: it runs before the advance)
        paced = pace_stage(setting, current, pc, adv)
        current, record.pace, resume = paced.current, paced.report, paced.advanced
        if paced.applied:
            record.names.append("pace")
            record.pace_cost_s = paced.time_cost_s
        del paced
    if adv is not None and not adv.is_identity:
        step("advance")
        handed = [current]
        del current  # (the stage lets the draft's simulation go after its first pass)
        advanced = advance_stage(setting, handed.pop(), adv, passes=advance_passes,
                                 resume=resume)
        current, record.passes = advanced.current, advanced.passes
        record.warnings.extend(advanced.warnings)
        if advanced.applied:
            record.names.append("advance")
        del advanced
    del resume
    if sl is not None and not sl.is_identity:
        step("slip")
        start = SlipStart.of(setting, current)
        del current  # (its simulation is let go while the slip's drafts are simulated)
        slipped = slip_stage(setting, start, sl, ahead=ahead.start)
        del start
        current = slipped.current
        record.warnings.extend(slipped.warnings)
        if slipped.applied:
            record.names.append("slip")
            record.added_grid = slipped.added_grid
        record.slip_rounds, record.slip_change = slipped.rounds, slipped.change
    return current


def _report(setting: Setting, draft: Draft, after_sim: SimulationResult, record: _Record,
            src: Path, dst: Path, *, lines_rewritten: int, baked_advance: bool,
            seconds: float, original: Callable[[], SimulationResult]) -> CompensationReport:
    """Before/after figures of the written file against the original intent
    (``original``: how to simulate the original again for the report's
    ``original_result``)."""
    intent = setting.original
    m = setting.twin.machine
    table = intent.table
    e_unit = setting.original_file.e_unit
    window = float(m.hotend.nozzle_diameter_mm)
    before = intent.before
    after = flow_figures(intent, after_sim, draft.row, window_mm=window)
    flow = after_sim.plan.table.moves["flow"].astype(np.float64)
    pr = printing_pieces(after_sim, draft)
    summary0 = intent.summary
    summary1 = after_sim.summary()
    warnings = list(record.warnings)
    warnings.extend(str(w) for w in after_sim.warnings if w not in intent.warnings)
    changed_k = lag_factor_changes(intent, after_sim, draft.row)
    if changed_k.size:
        warnings.append(_lag_warning(intent, after_sim, draft, changed_k))
    if baked_advance and (m.printer.pressure_advance.k_s > 0 or _has_pa_commands(table)):
        warnings.append("the advance is baked into the file: turn the firmware's pressure "
                        "advance off (M900 K0 / M572 S0 / SET_PRESSURE_ADVANCE ADVANCE=0) "
                        "when printing it")
    lines = table.moves["line"]
    slowed = () if record.slowed is None else tuple(int(x) for x in
                                                     lines[record.slowed].tolist())
    paced = () if record.pace is None else tuple(int(x) for x in
                                                  lines[record.pace.paced_rows].tolist())
    return CompensationReport(
        source=str(src), destination=str(dst), machine=m.name,
        firmware_pressure_advance=setting.twin.pressure_advance,
        transformations=tuple(record.names), before=before, after=after,
        time_before_s=intent.time_s,
        time_after_s=float(after_sim.plan.timeline.total_time_s),
        commanded_e_before_mm=float(np.sum(draft.row_e) * e_unit),
        commanded_e_after_mm=float(np.sum(draft.e_grid) * e_unit),
        limits=setting.limits,
        added_volume_mm3=float(record.added_grid * e_unit * m.filament.area_mm2
                               * (float(np.mean(flow[pr])) if np.any(pr) else 1.0)),
        slip_rounds=record.slip_rounds, slip_change=float(record.slip_change),
        slowed_moves=slowed, guard_time_cost_s=float(record.guard_cost_s),
        grinding_moves_before=summary0.grinding_moves,
        grinding_moves_after=summary1.grinding_moves,
        max_force_before_n=summary0.max_feed_force_n,
        max_force_after_n=summary1.max_feed_force_n,
        advance=record.passes, trajectory=record.trajectory,
        lines_rewritten=lines_rewritten, warnings=tuple(warnings), seconds=seconds,
        lag_factor_changed_moves=int(changed_k.size), paced_moves=paced,
        pace_time_cost_s=float(record.pace_cost_s), pace=record.pace,
        corner_velocity=(corner_velocity_cost(after_sim.plan, intent.time_s)
                         if "advance" in record.names else None),
        original_simulation=original, compensated_result=after_sim,
        piece_row=np.asarray(draft.row, dtype=np.int64))


def _lag_warning(original: Intent, after: SimulationResult, draft: Draft,
                 changed: npt.NDArray[np.int64]) -> str:
    table = original.table
    k0 = original.lag_k_s
    k1 = np.asarray(after.parameters.params.lag_k_s, dtype=np.float64)
    worst = int(np.argmax(np.abs(np.log(k1 / k0[draft.row]))))
    lines = table.moves["line"][changed]
    return (f"the twin's lag factor of {changed.size} moves (lines "
            f"{', '.join(str(int(x)) for x in lines[:5])}{' …' if lines.size > 5 else ''}) "
            f"differs between the original and the compensated file (e.g. line "
            f"{int(table.moves['line'][draft.row[worst]])}: K {k0[draft.row[worst]]:.3g} s → "
            f"{k1[worst]:.3g} s): the twin's parameters of a move depend on how it is cut "
            "(a layer height read from where the layer's first extrusion ends, in spiral "
            "layers); before and after are then not predicted on the same physics")


#: Relative change of a piece's lag factor against its original move's that is reported.
_LAG_TOLERANCE = 0.01


def lag_factor_changes(original: SimulationResult | Intent, compensated: SimulationResult,
                       piece_row: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
    """Original moves some piece of which the twin gives a different lag factor ``K``.

    Cutting a move into pieces changes no physics, so the twin should give every piece
    its move's ``K`` (temperature and layer height are the same); where it does not (more
    than 1 % apart), before/after figures compare two different models of the printer.

    Parameters
    ----------
    original, compensated
        The original and the compensated file simulated on the same machine (the
        original's :class:`~flowtwin.compensation.metrics.Intent` will do).
    piece_row
        Original move of every compensated move, shape ``(n_pieces,)``.

    Returns
    -------
    ndarray of int64
        Sorted indices of the original moves concerned.
    """
    k0 = (original.lag_k_s if isinstance(original, Intent)
          else np.asarray(original.parameters.params.lag_k_s, dtype=np.float64))
    k1 = np.asarray(compensated.parameters.params.lag_k_s, dtype=np.float64)
    if k1.shape != piece_row.shape:
        raise DataError("piece map does not match the compensated moves", field="piece_row",
                        value=piece_row.shape, allowed=str(k1.shape))
    off = np.abs(k1 - k0[piece_row]) > _LAG_TOLERANCE * k0[piece_row]
    return np.unique(piece_row[off]).astype(np.int64)


def _has_pa_commands(table: MoveTable) -> bool:
    for ev in table.events:
        if ev.code in ("M900", "M572", "SET_PRESSURE_ADVANCE"):
            return True
    return False
