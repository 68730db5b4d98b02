"""Firmware pressure advance, applied to the commanded feed as each firmware does it.

The three algorithms (:class:`flowtwin.firmware.AdvanceAlgorithm`; which firmware applies
which, and how each reads its advance command, is :mod:`flowtwin.firmware`). Which moves
get advance (all firmwares: the advance factor ``K`` is in seconds):

* **Klipper** (``SET_PRESSURE_ADVANCE ADVANCE= SMOOTH_TIME=``; ``[extruder]
  pressure_advance``/``pressure_advance_smooth_time``): the advanced position
  ``e + K·v_E`` on moves with XY motion and increasing E (``kinematics/extruder.py``),
  then a triangular (symmetric) average over ``smooth_time`` (default 0.040 s), which also
  smooths moves without advance; with ``K = 0`` no smoothing at all (Klipper docs,
  Pressure_Advance.md, Kinematics.md; formula in ``_advance_kernels``). M900/M572 are
  unknown to Klipper and ignored.
* **Prusa** (Buddy firmware, ``M572 S<K> W<smooth time>``): the same filter, evaluated by
  Prusa as a sampled Bartlett (triangular) FIR window spanning ``W`` (default 0.04 s); the
  continuous window is used here (the difference is O(sample interval²)). Missing ``S``/``W``
  keep their value; ``S`` outside 0–10 s or ``W`` outside 0–0.2 s are ignored (as the
  firmware does, with a message).
* **Marlin** Linear Advance 1.5 (``M900 K``, 0–10; Repetier is given the same): advance
  ``K·v_E`` reached by a constant speed offset ``K·a_E`` during acceleration/deceleration
  (tracking, ``_advance_kernels``), on blocks with XYZ motion, ``de > 0`` and
  ``de/D ≤ 3``. The planner's acceleration cap (E-jerk / (K·de/D)) belongs to the planner.
* **RepRapFirmware** (``M572 D<extruder> S<K>``): ``v_E + K·dv_E/dt`` within each move with
  XY (non-Z) motion and forward extrusion, i.e. the drive is advanced by ``K·v_E`` along a
  move; a jump of ``v_E`` between two moves (a change of extrusion ratio) is not advanced
  (a position step cannot be executed).

The G-code commands take effect from the move that follows them (a change of Klipper's or
Prusa's window ``max(h_old, h_new)`` earlier, so that a change while the extruder rests is
seamless; a change while it moves steps the averaged position — not fed, and reported).
Commands the chosen firmware does not know are counted in the warnings, not applied.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from flowtwin.dynamics._advance_kernels import (
    klipper_smooth,
    marlin_eligible,
    marlin_moves,
    marlin_track,
    merge_breakpoints,
)
from flowtwin.dynamics.feed import PHASE_GAP, PHASE_MIXED, CommandedFeed
from flowtwin.errors import ProfileError
from flowtwin.firmware import (
    DEFAULT_SMOOTH_TIME_S,
    MAX_SMOOTH_TIME_S,
    PA_CODES,
    AdvanceAlgorithm,
    Firmware,
    read_pa_command,
)
from flowtwin.gcode.moves import MoveKind, MoveTable

if TYPE_CHECKING:
    from flowtwin.profiles.printer import PrinterProfile

__all__ = [
    "AdvanceSchedule",
    "AdvanceSettings",
    "advance_eligible",
    "advance_schedule",
    "apply_advance",
    "apply_advance_carry",
    "printer_advance",
]


@dataclass(frozen=True, slots=True)
class AdvanceSettings:
    """Pressure advance configuration of a printer.

    Attributes
    ----------
    firmware
        Which firmware's algorithm and G-code commands apply.
    k_s
        Advance factor from the profile/config before any G-code command, s (``>= 0``).
    smooth_time_s
        Klipper ``pressure_advance_smooth_time`` / Prusa ``W``, s (``0 < t <= 0.2``).
    use_gcode
        Honour M900 / M572 / SET_PRESSURE_ADVANCE found in the G-code.
    tool
        Extruder the feed belongs to (``None``: tool 0 / the only extruder); commands
        addressed to other extruders are ignored.
    """

    firmware: Firmware
    k_s: float = 0.0
    smooth_time_s: float = DEFAULT_SMOOTH_TIME_S
    use_gcode: bool = True
    tool: int | None = None

    def __post_init__(self) -> None:
        if not (self.k_s >= 0.0 and np.isfinite(self.k_s)):
            raise ProfileError("pressure advance must be >= 0", field="k_s", value=self.k_s,
                               allowed="0 <= K (s)")
        if not (0.0 < self.smooth_time_s <= MAX_SMOOTH_TIME_S):
            raise ProfileError("smooth time out of range", field="smooth_time_s",
                               value=self.smooth_time_s, allowed="0 < t <= 0.2 s")


def printer_advance(printer: PrinterProfile, *, use_gcode: bool = True) -> AdvanceSettings:
    """The pressure advance a printer profile describes: its firmware's algorithm, its
    ``K`` and the smoothing window (the profile's, or the firmware default 0.040 s where
    the profile has none; unused by the algorithms without a window)."""
    smooth = (printer.pa_smooth_time_s or printer.pressure_advance.smooth_time_s
              or DEFAULT_SMOOTH_TIME_S)
    return AdvanceSettings(printer.firmware, k_s=printer.pressure_advance.k_s,
                           smooth_time_s=smooth, use_gcode=use_gcode)


@dataclass(frozen=True, slots=True)
class AdvanceSchedule:
    """Pressure advance in force for every move.

    Attributes
    ----------
    k_s
        Advance setting in force at each move, s, shape ``(n_moves,)``.
    smooth_time_s
        Smoothing window in force at each move, s, shape ``(n_moves,)``.
    eligible
        Whether the firmware advances each move, shape ``(n_moves,)``.
    applied
        Number of G-code commands that changed the setting.
    warnings
        Commands ignored, with line numbers.
    """

    k_s: npt.NDArray[np.float64]
    smooth_time_s: npt.NDArray[np.float64]
    eligible: npt.NDArray[np.bool_]
    applied: int = 0
    warnings: tuple[str, ...] = field(default_factory=tuple)

    @property
    def k_eff_s(self) -> npt.NDArray[np.float64]:
        """Advance actually applied per move (``k_s`` where eligible, else 0), s."""
        return np.where(self.eligible, self.k_s, 0.0)


def advance_eligible(moves: MoveTable, firmware: Firmware) -> npt.NDArray[np.bool_]:
    """Moves the firmware applies pressure advance to, shape ``(n_moves,)``.

    Klipper, Prusa, RRF: XY motion and ``de > 0``. Marlin's linear advance: XYZ motion,
    ``de > 0`` and ``de/D <= 3`` (``D`` the XYZ length; higher ratios are taken for
    retract/prime moves).
    """
    mv = moves.moves
    de = np.asarray(mv["de"], dtype=np.float64)
    if firmware.advance is not AdvanceAlgorithm.LINEAR_ADVANCE:
        return (de > 0.0) & ((mv["kind"] & int(MoveKind.XY)) != 0)
    out = np.empty(de.shape[0], dtype=np.bool_)
    x0, y0, z0 = (float(v) for v in np.asarray(moves.start_xyze[:3], dtype=np.float64))
    marlin_eligible(de, mv["x"], mv["y"], mv["z"], x0, y0, z0, out)
    return out


def advance_schedule(moves: MoveTable, settings: AdvanceSettings) -> AdvanceSchedule:
    """Advance setting per move from the profile and the G-code commands.

    Parameters
    ----------
    moves
        Move table with its events.
    settings
        Firmware and profile values.

    Returns
    -------
    AdvanceSchedule
        Per-move setting, smoothing, eligibility and notes.
    """
    fw = settings.firmware
    n = len(moves)
    k_cur = settings.k_s
    st_cur = settings.smooth_time_s
    at: list[int] = [0]
    ks: list[float] = [k_cur]
    sts: list[float] = [st_cur]
    warnings: list[str] = []
    ignored: dict[str, int] = {}
    applied = 0
    tool = 0 if settings.tool is None else settings.tool
    src = moves.source
    own = fw.pa_syntax.code
    for ev in moves.events if settings.use_gcode else []:
        if ev.code not in PA_CODES:
            continue
        if ev.code != own:
            ignored[ev.code] = ignored.get(ev.code, 0) + 1
            continue
        change = read_pa_command(fw, ev, tool=tool, source=src, warnings=warnings)
        if change is None:
            continue
        new_k = k_cur if change.k_s is None else change.k_s
        new_st = st_cur if change.smooth_time_s is None else change.smooth_time_s
        k_cur, st_cur = new_k, new_st
        at.append(ev.move_index)
        ks.append(k_cur)
        sts.append(st_cur)
        applied += 1
    for code, count in sorted(ignored.items()):
        warnings.append(f"{code} ignored {count}x: not a {fw.value} pressure-advance command")
    idx = np.searchsorted(np.asarray(at), np.arange(n), side="right") - 1
    return AdvanceSchedule(k_s=np.asarray(ks)[idx], smooth_time_s=np.asarray(sts)[idx],
                           eligible=advance_eligible(moves, fw), applied=applied,
                           warnings=tuple(warnings))


def apply_advance(feed: CommandedFeed, moves: MoveTable,
                  settings: AdvanceSettings) -> CommandedFeed:
    """Shape a nominal feed with the firmware's pressure advance.

    Parameters
    ----------
    feed
        Nominal feed from :func:`~flowtwin.dynamics.feed.nominal_feed` (piecewise linear,
        with planner phases).
    moves
        The move table the feed was built from (events, kinds, positions).
    settings
        Firmware and profile values.

    Returns
    -------
    CommandedFeed
        The feed as the firmware commands it (``advance`` names the firmware).

    Raises
    ------
    ProfileError
        The feed was built from another move table, or already carries advance.
    """
    if feed.n_moves != len(moves):
        raise ProfileError("feed and move table differ", field="moves", value=len(moves),
                           allowed=f"{feed.n_moves} moves")
    if feed.advance != "none" or np.any(feed.phase == PHASE_MIXED):
        raise ProfileError("feed already carries pressure advance", field="feed.advance",
                           value=feed.advance, allowed="a nominal feed")
    return apply_advance_carry(feed, moves, settings, np.zeros(1))


def apply_advance_carry(feed: CommandedFeed, moves: MoveTable, settings: AdvanceSettings,
                        marlin_state: npt.NDArray[np.float64]) -> CommandedFeed:
    """:func:`apply_advance` of one piece of a longer feed: Marlin's tracked advance
    (``marlin_state[0]``, mm) is taken before the piece and replaced by its value after it.

    For :mod:`flowtwin.simulation.stream`; other firmwares carry no state across moves
    (Klipper's and Prusa's smoothing is made seamless by where the pieces are cut).
    """
    sched = advance_schedule(moves, settings)
    fw = settings.firmware
    notes: list[str] = []
    if fw.advance is AdvanceAlgorithm.SMOOTHED:
        out, notes = _smoothed(feed, sched)
    elif fw.advance is AdvanceAlgorithm.LINEAR_ADVANCE:
        out = _marlin(feed, sched, marlin_state)
    else:
        out = _rrf(feed, sched)
    return CommandedFeed(t0_s=out[0], dt_s=out[1], coef=out[2], e0_mm=out[3], move=out[4],
                         gap=out[5], phase=out[6], move_t0_s=feed.move_t0_s,
                         move_t1_s=feed.move_t1_s, move_de_mm=feed.move_de_mm,
                         e_start_mm=feed.e_start_mm, advance=fw.value,
                         warnings=feed.warnings + sched.warnings + tuple(notes))


_Arrays = tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64],
                npt.NDArray[np.float64], npt.NDArray[np.int64], npt.NDArray[np.bool_],
                npt.NDArray[np.int8]]


def _seg_k(feed: CommandedFeed, k_move: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Per-segment advance: the move's value on move segments, 0 on stops."""
    k = np.zeros(feed.n_segments)
    own = ~feed.gap & (feed.move >= 0)
    k[own] = k_move[feed.move[own]]
    return k


