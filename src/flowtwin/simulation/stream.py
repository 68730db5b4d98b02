"""``simulate_stream``: the whole-print simulation in bounded memory, for multi-GB files.

The file is read chunk by chunk (:func:`~flowtwin.gcode.reader.iter_move_chunks`), planned
window by window (:class:`~flowtwin.planner.windows.WindowPlanner`: bit-identical phases,
times equal to rounding) and simulated section by section: per-move physics, commanded
feed with pressure advance, integration and deposition, with the integrator's state
(column compression, grinding), the extruder position, the nozzle temperature and its set
point carried from one section to the next. Only aggregates are kept: the same whole-print
summary, per-layer and per-feature rows as :class:`~flowtwin.simulation.SimulationResult`.

Sections end where the result cannot depend on what follows:

* without advance smoothing (no pressure advance, Marlin/RRF style, or advance 0), at any
  move: the state equation is causal and its state is carried;
* with Klipper's or Prusa's smoothed advance (once advance is on), between two moves that
  do not move the extruder for at least the largest half window ``h`` in use so far on
  each side — the average over ``t ± h`` then sees the extruder at rest on both sides, as
  it does in one piece. A window change read later than the cut it would affect is the
  one way to miss this (the cut is chosen with twice a section of moves read ahead).
  If no such rest comes within :data:`MAX_SECTION_FACTOR` sections' worth of moves, the
  section is cut anyway and counted (:attr:`StreamResult.cuts_not_at_rest`): the smoothed
  command differs there only within ``h`` of the cut.

Differences to :func:`~flowtwin.simulation.simulate`, by construction: layer heights come
from the highest extrusion of each layer seen so far (the reader gives slicer layer markers
only at the end of a stream; in a spiral layer split by a section cut, the part before the
cut sees the layer's top so far); ``use_slicer_limits`` (the slicer's limits sit at the end
of the file) is not offered. Marlin Linear Advance carries its tracked advance from section
to section. Warnings that count moves of a section add up to the whole print's wording
(:meth:`~flowtwin.simulation.aggregate.Aggregates.note_warnings`).

Three threads share the work (the compiled kernels release the GIL): the reader and the
window planner run ahead (:func:`flowtwin._pipeline.read_ahead`); the calling thread
prepares a section (parameters, commanded feed, pressure advance: their state carried)
while a worker integrates, deposits and aggregates the section before it (the integrator's
state carried there). Each step runs in the same order on the same numbers as in one
thread. Memory: about 110–140 bytes per G-code line on a 2.8 M-line print at the default
sizes, flat for any larger file.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field, replace
from typing import BinaryIO

import numpy as np
import numpy.typing as npt

from flowtwin._pipeline import read_ahead
from flowtwin.dynamics import (
    AdvanceSettings,
    CommandedFeed,
    integrate,
    nominal_feed,
    printer_advance,
    temperature_schedule,
)
from flowtwin.dynamics.advance import apply_advance_carry
from flowtwin.errors import DataError, GcodeError
from flowtwin.firmware import Firmware, PaChange, PlannerFamily, read_pa_command
from flowtwin.gcode.moves import Event, MoveKind, MoveTable
from flowtwin.gcode.reader import iter_move_chunks
from flowtwin.physics.melt_history import MeltState
from flowtwin.planner.from_profile import klipper_settings, marlin_settings, read_options
from flowtwin.planner.klipper import plan_klipper
from flowtwin.planner.klipper_config import klipper_read_options, load_printer_cfg
from flowtwin.planner.marlin import plan_marlin
from flowtwin.planner.plan_file import PlanResult
from flowtwin.planner.timeline import Timeline
from flowtwin.planner.totals import PlanTotals
from flowtwin.planner.windows import LEAD_MOVES, PlannedSpan, WindowPlanner, state_key
from flowtwin.profiles.machine import Machine, load_machine
from flowtwin.profiles.setup import SetupProfile
from flowtwin.simulation.aggregate import Aggregates
from flowtwin.simulation.parameters import MoveParameters, move_parameters
from flowtwin.simulation.pipeline import DEFAULT_MACHINE
from flowtwin.simulation.result import deposition_metrics
from flowtwin.simulation.summary import StreamSummary

__all__ = ["MAX_SECTION_FACTOR", "SECTION_MOVES", "STREAM_CHUNK_BYTES", "StreamResult",
           "simulate_stream"]

#: Bytes read at a time (the reader's default is 16 MB; smaller chunks keep less in memory).
STREAM_CHUNK_BYTES = 1024 * 1024
#: Moves per simulated section and per planning window. Measured on the
#: 2.82 M-line print with Klipper's smoothed advance: 100 k-move sections (4 MB chunks)
#: peak at 866 MB, 20 k at 342 MB, and the smaller sections are no slower (cache-sized).
SECTION_MOVES = 20_000
#: A section without a rest to cut at grows to this many times :data:`SECTION_MOVES`.
MAX_SECTION_FACTOR = 4
#: Rest needed on each side of a cut with smoothed advance: Klipper's largest half window.
_REST_S = 0.1
_TEMP_CODES = frozenset({"M104", "M109", "SET_HEATER_TEMPERATURE"})


@dataclass(slots=True)
class StreamResult:
    """A G-code simulated in bounded memory: the whole-print aggregates.

    Attributes
    ----------
    aggregates
        Totals, per-layer and per-feature accumulators
        (:class:`~flowtwin.simulation.aggregate.Aggregates`).
    windows, sections
        Planning windows and simulated sections used.
    unverified_moves
        Moves whose plan two windows did not confirm (0 on every corpus file).
    cuts_not_at_rest
        Sections cut where the smoothed advance could see across the cut.
    lines
        G-code lines read.
    """

    aggregates: Aggregates
    windows: int
    sections: int
    unverified_moves: int
    cuts_not_at_rest: int
    lines: int

    def summary(self) -> StreamSummary:
        """Whole-print figures (those of ``SimulationResult.summary()``) and the stream's
        own counts."""
        return StreamSummary(self.aggregates.summary(), self.windows, self.sections,
                             self.unverified_moves, self.cuts_not_at_rest, self.lines)

    def per_layer(self) -> list[dict[str, float | int]]:
        """Rows of ``SimulationResult.per_layer()``."""
        return self.aggregates.rows("layer")

    def per_feature(self) -> list[dict[str, float | int | str]]:
        """Rows of ``SimulationResult.per_feature()``."""
        return self.aggregates.feature_rows()

    def worst_moves(self, by: str = "width", count: int = 10) -> list[dict[str, float | int]]:
        """Rows of ``SimulationResult.worst_moves()`` (``count`` up to
        :data:`~flowtwin.simulation.aggregate.WORST_KEPT`)."""
        return self.aggregates.worst_moves(by, count)


@dataclass(slots=True)
class _State:
    """What one section hands to the next."""

    x_mm: float = 0.0
    grinding: bool = False
    e_mm: float = 0.0
    temp_c: float = 0.0
    melt: MeltState | None = None
    set_c: float = 0.0
    first: bool = True
    layer_z: list[float] = field(default_factory=list)
    replay: dict[tuple[str, frozenset[str]], Event] = field(default_factory=dict)
    marlin_adv: npt.NDArray[np.float64] = field(default_factory=lambda: np.zeros(1))


@dataclass(slots=True)
class _Job:
    """A section ready to integrate."""

    table: MoveTable
    timeline: Timeline
    params: MoveParameters
    feed: CommandedFeed
    end_s: float | None


def simulate_stream(source: str | os.PathLike[str] | bytes | BinaryIO, *,
                    machine: Machine | SetupProfile | str | os.PathLike[str] | None = None,
                    klipper_config: str | os.PathLike[str] | None = None,
                    pressure_advance: bool = True, temperature_c: float | None = None,
                    chunk_bytes: int = STREAM_CHUNK_BYTES,
                    section_moves: int = SECTION_MOVES,
                    progress: Callable[[int], None] | None = None) -> StreamResult:
    """Simulate ``source`` on ``machine`` chunk by chunk, in memory bounded by the chunk and
    section sizes, not by the file.

    Parameters
    ----------
    source
        G-code path (plain or gzip), ``"-"`` for stdin, bytes or a binary stream.
    machine, klipper_config, pressure_advance, temperature_c
        As for :func:`~flowtwin.simulation.simulate`.
    chunk_bytes
        Bytes read at a time.
    section_moves
        Moves per planning window and simulated section (``>= 1000``).
    progress
        Called with the number of moves simulated so far after each section.

    Returns
    -------
    StreamResult

    Raises
    ------
    GcodeError, ProfileError
        Bad G-code or profiles; a file without moves.
    DataError
        A bad ``section_moves``.
    """
    if section_moves < 1000:
        raise DataError("sections must hold at least 1000 moves", field="section_moves",
                        value=section_moves, allowed=">= 1000")
    m = machine if isinstance(machine, Machine) else load_machine(machine or DEFAULT_MACHINE)
    plan_fn: Callable[[MoveTable], Timeline]
    if klipper_config is not None:
        ks = load_printer_cfg(klipper_config)
        options = klipper_read_options(ks)
        printer = os.fspath(klipper_config)
        settings: object = ks
        plan_fn = lambda t: plan_klipper(t, ks)  # noqa: E731
        ex = ks.extruders[0]
        adv = AdvanceSettings(Firmware.KLIPPER, k_s=ex.pressure_advance,
                              smooth_time_s=ex.pressure_advance_smooth_time)
    else:
        profile = m.printer
        options = read_options(profile)
        printer = profile.name
        if profile.firmware.planner is PlannerFamily.KLIPPER:
            kps = klipper_settings(profile)
            settings = kps
            plan_fn = lambda t: plan_klipper(t, kps)  # noqa: E731
        else:
            mps = marlin_settings(profile)
            settings = mps
            plan_fn = lambda t: plan_marlin(t, mps)  # noqa: E731
        adv = printer_advance(profile)
    advance = adv if pressure_advance else None
    label = "off" if advance is None else (
        f"{advance.firmware.value} K={advance.k_s:g} s (+ G-code commands)")
    smoothing = advance is not None and advance.firmware.smooths_advance
    start = np.array([*options.start_xyz, 0.0])
    name = _source_name(source)
    wp = WindowPlanner(plan_fn, name, start, window_moves=section_moves,
                       lead_moves=min(LEAD_MOVES, section_moves // 4))
    agg = Aggregates(file=name, machine=m.name, printer=printer, advance=label,
                     firmware=PlannerFamily.KLIPPER.value if klipper_config is not None
                     else m.printer.firmware.planner.value)
    state = _State(temp_c=m.temperature_c if temperature_c is None else temperature_c)
    state.set_c = state.temp_c
    sim = _Simulator(m, advance, settings, printer, start, agg, state, smoothing,
                     section_moves)
    lines = 0
    features: list[str] = []

    def planned() -> Iterator[tuple[list[PlannedSpan], MoveTable | None]]:
        for chunk in iter_move_chunks(source, options=options, chunk_bytes=chunk_bytes):
            yield wp.feed(chunk), chunk
        yield wp.finish(), None

    try:
        # three threads: read + plan ahead, prepare a section here, integrate on the worker
        for spans, chunk in read_ahead(planned()):
            sim.add(spans)
            sim.run(final=chunk is None, progress=progress)
            if chunk is not None:
                lines = chunk.n_lines or lines
                features = chunk.features or features
        sim.wait()
    finally:
        sim.close()
    if agg.moves == 0:
        raise GcodeError("no moves to simulate", source=name,
                         allowed="G-code with at least one G0/G1/G2/G3 move")
    agg.features = features
    agg.net_filament_mm = {str(k): w for k, (w, _x) in
                           sim.plan_totals.filament_by_tool().items()}
    return StreamResult(aggregates=agg, windows=wp.windows, sections=sim.sections,
                        unverified_moves=wp.unverified_moves,
                        cuts_not_at_rest=sim.cuts_not_at_rest, lines=lines)


def _source_name(source: object) -> str:
    if isinstance(source, str | os.PathLike):
        return "<stdin>" if os.fspath(source) == "-" else os.fspath(source)
    return "<bytes>" if isinstance(source, bytes | bytearray) else "<stream>"


def _trim(feed: CommandedFeed, t_a: float, t_b: float) -> CommandedFeed:
    """The segments of ``feed`` that start in ``[t_a, t_b)`` (piece borders fall on both)."""
    keep = (feed.t0_s >= t_a) & (feed.t0_s < t_b)
    if np.all(keep):
        return feed
    return replace(feed, t0_s=feed.t0_s[keep], dt_s=feed.dt_s[keep], coef=feed.coef[keep],
                   e0_mm=feed.e0_mm[keep], move=feed.move[keep], gap=feed.gap[keep],
                   phase=feed.phase[keep])


def _advance_change(advance: AdvanceSettings, ev: Event) -> PaChange | None:
    """What the G-code's advance command ``ev`` sets, read by the firmware model as the
    dynamics read it (:func:`flowtwin.firmware.read_pa_command`: the firmware's own syntax,
    the modelled tool, values the firmware accepts), or ``None``."""
    fw = advance.firmware
    if not advance.use_gcode or ev.code != fw.pa_syntax.code:
        return None
    return read_pa_command(fw, ev, tool=0 if advance.tool is None else advance.tool,
                           source="", warnings=[])


class _Simulator:
    """Buffers final planned spans and simulates them section by section."""

    def __init__(self, machine: Machine, advance: AdvanceSettings | None, settings: object,
                 printer: str, start: npt.NDArray[np.float64], agg: Aggregates,
                 state: _State, smoothing: bool, section_moves: int) -> None:
        self.m = machine
        self.advance = advance
        self.settings = settings
        self.printer = printer
        self.start_xyz = start[:3].copy()
        self.agg = agg
        self.st = state
        self.smoothing = smoothing
        self.pa_seen = advance is not None and advance.k_s > 0.0
        # rest needed on each side of a cut: the largest half window in use so far
        self.rest_s = 0.5 * advance.smooth_time_s if advance is not None else 0.0
        self.section_moves = section_moves
        self.spans: list[PlannedSpan] = []
        self.plan_totals = PlanTotals()
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="flowtwin-section")
        self._pending: Future[None] | None = None
        self.n_buf = 0
        self.sections = 0
        self.cuts_not_at_rest = 0
        self.done = 0

    def add(self, spans: list[PlannedSpan]) -> None:
        self.spans.extend(spans)
        self.n_buf += sum(len(s.moves) for s in spans)
        if self.smoothing:
            assert self.advance is not None  # smoothing needs an advance
            for span in spans:
                for ev in span.events:
                    change = _advance_change(self.advance, ev)
                    if change is None:
                        continue
                    # smoothing acts only while advance is on: a profile value or a command
                    # that may switch it on (a factor other than 0, or a new window)
                    self.pa_seen = self.pa_seen or change.k_s != 0.0 \
                        or change.smooth_time_s is not None
                    w = change.smooth_time_s
                    if w is not None and 0.0 < w <= 2.0 * _REST_S:
                        self.rest_s = max(self.rest_s, 0.5 * w)

    def run(self, *, final: bool, progress: Callable[[int], None] | None) -> None:
        while self.n_buf and (final or self.n_buf >= 2 * self.section_moves):
            n = self.n_buf
            cut = n
            if not (final and n <= MAX_SECTION_FACTOR * self.section_moves):
                cut = self._cut(final)
                if cut <= 0:
                    return  # wait for more moves
            self._section(cut, last=final and cut == n)
            if progress is not None:
                progress(self.done)

    def _front(self, count: int) -> tuple[npt.NDArray[np.void], npt.NDArray[np.void]]:
        """The first ``count`` buffered moves and phases: views when they lie in the first
        span, else one copy of the pieces (each move is copied at most once)."""
        first = self.spans[0]
        if count <= len(first.moves):
            return first.moves[:count], first.phases[:count]
        moves, phases, left = [], [], count
        for span in self.spans:
            take = min(left, len(span.moves))
            moves.append(span.moves[:take])
            phases.append(span.phases[:take])
            left -= take
            if not left:
                break
        return np.concatenate(moves), np.concatenate(phases)

    def _take(self, count: int, *, last: bool
              ) -> tuple[list[Event], list[tuple[int, float, str]], float]:
        """Remove the first ``count`` buffered moves; their events and dwells (all that are
        left when ``last``) and the start of the move after them (the buffer's end time
        when none is left)."""
        events: list[Event] = []
        dwells: list[tuple[int, float, str]] = []
        hi = self.spans[0].start + count
        kept: list[PlannedSpan] = []
        end_t = self.spans[-1].end_time_s
        for span in self.spans:
            end = span.start + len(span.moves)
            if end <= hi or last:
                events += span.events
                dwells += span.dwells
                continue
            if span.start < hi:  # split: the rest stays (views)
                k = hi - span.start
                events += [ev for ev in span.events if ev.move_index < hi]
                dwells += [d for d in span.dwells if d[0] < hi]
                span = PlannedSpan(hi, span.moves[k:], span.phases[k:],
                                   [ev for ev in span.events if ev.move_index >= hi],
                                   [d for d in span.dwells if d[0] >= hi], span.end_time_s)
            kept.append(span)
        if kept:
            end_t = float(kept[0].phases["t_start"][0])
        self.spans = kept
        self.n_buf -= count
        return events, dwells, end_t

    def _cut(self, final: bool) -> int:
        """Where to end the next section (0: wait for more)."""
        n = self.n_buf
        want = min(self.section_moves, n - 1)
        if not (self.smoothing and self.pa_seen):
            return want if n > want else n
        # boundaries 1..want look at moves 0..want
        moves, phases = self._front(want + 1)
        dur = np.asarray(phases["accel_t"] + phases["cruise_t"] + phases["decel_t"],
                         dtype=np.float64)
        ts = np.asarray(phases["t_start"], dtype=np.float64)
        rest = (moves["de"] == 0.0)
        # rest before boundary c: move c-1 idle plus the stop after it; after: move c idle
        before = np.where(rest[:-1], dur[:-1] + np.maximum(ts[1:] - (ts[:-1] + dur[:-1]), 0.0),
                          0.0)
        after = np.where(rest[1:], dur[1:], 0.0)
        ok = np.flatnonzero((before >= self.rest_s) & (after >= self.rest_s)) + 1
        ok = ok[ok <= want]
        if ok.size:
            return int(ok[-1])
        if final or n >= MAX_SECTION_FACTOR * self.section_moves:
            self.cuts_not_at_rest += 1
            return want
        return 0

    def _section(self, cut: int, *, last: bool) -> None:
        """Prepare the next ``cut`` moves here and integrate them on the worker thread, while
        this thread prepares the section after them."""
        base = self.spans[0].start
        moves, phases = self._front(cut)
        events, dwells, t_next = self._take(cut, last=last)
        job = self._prepare(moves, phases, events, dwells, t_next, base, last=last)
        self.wait()
        self._pending = self._pool.submit(self._finish, job)

    def wait(self) -> None:
        """Wait for the section on the worker thread (its errors raise here)."""
        if self._pending is not None:
            pending, self._pending = self._pending, None
            pending.result()

    def close(self) -> None:
        """Stop the worker thread (after :meth:`wait`)."""
        self._pool.shutdown(wait=True)

    def _prepare(self, sec_moves: npt.NDArray[np.void], sec_phases: npt.NDArray[np.void],
                 events: list[Event], dwells: list[tuple[int, float, str]], t_next: float,
                 base: int, *, last: bool) -> _Job:
        """Everything of a section up to its commanded feed; carries the state it needs.
        ``t_next``: the start of the move after the section (the print's end for the
        last)."""
        st = self.st
        cut = len(sec_moves)
        hi = base + cut
        # settings before the section replayed at its start (temperatures separately)
        replay = [Event(0, ev.line, ev.code, ev.params) for ev in
                  sorted(st.replay.values(), key=lambda e: e.line)
                  if ev.code not in _TEMP_CODES]
        own = [ev for ev in events if base <= ev.move_index < hi
               or (last and ev.move_index >= hi)]
        local = [Event(ev.move_index - base, ev.line, ev.code, ev.params) for ev in own]
        setp = Event(0, 0, "M104", {"S": float(st.set_c)})
        table = MoveTable(moves=sec_moves, events=[*replay, setp, *local],
                          start_xyze=np.array([*self.start_xyz, 0.0]), source=self.agg.file)
        # layer heights from the highest extrusion of every layer, carried across sections
        self._layer_z(sec_moves)
        layers = sec_moves["layer"]
        top = int(layers.max()) + 1 if cut else 0
        table.layer_z = st.layer_z[:top]
        tl = Timeline(phases=sec_phases,
                      dwell_s=[(d[0] - base, d[1], d[2]) for d in dwells
                               if base <= d[0] < hi or (last and d[0] >= hi)],
                      total_time_s=t_next, firmware=self.agg.firmware)
        params = move_parameters(self.m, table, tl, temperature_c=st.temp_c,
                                 melt_start=st.melt)
        p_end = sec_phases[-1]
        t_last_end = float(p_end["t_start"]) + float(p_end["accel_t"] + p_end["cruise_t"]
                                                      + p_end["decel_t"])
        tail = 0.0 if last else max(t_next - t_last_end, 0.0)
        feed = nominal_feed(table, tl, e_start_mm=st.e_mm, tail_s=tail)
        if self.advance is not None:
            t_a, t_b = feed.t_begin_s, feed.t_end_s
            feed = apply_advance_carry(feed, table, self.advance, st.marlin_adv)
            # smoothing pads the feed with rest before and after: only the print's own
            # start and end have it
            feed = _trim(feed, -math.inf if st.first else t_a, math.inf if last else t_b)
        # ---- carry the state of this stage
        st.first = False
        st.melt = params.melt_state
        st.e_mm = feed.e_end_mm()
        sched = temperature_schedule(table, tl, initial_c=st.temp_c,
                                     heater_tau_s=self.m.hotend.heater_time_constant_s or 0.0)
        st.temp_c = float(sched.at(np.array([t_next]))[0])
        k = int(np.searchsorted(sched.t_s, t_next, side="right")) - 1
        st.set_c = float(sched.set_c[max(k, 0)])
        for ev in own:
            key = state_key(ev)
            if key is not None:
                st.replay.pop(key, None)
                st.replay[key] = ev
        last_move = sec_moves[-1]
        self.start_xyz = np.array([last_move["x"], last_move["y"], last_move["z"]])
        self.sections += 1
        self.done += cut
        return _Job(table, tl, params, feed, t_next if last else None)

    def _finish(self, job: _Job) -> None:
        """Integrate a prepared section, deposit it and add it to the aggregates (the
        worker thread, one section at a time, in order)."""
        st = self.st
        dyn = integrate(job.feed, job.params.params, initial_compression_mm=st.x_mm,
                        initially_grinding=st.grinding)
        st.x_mm = dyn.final_compression_mm
        st.grinding = dyn.final_grinding
        plan = PlanResult(job.table, job.timeline, self.printer, self.settings)  # type: ignore[arg-type]
        metrics = deposition_metrics(plan, dyn, job.params)
        moves = job.table.moves
        self.agg.add(moves, dyn, metrics, job.params)
        self.plan_totals.add(moves, job.timeline.phases, job.timeline.dwell_s)
        self.agg.note_warnings(job.params.warnings)
        self.agg.note_warnings(dyn.warnings)
        self.agg.add_time(job.end_s)

    def _layer_z(self, moves: npt.NDArray[np.void]) -> None:
        """Record the highest Z of the extrusions of every layer seen so far."""
        zs = self.st.layer_z
        layer = moves["layer"].astype(np.int64)
        ext = ((moves["kind"] & MoveKind.EXTRUDE) != 0) & (layer >= 0)
        sel = np.flatnonzero(ext)
        if not sel.size:
            return
        top = int(layer[sel].max()) + 1
        z_top = np.full(top, -np.inf)
        np.maximum.at(z_top, layer[sel], moves["z"][sel].astype(np.float64))
        if len(zs) < top:
            zs.extend([math.nan] * (top - len(zs)))
        for lay in np.flatnonzero(np.isfinite(z_top)).tolist():
            value = float(z_top[lay])
            if math.isnan(zs[lay]) or value > zs[lay]:
                zs[lay] = value
