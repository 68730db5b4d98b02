"""Read and plan a G-code file of any size in bounded memory: the streamed ``plan_gcode``.

:func:`plan_stream` reads the file chunk by chunk
(:func:`~flowtwin.gcode.reader.iter_move_chunks`) and plans it window by window
(:class:`~flowtwin.planner.windows.WindowPlanner`: every move's phases bit-identical to a
whole-file plan, times equal to the rounding of the windows' clock offsets). Iterating the
returned :class:`PlanStream` gives the final plan of consecutive runs of moves
(:class:`~flowtwin.planner.windows.PlannedSpan`: moves, phases on the print's clock, the
commands and dwells before them) in file order — what a G-code rewriter needs, one span in
memory at a time — and adds them to :class:`~flowtwin.planner.totals.PlanTotals`. After
the iteration (or :meth:`PlanStream.run`), :meth:`PlanStream.summary` and
:meth:`PlanStream.per_layer` are those of :class:`~flowtwin.planner.plan_file.PlanResult`: the same
keys, the same figures (sums to the bit; ``total_time_s`` to ~1e-12 relative).

Memory is bounded by the chunk and window sizes, not by the file: ~300 MB for any file
(~135 MB of it the imported libraries) against ~390 bytes per G-code line planned in
memory; streaming is also faster on large files (no fresh memory for whole-file tables).
:data:`STREAM_ABOVE_BYTES` is the file size above which ``flowtwin plan`` streams on its
own (:func:`should_stream`).

Not streamed: Marlin deltas (their moves are cut into segments over the whole table; they
are planned in memory).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import BinaryIO

import numpy as np

from flowtwin._pipeline import read_ahead
from flowtwin.errors import DataError
from flowtwin.firmware import PlannerFamily
from flowtwin.gcode.moves import MOVE_DTYPE, Event, MoveTable
from flowtwin.gcode.reader import ReadOptions, iter_move_chunks
from flowtwin.planner.from_profile import klipper_settings, marlin_settings, read_options
from flowtwin.planner.klipper import plan_klipper
from flowtwin.planner.klipper_config import (
    KlipperSettings,
    klipper_read_options,
    load_printer_cfg,
)
from flowtwin.planner.marlin import MarlinSettings, marlin_settings_from_slicer_config, plan_marlin
from flowtwin.planner.plan_file import PlanSummary, load_printer, metadata_number
from flowtwin.planner.timeline import Timeline
from flowtwin.planner.totals import PlanTotals
from flowtwin.planner.windows import LEAD_MOVES, PlannedSpan, WindowPlanner
from flowtwin.profiles.printer import PrinterProfile

__all__ = ["CHUNK_BYTES", "STREAM_ABOVE_BYTES", "WINDOW_MOVES", "PlanStream", "is_large",
           "plan_stream", "should_stream"]

#: Files larger than this are planned streamed by the CLI: 32 MB of G-code is about 1.1 M
#: lines, ~0.45 GB planned in memory.
STREAM_ABOVE_BYTES = 32 * 1024 * 1024
#: Bytes read at a time.
CHUNK_BYTES = 4 * 1024 * 1024
#: Moves per planning window.
WINDOW_MOVES = 100_000


def is_large(source: str | os.PathLike[str] | bytes | BinaryIO, *,
             above_bytes: int | None = None) -> bool:
    """Whether ``source`` is a file larger than ``above_bytes`` (default
    :data:`STREAM_ABOVE_BYTES`) on disk (compressed ``.gz`` and ``.bgcode`` files expand, so
    they count sooner)."""
    if not isinstance(source, str | os.PathLike) or os.fspath(source) == "-":
        return False
    limit = STREAM_ABOVE_BYTES if above_bytes is None else above_bytes
    try:
        return os.path.getsize(source) > limit
    except OSError:
        return False  # the reader reports the file's problem


def should_stream(source: str | os.PathLike[str] | bytes | BinaryIO, *,
                  printer: PrinterProfile | str | os.PathLike[str] | None = None,
                  klipper_config: str | os.PathLike[str] | None = None,
                  above_bytes: int | None = None) -> bool:
    """Whether to plan ``source`` streamed: a large file (:func:`is_large`) for any printer
    but a Marlin delta."""
    if not is_large(source, above_bytes=above_bytes):
        return False
    if klipper_config is not None:
        return True
    profile = load_printer(printer)
    return (profile.firmware.planner is PlannerFamily.KLIPPER or profile.marlin is None
            or profile.marlin.delta is None)


class PlanStream:
    """A G-code file planned window by window (see the module docstring).

    Iterate once to receive the :class:`~flowtwin.planner.windows.PlannedSpan` objects in
    file order; the totals are complete when the iteration ends.

    Attributes
    ----------
    source
        File name for messages and the summary.
    printer
        Printer name (profile name or ``printer.cfg`` path).
    settings
        The firmware settings the planner used.
    totals
        The sums over the moves planned so far.
    windows, unverified_moves
        Planning windows used; moves whose plan two windows did not confirm (0 on every
        corpus file; see :class:`~flowtwin.planner.windows.WindowPlanner`).
    """

    def __init__(self, source: str | os.PathLike[str] | bytes | BinaryIO, *,
                 options: ReadOptions, plan: Callable[[MoveTable], Timeline], printer: str,
                 settings: KlipperSettings | MarlinSettings, chunk_bytes: int,
                 window_moves: int) -> None:
        if window_moves < 1000:
            raise DataError("windows must hold at least 1000 moves", field="window_moves",
                            value=window_moves, allowed=">= 1000")
        self._source = source
        self._options = options
        self._plan = plan
        self.printer = printer
        self.settings = settings
        self._chunk_bytes = chunk_bytes
        self._window_moves = window_moves
        self.source = _source_name(source)
        self.totals = PlanTotals()
        self.windows = 0
        self.unverified_moves = 0
        self.total_time_s = 0.0
        self.firmware = ("klipper" if isinstance(settings, KlipperSettings) else "marlin")
        self._notes: dict[str, str] = {}
        self._last: MoveTable | None = None
        self._started = False
        self._done = False

    # -- the stream -------------------------------------------------------------------------
    def __iter__(self) -> Iterator[PlannedSpan]:
        if self._started:
            raise DataError("a plan stream can be iterated once", field="PlanStream")
        self._started = True
        wp = WindowPlanner(self._planned, self.source,
                           np.array([*self._options.start_xyz, 0.0]),
                           window_moves=self._window_moves,
                           lead_moves=min(LEAD_MOVES, self._window_moves // 4))
        early: list[Event] = []   # commands before the first move (a file without moves)
        # the reader runs a chunk ahead on a worker thread (its kernel releases the GIL)
        for chunk in read_ahead(iter_move_chunks(self._source, options=self._options,
                                                 chunk_bytes=self._chunk_bytes)):
            self._last = chunk
            if self.totals.moves == 0 and len(chunk) == 0 and wp.windows == 0:
                early.extend(chunk.events)
            for span in wp.feed(chunk):
                self._take(span)
                yield span
        for span in wp.finish():
            self._take(span)
            yield span
        if self.totals.moves == 0:
            self._no_moves(early)
        self.windows = wp.windows
        self.unverified_moves = wp.unverified_moves
        self._done = True

    def run(self) -> PlanStream:
        """Read and plan the whole file, keeping only the totals; return ``self``."""
        for _span in self:
            pass
        return self

    def _planned(self, table: MoveTable) -> Timeline:
        timeline = self._plan(table)
        for note in timeline.warnings:  # "what: N× (first at line L)": count each once
            self._notes.setdefault(note.rsplit(": ", 1)[0], note)
        return timeline

    def _take(self, span: PlannedSpan) -> None:
        self.totals.add(span.moves, span.phases,
                        [(d[0] - span.start, d[1], d[2]) for d in span.dwells])
        self.total_time_s = span.end_time_s

    def _no_moves(self, events: list[Event]) -> None:
        table = MoveTable(moves=np.zeros(0, MOVE_DTYPE), events=events,
                          start_xyze=np.array([*self._options.start_xyz, 0.0]),
                          source=self.source)
        timeline = self._planned(table)
        self.totals.add(table.moves, timeline.phases, timeline.dwell_s)
        self.total_time_s = float(timeline.total_time_s)

    # -- results (after the iteration) ------------------------------------------------------
    def _table(self) -> MoveTable:
        if not self._done or self._last is None:
            raise DataError("the plan stream has not been read to its end; iterate it or "
                            "call run()", field="PlanStream")
        return self._last

    @property
    def warnings(self) -> list[str]:
        """The reader's warnings and the planner's (each kind once, as the first window
        that met it counted it)."""
        return [*self._table().warnings, *self._notes.values()]

    def per_layer(self) -> list[dict[str, float | int]]:
        """Rows of :meth:`flowtwin.planner.plan_file.PlanResult.per_layer`."""
        return self.totals.per_layer(self._table().layer_z)

    def summary(self) -> PlanSummary:
        """The figures of :meth:`flowtwin.planner.plan_file.PlanResult.summary`."""
        t = self._table()
        tot = self.totals
        by_tool = tot.filament_by_tool()
        slicer = t.metadata.get("slicer")
        return PlanSummary(
            file=t.source, printer=self.printer, firmware=self.firmware,
            total_time_s=float(self.total_time_s),
            net_filament_mm={str(k): w for k, (w, _x) in by_tool.items()},
            extruded_filament_mm={str(k): x for k, (_w, x) in by_tool.items()},
            moves=int(tot.moves), extruding_moves=int(tot.extruding_written),
            lines=t.n_lines, layers=int(tot.layers),
            unknown_commands=dict(t.unknown_commands),
            warnings=len(t.warnings) + len(self._notes),
            time_by_feature_s=tot.time_by_feature(t.features),
            slicer=slicer if isinstance(slicer, str) else None,
            slicer_time_s=metadata_number(t.metadata.get("slicer_time_s")),
            slicer_filament_mm=metadata_number(t.metadata.get("slicer_filament_mm")))


def plan_stream(source: str | os.PathLike[str] | bytes | BinaryIO, *,
                printer: PrinterProfile | str | os.PathLike[str] | None = None,
                klipper_config: str | os.PathLike[str] | None = None,
                use_slicer_limits: bool = False, strict: bool = False,
                chunk_bytes: int = CHUNK_BYTES,
                window_moves: int = WINDOW_MOVES) -> PlanStream:
    """Plan ``source`` for a printer in bounded memory (nothing is read until the returned
    stream is iterated or run).

    Parameters
    ----------
    source, printer, klipper_config, use_slicer_limits, strict
        As for :func:`~flowtwin.planner.plan_file.plan_gcode`. With ``use_slicer_limits`` the file
        is read twice (the slicer writes its machine limits at the end of the file).
    chunk_bytes
        Bytes read at a time.
    window_moves
        Moves per planning window (``>= 1000``).

    Returns
    -------
    PlanStream

    Raises
    ------
    ProfileError
        Bad printer profile or ``printer.cfg``; a Marlin delta (plan it with
        :func:`~flowtwin.planner.plan_file.plan_gcode`).
    DataError
        A bad ``window_moves``.
    """
    if klipper_config is not None:
        ks = load_printer_cfg(klipper_config)
        return PlanStream(source, options=klipper_read_options(ks, strict=strict),
                          plan=lambda t: plan_klipper(t, ks), printer=os.fspath(klipper_config),
                          settings=ks, chunk_bytes=chunk_bytes, window_moves=window_moves)
    profile = load_printer(printer)
    options = read_options(profile, strict=strict)
    if profile.firmware.planner is PlannerFamily.KLIPPER:
        kps = klipper_settings(profile)
        return PlanStream(source, options=options, plan=lambda t: plan_klipper(t, kps),
                          printer=profile.name, settings=kps, chunk_bytes=chunk_bytes,
                          window_moves=window_moves)
    ms = marlin_settings(profile)
    if ms.delta is not None:
        from flowtwin.errors import ProfileError

        raise ProfileError("a Marlin delta is planned in memory (its moves are cut into "
                           "segments over the whole file)", field="printer",
                           value=profile.name, allowed="plan_gcode for Marlin deltas")
    if use_slicer_limits:
        metadata: dict[str, object] = {}
        for chunk in iter_move_chunks(source, options=options, chunk_bytes=chunk_bytes):
            metadata = chunk.metadata or metadata
        sl = marlin_settings_from_slicer_config(metadata)
        ms = replace(sl, delta=ms.delta) if sl is not None else ms
    mss = ms
    return PlanStream(source, options=options, plan=lambda t: plan_marlin(t, mss),
                      printer=profile.name, settings=mss, chunk_bytes=chunk_bytes,
                      window_moves=window_moves)


def _source_name(source: object) -> str:
    if isinstance(source, str | os.PathLike):
        return "<stdin>" if os.fspath(source) == "-" else os.fspath(source)
    return "<bytes>" if isinstance(source, bytes | bytearray) else "<stream>"
