"""Klipper's motion planner: the time line of a move table on a Klipper printer.

Klipper's ``toolhead.py`` plans every move as a trapezoid with look-ahead over a queue
of moves: speeds at junctions are limited by the junction deviation (from
``square_corner_velocity``), by the "approximated circle must meet the moves no further
than mid-move" centripetal limit, by the extruder's ``instantaneous_corner_velocity``,
and cruise speeds by ``minimum_cruise_ratio``. Before a move is queued its speed and
acceleration are limited by ``max_velocity`` / ``max_accel`` (changed by ``M204`` and
``SET_VELOCITY_LIMIT``), Z moves by ``max_z_velocity`` / ``max_z_accel`` scaled by the Z
share of the move, and extrude-only and retract moves by ``max_extrude_only_velocity`` /
``max_extrude_only_accel`` scaled by the E share (Klipper ``docs/Kinematics.md``,
``docs/Config_Reference.md``). Extrude-only moves do not blend with their neighbours.

This module turns the reader's :class:`~flowtwin.gcode.moves.MoveTable` into those
per-move limits (vectorised) and the commands into queue operations, then runs the
compiled look-ahead (:mod:`flowtwin.planner._klipper_kernel`). Commands and their
meaning in Klipper:

* ``M400``: the head stops (look-ahead flushed). ``G4 P<ms>``: stop, then dwell P ms
  (``S`` is ignored, a bare ``G4`` dwells 0 s but still stops).
* ``G28``: stop; the homing motion itself takes no time here; axes are at
  ``position_endstop`` afterwards.
* ``M84`` / ``M18``: stop, step-generation flush, 2 × 0.1 s dwell; ``M84 E`` (E only) is
  a no-op, as the reference configurations define it.
* ``T<n>`` / ``ACTIVATE_EXTRUDER`` to another real extruder: stop and step-generation
  flush (the next move starts 2 × kin_flush_delay later), the M221 factor resets to 100 %.
  Tools without an ``[extruderN]`` (``T255``, ``T1000``) and the active tool do nothing.
* ``M204 S`` sets the acceleration; ``M204 P T`` uses min(P, T); ``M204`` with only P,
  only T or P R is ignored (Klipper: "Invalid M204 command"). ``SET_VELOCITY_LIMIT``
  ``VELOCITY``/``ACCEL``/``SQUARE_CORNER_VELOCITY``/``MINIMUM_CRUISE_RATIO`` apply,
  ``ACCEL_TO_DECEL`` is ignored. Extrude-only and Z limits keep their config values.
* ``SET_PRESSURE_ADVANCE`` that switches the smoothing on/off or changes its time:
  step-generation flush and a new kin_flush_delay. M201/M203/M205/M900/M572, heaters
  and fans take no time (Klipper batch mode).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from flowtwin.errors import GcodeError
from flowtwin.gcode.moves import Event, MoveKind, MoveTable
from flowtwin.planner import _klipper_kernel as kernel
from flowtwin.planner.kinematics.base import Kinematics, MoveGeometry, MoveLimits
from flowtwin.planner.klipper_config import (
    SDS_CHECK_TIME_S,
    KlipperSettings,
    klipper_read_options,
    load_printer_cfg,
)
from flowtwin.planner.timeline import PHASE_DTYPE, Timeline

__all__ = ["KlipperSettings", "klipper_read_options", "load_printer_cfg", "plan_klipper"]

#: Klipper's ``DISABLE_STALL_TIME`` (each M84/M18 dwells this twice), s.
DISABLE_STALL_TIME_S = 0.100

#: Commands that matter to the toolhead (everything else takes no time).
_TOOLHEAD_CODES = frozenset({"M204", "SET_VELOCITY_LIMIT", "G4", "M400", "G28", "M84", "M18",
                             "ACTIVATE_EXTRUDER", "M221", "SET_PRESSURE_ADVANCE"})


def _float_param(ev: Event, key: str, source: str, *, minval: float | None = None,
                 above: float | None = None, below: float | None = None,
                 maxval: float | None = None) -> float | None:
    """A numeric parameter with Klipper's ``get_float`` bounds, or ``None`` if absent."""
    value = ev.params.get(key)
    if value is None:
        return None
    if not isinstance(value, float):
        raise GcodeError(f"{ev.code} parameter {key} is not a number", source=source,
                         line=ev.line, field=key, value=value, allowed="a decimal number")
    if ((minval is not None and value < minval) or (above is not None and value <= above)
            or (below is not None and value >= below)
            or (maxval is not None and value > maxval)):
        bounds = [f"{op} {b:g}" for op, b in ((">=", minval), (">", above), ("<", below),
                                              ("<=", maxval)) if b is not None]
        raise GcodeError(f"{ev.code} parameter {key} out of range (Klipper rejects it)",
                         source=source, line=ev.line, field=key, value=value,
                         allowed=" and ".join(bounds))
    return value