def _rrf(feed: CommandedFeed, sched: AdvanceSchedule) -> _Arrays:
    k = _seg_k(feed, sched.k_eff_s)
    extra_v = k * feed.coef[:, 1]
    coef = feed.coef.copy()
    coef[:, 0] += extra_v
    adv_inc = extra_v * feed.dt_s
    adv_before = np.concatenate(([0.0], np.cumsum(adv_inc)[:-1]))
    return (feed.t0_s, feed.dt_s, coef, feed.e0_mm + adv_before, feed.move, feed.gap,
            feed.phase)


def _marlin(feed: CommandedFeed, sched: AdvanceSchedule,
            state: npt.NDArray[np.float64]) -> _Arrays:
    n = feed.n_moves
    k = sched.k_eff_s
    if not np.any(k > 0.0):
        # no block is advanced: the tracked advance is held, every segment passes unchanged
        return (feed.t0_s, feed.dt_s, feed.coef, feed.e0_mm + float(state[0]), feed.move,
                feed.gap, feed.phase)
    # per-move E speeds and acceleration from the nominal feed's phases
    v_cruise = np.empty(n)
    v_end = np.empty(n)
    a_e = np.empty(n)
    marlin_moves(feed.move, feed.gap, feed.phase, np.ascontiguousarray(feed.coef[:, 0]),
                 np.ascontiguousarray(feed.coef[:, 1]), feed.dt_s, n, v_cruise, v_end, a_e)
    rate = k * a_e
    nb = feed.n_segments
    o = [np.empty(2 * nb) for _ in range(5)]
    src = np.empty(2 * nb, dtype=np.int64)
    cnt = marlin_track(feed.t0_s, feed.dt_s, np.ascontiguousarray(feed.coef[:, 0]),
                       np.ascontiguousarray(feed.coef[:, 1]), feed.e0_mm, feed.move, feed.gap,
                       feed.phase, k * v_cruise, k * v_end, rate, o[0], o[1], o[2], o[3],
                       o[4], src, state)
    coef = np.zeros((cnt, 4))
    coef[:, 0] = o[2][:cnt]
    coef[:, 1] = o[3][:cnt]
    s = src[:cnt]
    return (o[0][:cnt], o[1][:cnt], coef, o[4][:cnt], feed.move[s], feed.gap[s], feed.phase[s])


