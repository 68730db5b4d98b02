"""``simulate_stream``: the whole-print simulation in bounded memory, for multi-GB files.

The file is read chunk by chunk (:func:`~flowtwin.gcode.reader.iter_move_chunks`), planned
window by window (:class:`~flowtwin.simulation.windows.WindowPlanner`: bit-identical phases,
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
to section.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import BinaryIO

import numpy as np
import numpy.typing as npt

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
from flowtwin.firmware import Firmware, PlannerFamily
from flowtwin.gcode.moves import Event, MoveKind, MoveTable
from flowtwin.gcode.reader import iter_move_chunks
from flowtwin.physics.melt_history import MeltState
from flowtwin.planner.from_profile import klipper_settings, marlin_settings, read_options
from flowtwin.planner.klipper import plan_klipper
from flowtwin.planner.klipper_config import klipper_read_options, load_printer_cfg
from flowtwin.planner.marlin import plan_marlin
from flowtwin.planner.timeline import Timeline
from flowtwin.planning import PlanResult
from flowtwin.profiles.machine import Machine, load_machine
from flowtwin.profiles.setup import SetupProfile
from flowtwin.simulation.aggregate import Aggregates
from flowtwin.simulation.parameters import move_parameters
from flowtwin.simulation.pipeline import DEFAULT_MACHINE
from flowtwin.simulation.result import deposition_metrics
from flowtwin.simulation.summary import StreamSummary
from flowtwin.simulation.windows import LEAD_MOVES, PlannedSpan, WindowPlanner, state_key

__all__ = ["MAX_SECTION_FACTOR", "SECTION_MOVES", "STREAM_CHUNK_BYTES", "StreamResult",
           "simulate_stream"]

#: Bytes read at a time (the reader's default is 16 MB; smaller chunks keep less in memory).
STREAM_CHUNK_BYTES = 4 * 1024 * 1024
#: Moves per simulated section (and per planning window).
SECTION_MOVES = 100_000
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
    for chunk in iter_move_chunks(source, options=options, chunk_bytes=chunk_bytes):
        sim.add(wp.feed(chunk))
        sim.run(final=False, progress=progress)
        lines = chunk.n_lines or lines
        features = chunk.features or features
        agg.note_warnings(chunk.warnings)
    sim.add(wp.finish())
    sim.run(final=True, progress=progress)
    if agg.moves == 0:
        raise GcodeError("no moves to simulate", source=name,
                         allowed="G-code with at least one G0/G1/G2/G3 move")
    agg.features = features
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


def _sets_advance(ev: Event) -> bool:
    """Whether a command may switch pressure advance on (Klipper, Prusa)."""
    if ev.code == "SET_PRESSURE_ADVANCE":
        v = ev.params.get("ADVANCE")
        return not (isinstance(v, float) and v == 0.0) or "SMOOTH_TIME" in ev.params
    if ev.code == "M572":
        v = ev.params.get("S")
        return not (isinstance(v, float) and v == 0.0)
    return False


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
        self.n_buf = 0
        self.sections = 0
        self.cuts_not_at_rest = 0
        self.done = 0

    def add(self, spans: list[PlannedSpan]) -> None:
        self.spans.extend(spans)
        self.n_buf += sum(len(s.moves) for s in spans)
        if self.smoothing:
            for span in spans:
                for ev in span.events:
                    # smoothing acts only while advance is on: a profile value or a command
                    self.pa_seen = self.pa_seen or _sets_advance(ev)
                    w = ev.params.get("SMOOTH_TIME" if ev.code == "SET_PRESSURE_ADVANCE"
                                      else "W" if ev.code == "M572" else "")
                    if isinstance(w, float) and 0.0 < w <= 2.0 * _REST_S:
                        self.rest_s = max(self.rest_s, 0.5 * w)

    def run(self, *, final: bool, progress: Callable[[int], None] | None) -> None:
        while self.n_buf and (final or self.n_buf >= 2 * self.section_moves):
            moves, phases, events, dwells, end_t, base = self._merge()
            cut = len(moves)
            if not (final and len(moves) <= MAX_SECTION_FACTOR * self.section_moves):
                cut = self._cut(moves, phases, final)
                if cut <= 0:
                    return  # wait for more moves
            self._section(moves, phases, events, dwells, end_t, base, cut,
                          last=final and cut == len(moves))
            if progress is not None:
                progress(self.done)

    def _merge(self) -> tuple[npt.NDArray[np.void], npt.NDArray[np.void], list[Event],
                              list[tuple[int, float, str]], float, int]:
        if len(self.spans) > 1:
            s0 = self.spans[0]
            merged = PlannedSpan(s0.start, np.concatenate([s.moves for s in self.spans]),
                                 np.concatenate([s.phases for s in self.spans]),
                                 [e for s in self.spans for e in s.events],
                                 [d for s in self.spans for d in s.dwells],
                                 self.spans[-1].end_time_s)
            self.spans = [merged]
        s = self.spans[0]
        return s.moves, s.phases, s.events, s.dwells, s.end_time_s, s.start

    def _cut(self, moves: npt.NDArray[np.void], phases: npt.NDArray[np.void],
             final: bool) -> int:
        """Where to end the next section (0: wait for more)."""
        n = len(moves)
        want = min(self.section_moves, n - 1)
        if not (self.smoothing and self.pa_seen):
            return want if n > want else n
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

    def _section(self, moves: npt.NDArray[np.void], phases: npt.NDArray[np.void],
                 events: list[Event], dwells: list[tuple[int, float, str]], end_t: float,
                 base: int, cut: int, *, last: bool) -> None:
        st = self.st
        sec_moves = moves[:cut]
        sec_phases = phases[:cut]
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
        t_next = end_t if cut == len(moves) else float(phases["t_start"][cut])
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
        dyn = integrate(feed, params.params, initial_compression_mm=st.x_mm,
                        initially_grinding=st.grinding)
        plan = PlanResult(table, tl, self.printer, self.settings)  # type: ignore[arg-type]
        metrics = deposition_metrics(plan, dyn, params)
        self.agg.add(sec_moves, dyn, metrics, params, first=st.first)
        self.agg.note_warnings(params.warnings)
        self.agg.note_warnings(dyn.warnings)
        self.agg.add_time(tl.dwell_s, t_next if last else None)
        # ---- carry the state
        st.first = False
        st.x_mm = dyn.final_compression_mm
        st.melt = params.melt_state
        st.grinding = dyn.final_grinding
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
        # keep the rest
        rest = PlannedSpan(hi, moves[cut:], phases[cut:],
                           [ev for ev in events if ev.move_index >= hi],
                           [d for d in dwells if d[0] >= hi], end_t)
        self.spans = [rest] if len(rest.moves) else []
        self.n_buf = len(rest.moves)

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