def _tool_number(code: str) -> int | None:
    if len(code) > 1 and code[0] == "T" and code[1:].isdigit():
        return int(code[1:])
    return None


def _kin_flush_delay(pa: list[tuple[float, float]], settings: KlipperSettings) -> float:
    """Half the largest active smooth time (PA ≠ 0), at least Klipper's 1 ms, s."""
    times = [smooth * 0.5 for adv, smooth in pa if adv] + [
        t * 0.5 for t in settings.extra_smooth_times]
    return max([SDS_CHECK_TIME_S, *times])


@dataclass(slots=True)
class _Ops:
    """Queue operations in command order: position, sort key, code, value, reason."""

    pos: list[int] = field(default_factory=list)
    key: list[int] = field(default_factory=list)
    code: list[int] = field(default_factory=list)
    val: list[float] = field(default_factory=list)
    reason: list[str] = field(default_factory=list)

    def add(self, pos: int, key: int, code: int, val: float = 0.0, reason: str = "") -> None:
        self.pos.append(pos)
        self.key.append(key)
        self.code.append(code)
        self.val.append(val)
        self.reason.append(reason)


@dataclass(slots=True)
class _Walk:
    """What the events mean for the moves: settings segments, flow resets, homing."""

    ops: _Ops
    notes: dict[str, list[int]]
    change_pos: list[int]                  # move index where a settings row starts
    rows: list[tuple[float, float, float, float, int]]   # (v, a, scv, mcr, extruder)
    flow_reset: list[tuple[int, int]]      # [start, end) moves at 100 % extrusion
    home_mask: npt.NDArray[np.uint8]       # G28 axes (X=1, Y=2, Z=4) before each move