def _smoothed(feed: CommandedFeed, sched: AdvanceSchedule) -> tuple[_Arrays, list[str]]:
    n = feed.n_moves
    h_move = np.where(sched.k_s > 0.0, 0.5 * sched.smooth_time_s, 0.0)
    h_max = float(np.max(h_move)) if n else 0.0
    if h_max == 0.0:
        # no advance and no smoothing anywhere: every piece is a base segment unchanged
        # (the kernel would return the same coefficients and positions, owners and gaps)
        phase = np.where(feed.gap, np.int8(PHASE_GAP), np.int8(PHASE_MIXED))
        return (feed.t0_s, feed.dt_s, feed.coef, feed.e0_mm, feed.move, feed.gap, phase), []
    pad = 2.0 * h_max
    # base segments, padded with rest before and after (extended to infinity by the kernel)
    t0 = np.concatenate(([feed.t_begin_s - pad], feed.t0_s, [feed.t_end_s]))
    dt = np.concatenate(([pad], feed.dt_s, [pad]))
    v0 = np.concatenate(([0.0], feed.coef[:, 0], [0.0]))
    acc = np.concatenate(([0.0], feed.coef[:, 1], [0.0]))
    e0 = np.concatenate(([feed.e_start_mm], feed.e0_mm, [feed.e_end_mm()]))
    k_seg = np.concatenate(([0.0], _seg_k(feed, sched.k_eff_s), [0.0]))
    bounds = np.concatenate((t0, [t0[-1] + dt[-1]]))
    t_lo, t_hi = float(bounds[0]), float(bounds[-1])
    # regimes of constant window half width; a change switches max(h_old, h_new) before the
    # first move after the command, so that a change made while the extruder rests (start
    # G-code, layer change) is seamless
    if n:
        change = np.flatnonzero(np.diff(h_move) != 0.0) + 1
        switch = feed.move_t0_s[change] - np.maximum(h_move[change - 1], h_move[change])
        switch = np.clip(np.maximum.accumulate(switch) if switch.size else switch, t_lo, t_hi)
        starts = np.concatenate(([t_lo], switch, [t_hi]))
        h_reg = np.concatenate(([h_move[0]], h_move[change]))
    else:
        starts = np.array([t_lo, t_hi])
        h_reg = np.zeros(1)
    pieces: list[npt.NDArray[np.float64]] = []
    widths: list[float] = []   # window half width of each regime, s
    counts: list[int] = []     # its number of pieces
    for r, h in enumerate(h_reg):
        lo = max(float(starts[r]), t_lo)
        hi = min(float(starts[r + 1]), t_hi)
        if hi <= lo:
            continue
        a = int(np.searchsorted(bounds, lo - h, side="left"))
        b = int(np.searchsorted(bounds, hi + h, side="right"))
        u = merge_breakpoints(np.ascontiguousarray(bounds[a:b]), float(h), lo, hi)
        pieces.append(u[:-1])
        widths.append(float(h))
        counts.append(u.shape[0] - 1)
    u_all = np.concatenate([*pieces, [t_hi]])
    del pieces
    reg_end = np.cumsum(np.asarray(counts, dtype=np.int64))
    reg_h = np.asarray(widths, dtype=np.float64)
    m = int(reg_end[-1]) if reg_end.size else 0
    out_coef = np.empty((m, 4))
    out_e0 = np.empty(m)
    owner = np.empty(m, dtype=np.int64)
    gap = np.empty(m, dtype=np.bool_)
    klipper_smooth(t0, dt, v0, acc, e0, k_seg, u_all, reg_end, reg_h, feed.move_t0_s,
                   feed.move_t1_s, out_coef, out_e0, owner, gap)
    del t0, dt, v0, acc, e0, k_seg
    phase = np.where(gap, np.int8(PHASE_GAP), np.int8(PHASE_MIXED))
    p_dt = np.diff(u_all)
    notes: list[str] = []
    # pieces where the window width changes: the first piece of each regime after the first
    firsts = np.cumsum(counts)[:-1]
    for k in firsts[[widths[i + 1] != widths[i] for i in range(len(widths) - 1)]]:
        c = out_coef[k - 1]
        ln = p_dt[k - 1]
        end = out_e0[k - 1] + ln * (c[0] + ln * (0.5 * c[1] + ln * (c[2] / 3 + ln * c[3] / 4)))
        jump = float(out_e0[k] - end)
        if abs(jump) > 1e-9:
            notes.append(f"smoothing window changes at t={u_all[k]:.4f} s while the extruder "
                         f"moves: the commanded position steps by {jump:+.3e} mm, which the "
                         "motor does not execute")
    return (u_all[:-1], p_dt, out_coef, out_e0, owner, gap, phase), notes
