"""``postprocess`` of a file of any size in bounded memory: the streamed pass.

Above :data:`~flowtwin.planner.plan_stream.STREAM_ABOVE_BYTES` (or asked with ``--stream``)
:func:`~flowtwin.postprocess.postprocess` holds no whole-file table:

* **times**: one scan finds the lines whose figures are rewritten (``M73``, the slicers'
  time comments, ``M600``/``M601``); the file is then planned window by window
  (:func:`~flowtwin.planner.plan_stream.plan_stream`) and only the start of the first move
  at or after each of those lines is kept, with the dwells before those moves, and, for
  the progress lines a Marlin-family file gets, each layer's first move. The result is a
  :class:`~flowtwin.postprocess.times.PlanTimes` over those moves only: every figure it
  gives at those lines is the whole table's (the windows' clock agrees with one plan to
  ~1e-12 relative), so :func:`~flowtwin.postprocess.times.time_edits` writes the same
  lines as in memory;
* **the verdict**: the streamed simulation's aggregates
  (:func:`~flowtwin.simulation.simulate_stream`): grinding risk (moves, episodes, the
  smallest force margin and where), the flow and width errors per move with the worst
  moves, the moves above the melt capacity and the worst of them, ooze, time. The windowed
  places (worst over- and under-extrusion over one nozzle diameter of path, per feature)
  need the whole tables: they are not computed, and the verdict says so
  (``"windowed": null`` and ``"not_computed"``);
* **compensation** and the **HTML report** need the whole file: refused.

Memory: the plan's and the simulation's bounded buffers, one after the other, plus a few
numbers per rewritten line.
"""

from __future__ import annotations

import math
import os
import re
from array import array
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from flowtwin.gcode.inputs import line_chunks, open_source
from flowtwin.postprocess.times import PlanTimes, TimeEdits, format_dhms

if TYPE_CHECKING:
    from flowtwin.planner.windows import PlannedSpan
    from flowtwin.postprocess.lines import LineMap
    from flowtwin.postprocess.printer import PrinterChoice
    from flowtwin.postprocess.run import PostprocessOptions
    from flowtwin.simulation import StreamResult

__all__ = ["NOT_COMPUTED", "LineTimes", "StreamedPass", "check_stream", "silent_times_streamed",
           "slicer_config_streamed", "streamed_failures", "streamed_melt", "streamed_pass",
           "streamed_verdict"]

#: What a streamed verdict leaves out, and why (in the sidecar and on stderr).
NOT_COMPUTED = ("the file was streamed (larger than the in-memory limit, or --stream): the "
                "worst over- and under-extrusion places over one nozzle diameter of path, "
                "the per-feature flow figures, the line with the most ooze and the flow and "
                "speed limits of the advice need the whole print in memory and were not "
                "computed (run with --no-stream on a machine with the memory for them); "
                "the flow figures below are per move")
_COMMENT = re.compile(rb"^[ \t]*;([^\n]*)$", re.MULTILINE)
_CHUNK = 8 * 1024 * 1024


def slicer_config_streamed(source: str | os.PathLike[str]) -> dict[str, str] | None:
    """The slicer's embedded configuration (``metadata["slicer_config"]`` of the reader), from
    the file's whole-line comments read chunk by chunk; ``None`` when it has none."""
    from flowtwin.gcode.metadata import CommentInterpreter

    comments = CommentInterpreter()
    stream, name = open_source(source)
    try:
        for chunk in line_chunks(stream, name, _CHUNK):
            for m in _COMMENT.finditer(chunk):
                text = m.group(1).rstrip(b"\r")
                if b"=" in text or text.startswith(b"   "):
                    comments.feed(text.decode("utf-8", "replace"), 0, 0)
    finally:
        stream.close()
    config = comments.finish().get("slicer_config")
    return config if isinstance(config, dict) else None