def _walk_events(table: MoveTable, settings: KlipperSettings) -> _Walk:
    """Interpret the events in file order as Klipper's toolhead and gcode_move would."""
    n = len(table)
    src = table.source
    kin = settings.kinematics_model
    vel, acc = settings.max_velocity, settings.max_accel
    scv, mcr = settings.square_corner_velocity, settings.minimum_cruise_ratio
    active = 0
    pa = [(ex.pressure_advance, ex.pressure_advance_smooth_time) for ex in settings.extruders]
    names = {ex.name: i for i, ex in enumerate(settings.extruders)}
    w = _Walk(_Ops(), {}, [0], [(vel, acc, scv, mcr, active)], [],
              np.zeros(n + 1, dtype=np.uint8))
    reset_from: int | None = None
    ops, notes = w.ops, w.notes

    def note(text: str, line: int) -> None:
        notes.setdefault(text, []).append(line)

    invalid_m204: list[int] = []
    for ev in table.events:
        code = ev.code
        tool = _tool_number(code) if code[0] == "T" else None
        if tool is None and code not in _TOOLHEAD_CODES:
            continue
        if code == "M204":
            s = _float_param(ev, "S", src, above=0.0)
            if s is None:
                p = _float_param(ev, "P", src, above=0.0)
                t = _float_param(ev, "T", src, above=0.0)
                if p is None or t is None:
                    invalid_m204.append(ev.line)   # Klipper: 'Invalid M204 command'
                    continue
                s = min(p, t)
            acc = s
            pos = min(max(ev.move_index, 0), n)
            w.change_pos.append(pos)
            w.rows.append((vel, acc, scv, mcr, active))
            continue
        pos = min(max(ev.move_index, 0), n)
        key = 2 * ev.line
        new_ext = -1
        if code == "SET_VELOCITY_LIMIT":
            v = _float_param(ev, "VELOCITY", src, above=0.0)
            a = _float_param(ev, "ACCEL", src, above=0.0)
            c = _float_param(ev, "SQUARE_CORNER_VELOCITY", src, minval=0.0)
            r = _float_param(ev, "MINIMUM_CRUISE_RATIO", src, minval=0.0, below=1.0)
            if "ACCEL_TO_DECEL" in ev.params:
                note("ignored SET_VELOCITY_LIMIT ACCEL_TO_DECEL", ev.line)
            vel = vel if v is None else v
            acc = acc if a is None else a
            scv = scv if c is None else c
            mcr = mcr if r is None else r
        elif code == "G4":
            p = _float_param(ev, "P", src, minval=0.0)
            ops.add(pos, key, kernel.OP_DWELL, (p or 0.0) / 1000.0, f"G4 line {ev.line}")
            continue
        elif code == "M400":
            ops.add(pos, key, kernel.OP_WAIT, reason=f"M400 line {ev.line}")
            continue
        elif code == "G28":
            ops.add(pos, key, kernel.OP_HOME, reason=f"G28 line {ev.line}")
            named = sum(1 << a for a in range(3) if "XYZ"[a] in ev.params)
            homed = kin.homed_axes(named)
            if named and homed != named:
                note(f"G28 naming some axes homes more on a {kin.name} printer (the reader "
                     "moved only the named ones)", ev.line)
            w.home_mask[pos] |= homed
            continue
        elif code in ("M84", "M18"):
            if set(ev.params) & {"X", "Y", "Z", "E"} == {"E"}:
                note(f"{code} E treated as a no-op", ev.line)
                continue
            why = f"{code} line {ev.line}"
            ops.add(pos, key, kernel.OP_SG_FLUSH, reason=why)
            ops.add(pos, key, kernel.OP_DWELL, DISABLE_STALL_TIME_S, why)
            ops.add(pos, key, kernel.OP_DWELL, DISABLE_STALL_TIME_S, why)
            continue
        elif tool is not None:
            if tool >= settings.extruder_count:
                note("tool without an [extruderN] ignored", ev.line)
                continue
            new_ext = tool
        elif code == "ACTIVATE_EXTRUDER":
            name = ev.params.get("EXTRUDER")
            if name is None:
                continue  # Klipper's mux command needs EXTRUDER=
            index = names.get(str(name))
            if index is None:
                raise GcodeError("ACTIVATE_EXTRUDER names an extruder the printer does not "
                                 "have", source=src, line=ev.line, field="EXTRUDER",
                                 value=name, allowed=", ".join(names) or "no extruders")
            new_ext = index
        elif code == "M221":
            if isinstance(ev.params.get("S"), float) and reset_from is not None:
                w.flow_reset.append((reset_from, pos))
                reset_from = None
            continue
        else:  # SET_PRESSURE_ADVANCE
            name = ev.params.get("EXTRUDER")
            index = active if name is None else names.get(str(name), -1)
            if not 0 <= index < len(pa):
                raise GcodeError("SET_PRESSURE_ADVANCE names an extruder the printer does "
                                 "not have", source=src, line=ev.line, field="EXTRUDER",
                                 value=name, allowed=", ".join(names) or "no extruders")
            adv = _float_param(ev, "ADVANCE", src, minval=0.0)
            smooth = _float_param(ev, "SMOOTH_TIME", src, minval=0.0, maxval=0.2)
            old = pa[index]
            pa[index] = (old[0] if adv is None else adv, old[1] if smooth is None else smooth)
            if (pa[index][1] if pa[index][0] else 0.0) != (old[1] if old[0] else 0.0):
                # new smoothing window: toolhead.note_step_generation_scan_time()
                why = f"SET_PRESSURE_ADVANCE line {ev.line}"
                ops.add(pos, key, kernel.OP_SG_FLUSH, reason=why)
                ops.add(pos, key, kernel.OP_SET_KFD, _kin_flush_delay(pa, settings), why)
                ops.add(pos, key, kernel.OP_LAST_MOVE_TIME, reason=why)
            continue
        if new_ext >= 0:
            if new_ext == active:
                continue
            ops.add(pos, key, kernel.OP_SG_FLUSH, reason=f"tool change line {ev.line}")
            active = new_ext
            if reset_from is not None:
                w.flow_reset.append((reset_from, pos))
            reset_from = pos   # gcode_move resets the extrude factor to 100 % on activation
        w.change_pos.append(pos)
        w.rows.append((vel, acc, scv, mcr, active))
    if reset_from is not None:
        w.flow_reset.append((reset_from, n))
    if invalid_m204:
        notes["ignored invalid M204 (Klipper needs S, or P and T)"] = invalid_m204
    return w


