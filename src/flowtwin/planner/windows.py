"""Plan a move stream window by window, exactly: the look-ahead planners on bounded memory.

The planners (:func:`~flowtwin.planner.klipper.plan_klipper`,
:func:`~flowtwin.planner.marlin.plan_marlin`) plan whole move tables and start and end them
at rest. A window of the stream therefore has two artificial boundaries: its first moves
are planned from rest (a *start transient*: the real head arrives with speed) and its last
moves decelerate to a stop that is not in the G-code (an *end transient*). Both die out
within a few moves: a junction speed depends on the moves around it only until a junction
or speed limit binds.

:class:`WindowPlanner` plans overlapping windows and keeps only what two windows with
different boundaries agree on. Window ``k`` starts :data:`LEAD_MOVES` moves before the
point up to which window ``k - 1`` was final and extends to the newest move read. On the
moves both windows plan, the phases (speeds and phase times) are compared: window ``k``'s
start transient is over at the first of :data:`AGREE_RUN` consecutive identical moves, and
window ``k - 1``'s end transient begins at the first move after that which differs. The
moves in between are final: two plans whose starts and ends differ computed them bit for
bit alike. Their times are shifted onto the clock of the earlier window (a constant
offset). Windows that do not agree are extended (a longer lead-in, more moves) up to
:data:`MAX_WINDOW_FACTOR` times their size; beyond that the moves are taken unverified and
counted (:attr:`WindowPlanner.unverified_moves`, never silently).

State that G-code commands set before a window (accelerations, velocity limits, pressure
advance, the active tool) is carried by replaying, at the window's start, the last command
of each kind and parameter set (:func:`state_key`): for every parameter the last command
that wrote it is replayed after all earlier ones, so every setting ends as in the stream.
Commands that take time (dwells, waits, homing) are not replayed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from flowtwin.gcode.moves import Event, MoveTable
from flowtwin.planner.timeline import PHASE_DTYPE, Timeline

__all__ = ["AGREE_RUN", "LEAD_MOVES", "MAX_WINDOW_FACTOR", "STATE_CODES", "PlannedSpan",
           "WindowPlanner", "state_key"]

#: Moves planned again before the point where the previous window was final.
LEAD_MOVES = 2048
#: Consecutive identical moves that end a window's start transient.
AGREE_RUN = 8
#: A window that does not verify grows up to this many times its nominal size.
MAX_WINDOW_FACTOR = 8

#: Commands whose effect is a setting (replayed at a window's start).
STATE_CODES = frozenset({"M201", "M203", "M204", "M205", "M900", "M572", "M221",
                         "SET_VELOCITY_LIMIT", "SET_PRESSURE_ADVANCE", "ACTIVATE_EXTRUDER",
                         "M104", "M109", "SET_HEATER_TEMPERATURE"})

_COMPARE = ("start_v", "cruise_v", "end_v", "accel", "accel_t", "cruise_t", "decel_t")


def state_key(ev: Event) -> tuple[str, frozenset[str]] | None:
    """Replay key of a settings command (``None``: not a setting).

    ``T<n>`` tool changes all share one key (the last selects the tool).
    """
    code = ev.code
    if len(code) > 1 and code[0] == "T" and code[1:].isdigit():
        return ("T", frozenset())
    if code not in STATE_CODES:
        return None
    keys = frozenset(ev.params)
    if code in ("M104", "M109", "SET_HEATER_TEMPERATURE"):
        tool = ev.params.get("T", ev.params.get("HEATER", ""))
        keys = frozenset({f"heater:{tool}"})
    return (code, keys)


@dataclass(slots=True)
class PlannedSpan:
    """Final plan of a run of moves of the stream.

    Attributes
    ----------
    start
        Global index of the first move.
    moves
        The moves (``MOVE_DTYPE`` rows).
    phases
        Their phases (``PHASE_DTYPE``) on the stream's clock.
    events
        Commands before each move, global ``move_index``.
    dwells
        ``(global move index, seconds, reason)`` of the dwells and restart gaps before
        these moves.
    end_time_s
        Start of the next move on the stream's clock (the end of this span, stops and
        dwells included); for the last span, the end of everything.
    """

    start: int
    moves: npt.NDArray[np.void]
    phases: npt.NDArray[np.void]
    events: list[Event]
    dwells: list[tuple[int, float, str]]
    end_time_s: float


@dataclass(slots=True)
class WindowPlanner:
    """Windowed exact planning of a stream of move chunks (see the module docstring).

    Attributes
    ----------
    plan
        The planner: a move table in, its timeline out.
    source
        File name for messages.
    start_xyze
        Toolhead position before the first move.
    window_moves
        Moves per window (plus the lead-in).
    lead_moves
        Lead-in replanned before each window's final point, and moves held back at its
        end (default :data:`LEAD_MOVES`).
    unverified_moves, windows
        Counts (see the module docstring).
    """

    plan: Callable[[MoveTable], Timeline]
    source: str
    start_xyze: npt.NDArray[np.float64]
    window_moves: int = 200_000
    lead_moves: int = LEAD_MOVES
    unverified_moves: int = 0
    windows: int = 0
    # moves read and not yet final: global indices [_b0, _b0 + len(_moves))
    _moves: npt.NDArray[np.void] | None = None
    _events: list[Event] = field(default_factory=list)
    _b0: int = 0
    _final: int = 0                   # moves before this index are final (emitted)
    _replay: dict[tuple[str, frozenset[str]], Event] = field(default_factory=dict)
    _start_xyz: npt.NDArray[np.float64] | None = None   # position before move _b0
    # previous window: phases of global [_p0, _p0 + len(_prev)) on the stream clock
    _prev: npt.NDArray[np.void] | None = None
    _prev_dwells: list[tuple[int, float, str]] = field(default_factory=list)
    _p0: int = 0
    _prev_total_s: float = 0.0

    def feed(self, chunk: MoveTable) -> list[PlannedSpan]:
        """Add a chunk of the stream; return the spans that became final."""
        m = chunk.moves
        self._moves = m.copy() if self._moves is None else np.concatenate((self._moves, m))
        self._events.extend(chunk.events)
        if self._start_xyz is None:
            self._start_xyz = np.asarray(self.start_xyze, dtype=np.float64)[:3].copy()
        pending = self._b0 + len(self._moves) - self._final
        if pending < self.window_moves + 2 * self.lead_moves:
            return []
        return self._step(last=False)

    def finish(self) -> list[PlannedSpan]:
        """Plan what is left (the stream's end is a real end)."""
        if self._moves is None or self._b0 + len(self._moves) == self._final:
            return []
        return self._step(last=True)

    # -- one window -------------------------------------------------------------------------
    def _table(self, lo: int, hi: int) -> MoveTable:
        """Moves ``[lo, hi)`` (global) with the settings before ``lo`` replayed at 0."""
        assert self._moves is not None and self._start_xyz is not None
        a = lo - self._b0
        events = [Event(0, ev.line, ev.code, ev.params) for ev in
                  sorted(self._replay_before(lo), key=lambda e: e.line)]
        events += [Event(ev.move_index - lo, ev.line, ev.code, ev.params) for ev in self._events
                   if lo <= ev.move_index < hi or (ev.move_index >= hi and hi == self._end())]
        start = np.zeros(4)
        if a == 0:
            start[:3] = self._start_xyz
        else:
            prev = self._moves[a - 1]
            start[:3] = (prev["x"], prev["y"], prev["z"])
        return MoveTable(moves=self._moves[a:hi - self._b0], events=events, start_xyze=start,
                         source=self.source)

    def _end(self) -> int:
        assert self._moves is not None
        return self._b0 + len(self._moves)

    def _replay_before(self, lo: int) -> list[Event]:
        rep = dict(self._replay)
        for ev in self._events:
            if ev.move_index >= lo:
                break
            key = state_key(ev)
            if key is not None:
                rep.pop(key, None)
                rep[key] = ev
        return list(rep.values())

    def _step(self, *, last: bool) -> list[PlannedSpan]:
        end = self._end()
        lo = self._final if self._prev is None and self._final == 0 else max(
            self._b0, self._final - self.lead_moves)
        while True:
            table = self._table(lo, end)
            tl = self.plan(table)
            self.windows += 1
            ph = tl.phases
            if self._prev is None and lo == 0:
                offset = 0.0
                agree = 0          # the stream's real start: exact from the first move
            else:
                agree, offset = self._agreement(lo, ph)
            if agree >= 0 and agree <= self._final:
                break
            if lo > self._b0:       # longer lead-in first
                lo = max(self._b0, lo - 4 * self.lead_moves)
                continue
            if not last and end - self._final < MAX_WINDOW_FACTOR * self.window_moves:
                return []           # wait for more moves
            # no agreement: take the window's own plan from the final point, unverified
            agree = self._final
            offset = self._offset_fallback(lo, ph)
            self.unverified_moves += self.lead_moves
            break
        times = np.asarray(ph["t_start"], dtype=np.float64) + offset
        # end of what this window makes final
        if last:
            stop = end
        else:
            stop = max(self._final, end - self.lead_moves)
        spans = []
        if stop > self._final:
            i0 = self._final - lo
            i1 = stop - lo
            phases = ph[i0:i1].copy()
            phases["t_start"] = times[i0:i1]
            dwells = [(d[0] + lo, d[1], d[2]) for d in tl.dwell_s
                      if i0 <= d[0] < i1 or (last and d[0] >= i1)]
            if last:
                end_t = float(tl.total_time_s) + offset
            else:
                end_t = float(times[i1])
            evs = [ev for ev in self._events if self._final <= ev.move_index < stop
                   or (last and ev.move_index >= stop)]
            a = self._final - self._b0
            spans.append(PlannedSpan(self._final, self._moves[a:stop - self._b0].copy(),  # type: ignore[index]
                                     phases, evs, dwells, end_t))
        # keep this window for the next comparison, drop what no window needs any more
        self._prev = ph.copy()
        self._prev["t_start"] = times
        self._p0 = lo
        self._final = stop
        keep_from = max(self._b0, stop - 8 * self.lead_moves)
        self._forget_before(keep_from)
        return spans

    def _agreement(self, lo: int, ph: npt.NDArray[np.void]) -> tuple[int, float]:
        """First global index from which window ``ph`` (starting at ``lo``) and the previous
        window agree for :data:`AGREE_RUN` moves, with the clock offset; ``(-1, 0)`` if none
        before the previous window's final point.

        From there up to that final point the previous window's moves were already taken;
        any of them this window (which sees further ahead) plans differently is counted in
        :attr:`unverified_moves`.
        """
        prev = self._prev
        if prev is None:
            return -1, 0.0
        a = max(lo, self._p0)
        b = min(self._final, self._p0 + len(prev), lo + len(ph))
        if b - a < AGREE_RUN:
            return -1, 0.0
        x = ph[a - lo:b - lo]
        y = prev[a - self._p0:b - self._p0]
        same = np.ones(b - a, dtype=np.bool_)
        for name in _COMPARE:
            same &= x[name] == y[name]
        # durations between consecutive starts must agree too (dwells, gaps)
        dt_x = np.diff(np.asarray(x["t_start"], dtype=np.float64))
        dt_y = np.diff(np.asarray(y["t_start"], dtype=np.float64))
        same[1:] &= np.abs(dt_x - dt_y) <= 1e-9 * np.maximum(1.0, np.abs(dt_y))
        run = np.convolve(same.astype(np.int64), np.ones(AGREE_RUN, dtype=np.int64), "valid")
        hits = np.flatnonzero(run == AGREE_RUN)
        if hits.size == 0:
            return -1, 0.0
        j = int(hits[0])
        self.unverified_moves += int(np.count_nonzero(~same[j:]))
        offset = float(y["t_start"][j]) - float(x["t_start"][j])
        return a + j, offset

    def _offset_fallback(self, lo: int, ph: npt.NDArray[np.void]) -> float:
        prev = self._prev
        if prev is None:
            return 0.0
        k = self._final
        if self._p0 <= k < self._p0 + len(prev) and k - lo < len(ph):
            return float(prev["t_start"][k - self._p0]) - float(ph["t_start"][k - lo])
        return 0.0

    def _forget_before(self, g: int) -> None:
        assert self._moves is not None
        if g <= self._b0:
            return
        for ev in self._events:
            if ev.move_index >= g:
                break
            key = state_key(ev)
            if key is not None:
                self._replay.pop(key, None)
                self._replay[key] = ev
        self._events = [ev for ev in self._events if ev.move_index >= g]
        a = g - self._b0
        self._start_xyz = np.array([self._moves[a - 1]["x"], self._moves[a - 1]["y"],
                                    self._moves[a - 1]["z"]], dtype=np.float64)
        self._moves = self._moves[a:].copy()
        self._b0 = g


def empty_phases(n: int) -> npt.NDArray[np.void]:
    """``n`` zero phase rows."""
    return np.zeros(n, dtype=PHASE_DTYPE)