class LineTimes:
    """Collects, from planned spans in file order, the times a rewriter needs at ``lines``
    (see the module docstring).

    Parameters
    ----------
    lines
        Line numbers whose elapsed time is asked for.
    layers
        Also find each layer's first move (the progress lines of a file without ``M73``).
    """

    def __init__(self, lines: list[int], *, layers: bool) -> None:
        self._need = np.unique(np.asarray(lines, dtype=np.int64))
        self._p = 0
        self._layers = layers
        self._kept: dict[int, tuple[int, float]] = {}   # move → (line, t_start)
        self._d_move = array("q")
        self._d_line = array("q")
        self._d_s = array("d")
        self._prev_line = -1
        self._prev_layer: int | None = None
        self._line_first: tuple[int, int, float] | None = None   # (move, line, t) of the
        self.progress: set[int] = set()                         # last line's first move
        self.moves = 0
        self.first_line = 0
        self.last_line = 0

    def add(self, span: PlannedSpan) -> None:
        """Take the next span."""
        from flowtwin.postprocess.times import _reason_line

        for move, seconds, reason in span.dwells:
            self._d_move.append(int(move))
            self._d_line.append(_reason_line(reason))
            self._d_s.append(float(seconds))
        n = len(span.moves)
        if not n:
            return
        ln = np.asarray(span.moves["line"], dtype=np.int64)
        ts = np.asarray(span.phases["t_start"], dtype=np.float64)
        if self.moves == 0:
            self.first_line = int(ln[0])
            if self._layers:   # the first progress line: the first move
                self._kept[span.start] = (int(ln[0]), float(ts[0]))
        q = int(np.searchsorted(self._need, ln[-1], side="right"))
        if q > self._p:
            for k in np.unique(np.searchsorted(ln, self._need[self._p:q], side="left")).tolist():
                self._kept[span.start + k] = (int(ln[k]), float(ts[k]))
            self._p = q
        if self._layers:
            layer = np.asarray(span.moves["layer"], dtype=np.int64)
            prev = layer[0] - 1 if self._prev_layer is None else self._prev_layer
            starts = np.flatnonzero(np.diff(layer, prepend=prev) != 0)
            starts = starts[layer[starts] >= 0]
            first = ln != np.concatenate(([self._prev_line], ln[:-1]))
            owner = np.maximum.accumulate(np.where(first, np.arange(n), -1))
            for s in starts.tolist():
                f = int(owner[s])
                if f >= 0:
                    self._kept[span.start + f] = (int(ln[f]), float(ts[f]))
                elif self._line_first is not None:
                    m, line, t = self._line_first
                    self._kept[m] = (line, t)
                self.progress.add(int(ln[s]))
            last_first = int(owner[-1])
            if last_first >= 0:
                self._line_first = (span.start + last_first, int(ln[last_first]),
                                    float(ts[last_first]))
            self._prev_layer = int(layer[-1])
        self._prev_line = int(ln[-1])
        self.moves += n
        self.last_line = int(ln[-1])

    def times(self, total_s: float, per_layer: list[dict[str, float | int]]) -> PlanTimes:
        """The :class:`PlanTimes` over the kept moves (after the last span)."""
        layer_s = {int(r["layer"]): float(r["time_s"]) for r in per_layer}
        idx = np.array(sorted(self._kept), dtype=np.int64)
        lines = np.array([self._kept[i][0] for i in idx.tolist()], dtype=np.int64)
        starts = np.array([self._kept[i][1] for i in idx.tolist()], dtype=np.float64)
        d_move = np.frombuffer(self._d_move, dtype=np.int64) if self._d_move else \
            np.zeros(0, np.int64)
        # a dwell counts at a kept move (its compressed index) or after the last move
        pos = np.searchsorted(idx, d_move)
        hit = (pos < idx.size) & (idx[np.minimum(pos, max(idx.size - 1, 0))] == d_move) \
            if idx.size else np.zeros(d_move.shape, bool)
        after = d_move >= self.moves
        keep = hit | after
        comp = np.where(after, idx.size, pos)[keep]
        return PlanTimes(total_s=float(total_s), first_layer_s=layer_s.get(0, 0.0),
                         before_first_layer_s=layer_s.get(-1, 0.0), move_lines=lines,
                         t_start=starts, dwell_move=comp.astype(np.int64),
                         dwell_line=np.asarray(self._d_line, dtype=np.int64)[keep],
                         dwell_s=np.asarray(self._d_s, dtype=np.float64)[keep])

    def progress_lines(self) -> list[int]:
        """Where a file without ``M73`` gets them: the first move, each layer's first move,
        after the last move (as :func:`~flowtwin.postprocess.run.postprocess` in memory)."""
        if not self.moves:
            return []
        return sorted({self.first_line, *self.progress, self.last_line + 1})


#: Commands that set Marlin-style machine limits (PrusaSlicer's silent mode ignores those
#: before the first move).
_LIMIT_CODES = frozenset({"M201", "M203", "M204", "M205"})