def _limit_error(err: npt.NDArray[np.float64], lines: npt.NDArray[np.int32],
                 source: str) -> GcodeError:
    """The error Klipper raises for the move :func:`_klipper_kernel.move_limits` flagged."""
    code, k, value, allowed = int(err[0]), int(err[1]), float(err[2]), float(err[3])
    line = int(lines[k])
    if code == kernel.ERR_SPEED:
        return GcodeError("move without a positive speed", source=source, line=line,
                          field="F", value=value, allowed="> 0 mm/min")
    if kernel.ERR_RANGE_X <= code <= kernel.ERR_RANGE_X + 2:
        axis = "XYZ"[code - kernel.ERR_RANGE_X]
        return GcodeError(f"Move out of range: {axis} beyond [stepper_{axis.lower()}] "
                          "position_min/position_max", source=source, line=line, field=axis,
                          value=value, allowed=f"{'<=' if value > allowed else '>='} "
                          f"{allowed:g} mm")
    if code == kernel.ERR_EXTRUDE_ONLY:
        return GcodeError("Extrude only move too long (see max_extrude_only_distance)",
                          source=source, line=line, field="E", value=value,
                          allowed=f"<= {allowed:g} mm of filament")
    if code == kernel.ERR_CROSS_SECTION:
        return GcodeError("Move exceeds maximum extrusion (see max_extrude_cross_section)",
                          source=source, line=line, field="E", value=value,
                          allowed=f"<= {allowed:g} mm of filament per mm of path")
    return GcodeError("Extrude when no extruder present", source=source, line=line,
                      field="E", value=value, allowed="E moves only with an [extruder]")


_NO_CAPS = np.zeros(0)


def _cap_arrays(caps: MoveLimits, n: int) -> tuple[npt.NDArray[np.float64],
                                                   npt.NDArray[np.float64]]:
    """Speed and acceleration caps for the kernel: both length ``n``, or both empty."""
    if caps.speed is None and caps.accel is None:
        return _NO_CAPS, _NO_CAPS
    inf = np.full(n, np.inf)
    return (np.ascontiguousarray(caps.speed if caps.speed is not None else inf,
                                 dtype=np.float64),
            np.ascontiguousarray(caps.accel if caps.accel is not None else inf,
                                 dtype=np.float64))


def _kinematics_limits(kin: Kinematics, x: npt.NDArray[np.float64], y: npt.NDArray[np.float64],
                       z: npt.NDArray[np.float64], start_xyz: npt.NDArray[np.float64],
                       home_mask: npt.NDArray[np.uint8], home: npt.NDArray[np.float64],
                       feed: npt.NDArray[np.float64], seg_tab: npt.NDArray[np.float64],
                       seg: npt.NDArray[np.int64]) -> MoveLimits:
    """The kinematics' own range checks and per-move caps (none for box kinematics)."""
    n = x.shape[0]
    if type(kin).limit_moves is Kinematics.limit_moves or not n:
        return MoveLimits()
    sx, sy, sz, length = (np.empty(n) for _ in range(4))
    kernel.move_starts(x, y, z, start_xyz, home_mask, home, sx, sy, sz, length)
    start = np.column_stack((sx, sy, sz))
    kinematic = length >= kernel.MIN_KINEMATIC_D
    end = np.where(kinematic[:, None], np.column_stack((x, y, z)), start)
    geom = MoveGeometry(start=start, end=end, kinematic=kinematic, length=length,
                        speed=np.minimum(feed, seg_tab[seg, kernel.SEG_VEL]))
    return kin.limit_moves(geom)


def plan_klipper(table: MoveTable, settings: KlipperSettings, *,
                 stop_after_lines: Sequence[int] = (), lazy_flush: bool = False) -> Timeline:
    """Plan a move table exactly as Klipper's toolhead would execute it.

    Parameters
    ----------
    table
        Moves (``n`` rows) and events from the G-code reader, read with
        :func:`~flowtwin.planner.klipper_config.klipper_read_options` for this printer.
    settings
        The printer (:func:`~flowtwin.planner.klipper_config.load_printer_cfg`).
    stop_after_lines
        Source lines after which the head is brought to a stop as by an ``M400``; the
        print time of each stop is in :attr:`Timeline.stop_times_s` (line 0 = before
        the first line).
    lazy_flush
        Emulate Klipper's piecewise ("lazy") flushing of the look-ahead queue as moves
        arrive. Klipper's design makes it give the same plan as one backward pass per
        run of moves between stops (the default, 2-8x faster); the tests check both
        agree on every corpus file.

    Returns
    -------
    Timeline
        ``firmware="klipper"``; phases per move (zero-length moves take no time), dwells
        and restart gaps in ``dwell_s``, stop times, move lines, ignored commands in
        ``warnings``.

    Raises
    ------
    GcodeError
        A command Klipper rejects (``M204 S0``, ``G4 P-1``, an unknown extruder), a move
        beyond ``position_min``/``position_max``, an extrude-only move longer than
        ``max_extrude_only_distance`` or an extrusion above ``max_extrude_cross_section``
        (the message names the file and line).
    """
    moves = table.moves
    n = len(table)
    src = table.source
    lines = np.ascontiguousarray(moves["line"], dtype=np.int32)
    stops = sorted({int(v) for v in stop_after_lines})
    if stops and stops[0] < 0:
        raise GcodeError("stop line must not be negative", source=src,
                         field="stop_after_lines", value=stops[0], allowed=">= 0")
    kin = settings.kinematics_model
    w = _walk_events(table, settings)
    ops = w.ops
    stop_op: dict[int, int] = {}
    for line in stops:
        stop_op[line] = len(ops.code)
        ops.add(int(np.searchsorted(lines, line, side="right")), 2 * line + 1, kernel.OP_WAIT,
                reason=f"stop after line {line}")

    # -- per-move settings and limits ------------------------------------------------------
    seg = (np.searchsorted(np.asarray(w.change_pos), np.arange(n), side="right") - 1
           ).astype(np.int64)
    rows = np.array(w.rows, dtype=np.float64).reshape(-1, 5)
    seg_tab = np.empty((rows.shape[0], 5))
    seg_tab[:, kernel.SEG_VEL] = rows[:, 0]
    seg_tab[:, kernel.SEG_ACCEL] = rows[:, 1]
    seg_tab[:, kernel.SEG_ACCEL_TO_DECEL] = rows[:, 1] * (1.0 - rows[:, 3])
    seg_tab[:, kernel.SEG_JD] = rows[:, 2] ** 2 * (math.sqrt(2.0) - 1.0) / rows[:, 1]
    seg_tab[:, kernel.SEG_EXT] = rows[:, 4]
    ex_tab = np.array([[x.max_extrude_only_velocity, x.max_extrude_only_accel,
                        x.max_extrude_only_distance, x.max_extrude_ratio,
                        x.nozzle_diameter * x.max_extrude_ratio,
                        x.instantaneous_corner_velocity] for x in settings.extruders],
                      dtype=np.float64).reshape(-1, 6)
    flow = np.asarray(moves["flow"], dtype=np.float64)
    if w.flow_reset:
        flow = flow.copy()
        for a, b in w.flow_reset:
            flow[a:b] = 1.0
    de = moves["de"] * flow
    (move_d, ux, uy, uz, er, max_cruise_v2, accel, smooth_delta_v2, jdev, icv,
     min_move_t) = (np.empty(n) for _ in range(11))
    is_kin = np.empty(n, dtype=np.bool_)
    valid = np.empty(n, dtype=np.bool_)
    err = np.zeros(4)
    x = np.ascontiguousarray(moves["x"], dtype=np.float64)
    y = np.ascontiguousarray(moves["y"], dtype=np.float64)
    z = np.ascontiguousarray(moves["z"], dtype=np.float64)
    feed = np.ascontiguousarray(moves["feed_mm_s"], dtype=np.float64)
    start = np.asarray(table.start_xyze[:3], dtype=np.float64)
    home = np.asarray(kin.home_position, dtype=np.float64)
    caps = _kinematics_limits(kin, x, y, z, start, w.home_mask, home, feed, seg_tab, seg)
    kernel.move_limits(
        x, y, z, de, feed, start, w.home_mask, home, seg, seg_tab, ex_tab,
        kin.max_z_velocity, kin.max_z_accel, np.asarray(kin.box_min, dtype=np.float64),
        np.asarray(kin.box_max, dtype=np.float64),
        *_cap_arrays(caps, n),
        move_d, ux, uy, uz, er, is_kin, valid, max_cruise_v2, accel, smooth_delta_v2, jdev,
        icv, min_move_t, err)
    refused = caps.refused
    if refused is not None and (err[0] == kernel.ERR_NONE or refused.index < int(err[1])):
        raise GcodeError(refused.message, source=src, line=int(lines[refused.index]),
                         field="XYZ", value=refused.value, allowed=refused.allowed)
    if err[0] != kernel.ERR_NONE:
        raise _limit_error(err, lines, src)
    stalled = np.flatnonzero(valid & ~((max_cruise_v2 > 0.0) & (accel > 0.0)))
    if stalled.size:   # a limit so small that its square underflows: Klipper divides by 0
        k = int(stalled[0])
        raise GcodeError("speed or acceleration limit too small to move (its square is 0)",
                         source=src, line=int(lines[k]), field="F",
                         value=(float(np.sqrt(max_cruise_v2[k])), float(accel[k])),
                         allowed="limits above 1e-150 mm/s and mm/s²")
    if settings.arc_resolution is None and n:
        arcs = (moves["kind"] & int(MoveKind.ARC)) != 0
        if np.any(arcs):
            w.notes.setdefault("G2/G3 arcs but no [gcode_arcs] (Klipper would not run "
                               "them)", []).append(int(lines[np.argmax(arcs)]))

    # -- run ---------------------------------------------------------------------------------
    order = np.lexsort((np.arange(len(ops.code)), np.asarray(ops.key, dtype=np.int64),
                        np.asarray(ops.pos, dtype=np.int64)))
    op_pos = np.asarray(ops.pos, dtype=np.int64)[order]
    op_code = np.asarray(ops.code, dtype=np.int64)[order]
    op_val = np.asarray(ops.val, dtype=np.float64)[order]
    out_v = np.zeros((n, 3))
    out_t = np.zeros((n, 3))
    t_start = np.zeros(n)
    gap = np.zeros(n)
    op_time = np.zeros(order.shape[0])
    op_gap = np.zeros(order.shape[0])
    kfd0 = _kin_flush_delay([(x.pressure_advance, x.pressure_advance_smooth_time)
                             for x in settings.extruders], settings)
    total = kernel.run_toolhead(
        move_d, ux, uy, uz, er, is_kin, valid, max_cruise_v2, accel, smooth_delta_v2, jdev,
        icv, min_move_t, op_pos, op_code, op_val, kfd0, lazy_flush, out_v, out_t, t_start,
        gap, op_time, op_gap)

    # -- timeline ----------------------------------------------------------------------------
    if n and not np.all(valid):
        ends = np.where(valid, t_start + out_t.sum(axis=1), -np.inf)
        prev_end = np.maximum.accumulate(np.concatenate(([0.0], ends[:-1])))
        t_start = np.where(valid, t_start, prev_end)
        accel = np.where(valid, accel, 0.0)
    phases = np.empty(n, dtype=PHASE_DTYPE)
    phases["t_start"] = t_start
    phases["start_v"] = out_v[:, 0]
    phases["cruise_v"] = out_v[:, 1]
    phases["end_v"] = out_v[:, 2]
    phases["accel"] = accel
    phases["accel_t"] = out_t[:, 0]
    phases["cruise_t"] = out_t[:, 1]
    phases["decel_t"] = out_t[:, 2]
    dwells = [(int(op_pos[j]), float(op_gap[j]), ops.reason[int(order[j])])
              for j in np.flatnonzero(op_gap > 0.0).tolist()]
    dwells += [(k, float(gap[k]), "restart after step-generation flush")
               for k in np.flatnonzero(gap > 0.0).tolist()]
    dwells.sort(key=lambda d: d[0])
    inverse = np.empty_like(order)
    inverse[order] = np.arange(order.shape[0])
    stop_times = {line: float(op_time[inverse[j]]) for line, j in stop_op.items()}
    warnings = [f"{text}: {len(where)}x (first at line {where[0]})"
                for text, where in w.notes.items()]
    return Timeline(phases=phases, dwell_s=dwells, total_time_s=float(total),
                    firmware="klipper", warnings=warnings, stop_times_s=stop_times,
                    lines=lines)