def silent_times_streamed(work: Path, choice: PrinterChoice, lines: list[int]) -> PlanTimes:
    """:func:`~flowtwin.postprocess.run._silent_times` planned window by window: PrusaSlicer's
    silent-mode limits, the file's limit commands before its first move dropped."""
    from flowtwin.gcode.moves import MoveTable
    from flowtwin.gcode.reader import iter_move_chunks
    from flowtwin.planner.from_profile import marlin_settings, read_options
    from flowtwin.planner.marlin import plan_marlin
    from flowtwin.planner.plan_stream import CHUNK_BYTES, WINDOW_MOVES
    from flowtwin.planner.totals import PlanTotals
    from flowtwin.planner.windows import LEAD_MOVES, WindowPlanner

    assert choice.silent is not None
    options = read_options(choice.silent)
    ms = marlin_settings(choice.silent)
    wp = WindowPlanner(lambda t: plan_marlin(t, ms), str(work),
                       np.array([*options.start_xyz, 0.0]), window_moves=WINDOW_MOVES,
                       lead_moves=min(LEAD_MOVES, WINDOW_MOVES // 4))
    collect = LineTimes(lines, layers=False)
    totals = PlanTotals()
    last: MoveTable | None = None
    end = 0.0

    def chunks() -> Iterator[MoveTable]:
        seen = 0
        for chunk in iter_move_chunks(work, options=options, chunk_bytes=CHUNK_BYTES):
            if seen == 0:
                chunk.events = [e for e in chunk.events
                                if not (e.move_index == 0 and e.code in _LIMIT_CODES)]
            seen += len(chunk)
            yield chunk

    def take(span: PlannedSpan) -> None:
        nonlocal end
        collect.add(span)
        totals.add(span.moves, span.phases,
                   [(d[0] - span.start, d[1], d[2]) for d in span.dwells])
        end = span.end_time_s

    for chunk in chunks():
        last = chunk
        for span in wp.feed(chunk):
            take(span)
    for span in wp.finish():
        take(span)
    return collect.times(end, totals.per_layer([] if last is None else last.layer_z))


# ---- the verdict of a streamed simulation ----------------------------------------------------
def streamed_melt(res: StreamResult, lines: LineMap) -> dict[str, object]:
    """Moves beyond the melt capacity, as :func:`~flowtwin.postprocess.run._melt` words them
    (``lines``: line numbers of the written file)."""
    agg = res.aggregates
    w = agg.worst_over_flow
    if not agg.over_flow_limit or w is None:
        return {"moves": 0, "text": "No move asks for more than the hot end can melt."}
    k = int(w["feature"])
    feature = agg.features[k] if 0 <= k < len(agg.features) else ""
    n, line, layer = agg.over_flow_limit, lines(int(w["line"])), int(w["layer"])
    flow, limit = float(w["flow_mm3_s"]), float(w["limit_mm3_s"])
    return {"moves": n, "worst_line": line, "worst_layer": layer, "worst_feature": feature,
            "worst_flow_mm3_s": flow, "limit_mm3_s": limit,
            "text": (f"{n} moves ask for more than the hot end can melt; worst at line {line} "
                     f"(layer {layer}, {feature or 'no feature'}): "
                     f"{flow:.1f} mm³/s against {limit:.1f} mm³/s.")}


def _pct(v: float) -> str:
    return f"{100 * v:+.1f} %" if math.isfinite(v) else "–"


def streamed_verdict(res: StreamResult) -> tuple[dict[str, object], list[str]]:
    """The verdict of a streamed simulation: a JSON-able dictionary (the grinding risk, the
    per-move figures, the worst moves; ``"windowed": None`` and :data:`NOT_COMPUTED`) and
    its sentences (headline first)."""
    from flowtwin.compensation.guard import GuardOptions

    s = res.aggregates.summary()
    safety = GuardOptions().safety
    force = res.worst_moves("force", 1)
    grinding_moves = s.grinding_moves
    grinding: dict[str, object] = {
        "level": "grinds" if grinding_moves > 0 else "safe",
        "min_margin_n": None, "min_margin_share": None,
        "max_feed_force_n": s.max_feed_force_n, "grip_n": None,
        "grinding_moves": grinding_moves,
        "grinding_events": s.grinding_events,
        "line": 0, "layer": -1, "safety": safety}
    if force:
        r = force[0]
        margin = float(r["force_margin_n"])
        grip = float(r["peak_force_n"]) + margin   # margin = grip − peak force
        share = margin / grip if grip > 0 else math.nan
        if grinding_moves == 0 and share < 1.0 - safety:
            grinding["level"] = "at risk"
        grinding.update(min_margin_n=margin, min_margin_share=share, grip_n=grip,
                        line=int(r["line"]), layer=int(r["layer"]))
    time_s = s.total_time_s
    over, under = s.peak_overextrusion, s.peak_underextrusion
    width = res.worst_moves("width", 10)
    verdict: dict[str, object] = {
        "streamed": True, "not_computed": NOT_COMPUTED, "windowed": None,
        "file": s.file, "machine": s.machine, "printer": s.printer,
        "firmware": s.firmware, "pressure_advance": s.pressure_advance,
        "print_time_s": time_s, "grinding": grinding,
        "peak_overextrusion_per_move": over, "peak_underextrusion_per_move": -under,
        "worst_width_error_mm": s.worst_width_error_mm,
        "rms_flow_error": s.rms_flow_error, "volume_error": s.volume_error,
        "mean_slip": s.mean_slip, "ooze_mm3": s.ooze_volume_mm3,
        "narrow_beads": s.narrow_beads,
        "moves_over_flow_limit": s.moves_over_flow_limit,
        "worst_moves_width": width, "worst_moves_force": res.worst_moves("force", 10)}
    g = grinding
    margin_n = g["min_margin_n"]
    grind = {"grinds": f"the drive grinds the filament ({grinding_moves} moves)",
             "at risk": (f"the drive comes within {margin_n:.1f} N of grinding "
                         f"({100 * float(g['min_margin_share']):.0f} % margin)"  # type: ignore[arg-type]
                         if isinstance(margin_n, float) else ""),
             "safe": (f"no grinding risk ({margin_n:.0f} N margin)"
                      if isinstance(margin_n, float) else "no grinding risk")}[str(g["level"])]
    headline = (f"{grind}; per move the flow is within {_pct(over)} / {_pct(-under)} of the "
                f"command (windowed places not computed: the file was streamed); it takes "
                f"{format_dhms(time_s)}.")
    out = [headline[0].upper() + headline[1:]]
    if isinstance(margin_n, float):
        out.append(f"Grinding: {g['level']}. The smallest margin of the feed force to the "
                   f"roller's grip is {margin_n:.1f} N "
                   f"({100 * float(g['min_margin_share']):.0f} % of "  # type: ignore[arg-type]
                   f"{float(g['grip_n']):.0f} N) at line {g['line']} (layer {g['layer']}); "  # type: ignore[arg-type]
                   f"peak force {s.max_feed_force_n:.1f} N.")
    if width:
        w = width[0]
        out.append(f"Worst bead width error of a move: {float(w['width_mean_mm']):.2f} mm "
                   f"against {float(w['width_nominal_mm']):.2f} mm at line {w['line']} "
                   f"(layer {w['layer']}).")
    out.append(f"Volume: {_pct(s.volume_error)} over the print; RMS flow error "
               f"per move {100 * s.rms_flow_error:.1f} %; drive slip "
               f"{100 * s.mean_slip:.2f} %.")
    out.append(f"Ooze during travels and stops: {s.ooze_volume_mm3:.2f} mm³.")
    out.append(f"Print time: {format_dhms(time_s)}.")
    out.append(f"Not computed: {NOT_COMPUTED}.")
    return verdict, out


def streamed_failures(fail_on: frozenset[str], verdict: dict[str, object],
                      melt: dict[str, object], lines: LineMap) -> list[str]:
    """The ``--fail-on`` messages of a streamed verdict."""
    out = []
    g = verdict["grinding"]
    assert isinstance(g, dict)
    if "grinding" in fail_on and g["level"] == "grinds":
        out.append(f"the twin predicts the drive grinds the filament ({g['grinding_moves']} "
                   f"moves, {g['grinding_events']} episodes); the smallest margin is at line "
                   f"{lines(int(g['line']))} (layer {g['layer']}). Lower the volumetric flow "
                   "there, or add --guard (on a file small enough to hold in memory).")
    if "melt-limit" in fail_on and int(melt.get("moves", 0)):  # type: ignore[call-overload]
        out.append(f"{melt['text']} Lower the slicer's maximum volumetric speed below "
                   f"{float(melt['limit_mm3_s']):.1f} mm³/s or raise the temperature.")  # type: ignore[arg-type]
    return out


def check_stream(path: Path, choice: PrinterChoice, opts: PostprocessOptions) -> bool:
    """Whether to stream a file chosen for streaming: not a Marlin delta (planned in memory:
    refused when ``--stream`` was asked for); compensation and the report are refused."""
    from flowtwin.errors import DataError
    from flowtwin.planner.plan_stream import STREAM_ABOVE_BYTES, should_stream

    if not should_stream(path, printer=choice.machine.printer,
                         klipper_config=choice.klipper_config, above_bytes=-1):
        if opts.stream:
            raise DataError("a Marlin delta is planned in memory; it cannot be streamed",
                            field="--stream", value=choice.machine.printer.name,
                            allowed="--no-stream")
        return False
    why = ("asked for with --stream" if opts.stream else
           f"{path.stat().st_size / 2**20:.0f} MB, above the "
           f"{STREAM_ABOVE_BYTES / 2**20:.0f} MB streamed above")
    asked = [f"--{n}" for n in (*opts.compensations, *(("report",) if opts.report else ()))]
    if asked:
        raise DataError(f"{', '.join(asked)} need the whole file in memory, and this file "
                        f"is processed in bounded memory ({why})", source=path,
                        field=asked[0], value="on",
                        allowed="times and verdict only (drop the option), or --no-stream "
                                "on a machine with the memory for the whole file")
    return True


# ---- the whole streamed pass -----------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class StreamedPass:
    """What the streamed pass found (the in-memory path's pieces of a
    :class:`~flowtwin.postprocess.run.PostprocessResult`)."""

    times: PlanTimes
    silent: PlanTimes | None
    edits: TimeEdits
    lines: LineMap
    verdict: dict[str, object]
    sentences: list[str]
    melt: dict[str, object]
    per_layer: list[dict[str, float | int]]
    slicer_time_s: object
    warnings: list[str]


def streamed_pass(work: Path, choice: PrinterChoice,
                  header: Callable[[PlanTimes], list[str]],
                  step: Callable[[str], None]) -> StreamedPass:
    """Times, edits and verdict of ``work`` in bounded memory (see the module docstring);
    ``header``: the flowtwin comment lines for the times."""
    from flowtwin.firmware import PlannerFamily
    from flowtwin.planner.plan_stream import plan_stream
    from flowtwin.postprocess.lines import LineMap
    from flowtwin.postprocess.scan import scan_gcode
    from flowtwin.postprocess.times import time_edits
    from flowtwin.simulation import simulate_stream

    step("scan")
    scan = scan_gcode(work)
    need = [line for line, _t in scan.candidates] + list(scan.stops)
    marlin = choice.firmware.planner is PlannerFamily.MARLIN
    step("plan")
    ps = plan_stream(work, printer=choice.machine.printer, klipper_config=choice.klipper_config)
    collect = LineTimes(need, layers=marlin)
    for span in ps:
        collect.add(span)
    per_layer = ps.per_layer()
    times = collect.times(ps.total_time_s, per_layer)
    progress = collect.progress_lines() if marlin else []
    silent = None
    if choice.silent is not None:
        step("plan silent mode")
        silent = silent_times_streamed(work, choice, need + progress)
    has_progress = any(t.lstrip().startswith("M73") and re.search(r"\s[PQ][\d.]", t)
                       for _line, t in scan.candidates)
    if progress and not has_progress:
        scan = scan_gcode(work, wanted=progress)   # the texts of the lines M73 goes before
    step("times")
    edits = time_edits(scan, times, silent=silent, header=header(times),
                       progress_at=progress or None)
    lines = LineMap(edits.edits, edits.original_index)
    step("simulate")
    res = simulate_stream(work, machine=choice.machine, klipper_config=choice.klipper_config)
    step("verdict")
    verdict, sentences = streamed_verdict(res)
    warnings = [*ps.warnings[:20], *res.aggregates.warning_texts()[:20]]
    return StreamedPass(times=times, silent=silent, edits=edits, lines=lines, verdict=verdict,
                        sentences=sentences, melt=streamed_melt(res, lines),
                        per_layer=per_layer, slicer_time_s=ps.summary().slicer_time_s,
                        warnings=warnings)
