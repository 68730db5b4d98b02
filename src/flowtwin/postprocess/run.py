"""``postprocess``: one pass of the twin over a G-code, in the slicer's post-processing step.

1. the printer and set-up are decided (:mod:`flowtwin.postprocess.printer`): a Klipper
   ``printer.cfg`` (a file or the live one from Moonraker), else the slicer's settings, else
   the profile;
2. optionally the file is compensated (the public :func:`flowtwin.compensation.compensate`:
   advance, slip, pacing, grinding guard) into a temporary file;
3. the (compensated) file is simulated; its plan gives the times, the simulation the verdict
   (:func:`flowtwin.report.build_verdict`) and the moves beyond the melt capacity;
4. with ``fail_on`` met, nothing is written to the G-code (the slicer shows the message and
   keeps its file); else the slicer's time lines are rewritten with the planner's figures
   (:mod:`flowtwin.postprocess.times`) and the file is replaced atomically, stored as it
   was (text, gzip or ``.bgcode``);
5. the verdict goes to a JSON sidecar ``<output>.flowtwin.json`` (and, on request, the HTML
   report ``<output>.report.html``) beside the slicer's final output name.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from flowtwin.errors import DataError, GcodeError
from flowtwin.firmware import PlannerFamily
from flowtwin.postprocess.lines import LineMap, remap_lines
from flowtwin.postprocess.printer import PrinterChoice, resolve_printer
from flowtwin.postprocess.scan import FLOWTWIN_MARK
from flowtwin.postprocess.slicer import SlicerContext
from flowtwin.postprocess.times import PlanTimes, TimeEdits, format_dhms

if TYPE_CHECKING:
    from flowtwin.compensation import CompensationReport
    from flowtwin.simulation import SimulationResult

__all__ = ["FAIL_ON", "PostprocessOptions", "PostprocessResult", "json_clean", "postprocess",
           "sidecar_path"]

#: Conditions ``fail_on`` accepts.
FAIL_ON = ("grinding", "melt-limit")
#: Suffix of the JSON sidecar added to the output's file name.
SIDECAR_SUFFIX = ".flowtwin.json"
#: Suffix of the HTML report added to the output's file name.
REPORT_SUFFIX = ".report.html"

Progress = Callable[[str], None]


@dataclass(frozen=True, slots=True)
class PostprocessOptions:
    """What a run does.

    Attributes
    ----------
    setup
        Set-up (built-in name or TOML); default the simulation's default.
    klipper_config
        A Klipper ``printer.cfg`` to plan with.
    moonraker
        URL of a Klipper printer's Moonraker whose live configuration to plan with.
    advance, slip, pace, guard
        Compensations to apply (:func:`flowtwin.compensation.compensate`).
    pace_budget
        Share of the print time the pacing may add (``PaceOptions.time_budget``; ``None``:
        no cap).
    report
        Also write the HTML report.
    fail_on
        Conditions that stop the export (``"grinding"``, ``"melt-limit"``).
    stream
        Bounded memory (:mod:`flowtwin.postprocess.stream`): ``None`` streams files above
        :data:`~flowtwin.planner.plan_stream.STREAM_ABOVE_BYTES`.
    """

    setup: str | None = None
    klipper_config: str | os.PathLike[str] | None = None
    moonraker: str | None = None
    advance: bool = False
    slip: bool = False
    pace: bool = False
    pace_budget: float | None = 0.10  # PaceOptions().time_budget (not imported: lean start)
    guard: bool = False
    report: bool = False
    fail_on: frozenset[str] = frozenset()
    stream: bool | None = None

    def __post_init__(self) -> None:
        bad = sorted(set(self.fail_on) - set(FAIL_ON))
        if bad:
            raise DataError("unknown --fail-on condition", field="--fail-on", value=bad[0],
                            allowed=", ".join((*FAIL_ON, "none")))
        if self.klipper_config is not None and self.moonraker is not None:
            raise DataError("give the printer once", field="--moonraker",
                            value=self.moonraker, allowed="--klipper-config or --moonraker")

    @property
    def compensations(self) -> tuple[str, ...]:
        """Names of the compensations asked for."""
        return tuple(n for n in ("advance", "slip", "pace", "guard") if getattr(self, n))


@dataclass(frozen=True, slots=True)
class PostprocessResult:
    """What a run did and found.

    Attributes
    ----------
    gcode
        The file processed (edited in place unless ``written`` is false).
    output
        The slicer's final output name (where the sidecar and report go).
    written
        The G-code was rewritten (false when a ``fail_on`` condition stopped the export).
    failures
        One message per ``fail_on`` condition met.
    verdict
        The twin's verdict as a JSON-able dictionary, line numbers of the written file.
    sentences
        The verdict in plain sentences, line numbers of the written file.
    melt
        Moves above the machine's maximum volumetric flow: count, worst move.
    times
        The figures written (s) and what was rewritten.
    choice
        The printer and set-up used.
    slicer
        What the slicer passed.
    settings_source
        ``"environment"``, ``"embedded"`` or ``"none"``.
    compensation
        The compensation's summary, or ``None``.
    sidecar, report
        Files written beside the output (``report``: ``None`` unless asked for).
    warnings
        Notes on the printer and the planner's and simulation's warnings.
    sidecar_written
        False when the sidecar could not be written (the reason is the last warning).
    streamed
        The file was processed in bounded memory (the verdict without windowed places).
    """

    gcode: Path
    output: Path
    written: bool
    failures: tuple[str, ...]
    verdict: dict[str, object]
    sentences: tuple[str, ...]
    melt: dict[str, object]
    times: dict[str, object]
    choice: PrinterChoice
    slicer: SlicerContext
    settings_source: str
    compensation: dict[str, object] | None
    sidecar: Path
    report: Path | None
    warnings: tuple[str, ...] = field(default_factory=tuple)
    sidecar_written: bool = True
    streamed: bool = False

    def as_dict(self) -> dict[str, object]:
        """The sidecar's content."""
        from flowtwin import __version__

        m = self.choice.machine
        return {
            "flowtwin": __version__,
            "gcode": str(self.gcode), "output": str(self.output), "written": self.written,
            "streamed": self.streamed,
            "failed": bool(self.failures), "failures": list(self.failures),
            "slicer": {"host": self.slicer.host, "output_name": self.slicer.output_name,
                       "settings": self.settings_source},
            "printer": {"source": self.choice.source, "label": self.choice.label,
                        "firmware": self.choice.firmware.value,
                        "klipper_config": (None if self.choice.klipper_config is None
                                           else str(self.choice.klipper_config)),
                        "profile": m.printer.model_dump(mode="json"),
                        "silent_profile": (None if self.choice.silent is None else
                                           self.choice.silent.model_dump(mode="json")),
                        "notes": list(self.choice.notes)},
            "setup": {"name": m.name, "drive": m.drive.name, "hotend": m.hotend.name,
                      "nozzle_diameter_mm": m.hotend.nozzle_diameter_mm,
                      "material": m.material.name, "filament": m.filament.name,
                      "filament_diameter_mm": m.filament.diameter_mm,
                      "temperature_c": m.temperature_c},
            "times": self.times, "verdict": self.verdict,
            "verdict_text": list(self.sentences), "melt_limit": self.melt,
            "compensation": self.compensation,
            "sidecar": str(self.sidecar),
            "report": None if self.report is None else str(self.report),
            "warnings": list(self.warnings),
        }

    def stderr_lines(self) -> list[str]:
        """A few lines for the slicer's log or error dialog."""
        t = self.times
        out = []
        if self.failures:
            out.append("flowtwin: export stopped (--fail-on):")
            out += [f"  {f}" for f in self.failures]
        c = self.compensation
        if c is None:
            out.append(f"flowtwin: {self.sentences[0]}" if self.sentences else "flowtwin:")
            out += [f"  {s}" for s in self.sentences[1:4]]
        else:
            # the verdict's flow figures measure the file against its own E (which holds
            # the baked advance): against the slicer's intent the compensation's count
            names = ", ".join(str(n) for n in c["transformations"]) or "nothing"  # type: ignore[attr-defined]
            out.append(f"flowtwin: compensated ({names}); against the slicer's intent the RMS "
                       f"flow error goes {_pct(c['rms_flow_error_before'], '')} → "
                       f"{_pct(c['rms_flow_error_after'], '')}, the worst over "
                       f"{c['peak_window_mm']} mm of path "
                       f"{_pct(c['peak_overextrusion_window_before'])} → "
                       f"{_pct(c['peak_overextrusion_window_after'])}.")
            out += [f"  {s}" for s in self.sentences[1:2]]
            from flowtwin.compensation.outcome import pace_note

            note = pace_note(c.get("pace"), float(c["time_before_s"]))  # type: ignore[attr-defined, arg-type]
            if note is not None:
                out.append(f"  {note[0].upper()}{note[1:]}.")
        n = int(self.melt.get("moves", 0))  # type: ignore[call-overload]
        if n:
            out.append(f"  {self.melt['text']}")
        out.append(f"  Print time {format_dhms(float(t['total_s']))} "  # type: ignore[arg-type]
                   f"({self.choice.firmware.label} planner, {self.choice.source}); "
                   f"the slicer said {t.get('slicer_estimate') or 'nothing'}.")
        if self.sidecar_written:
            out.append(f"  Details: {self.sidecar}"
                       + (f", {self.report}" if self.report else ""))
        else:
            out.append(f"  warning: {self.warnings[-1]}")
        return out


def _pct(v: object, sign: str = "+") -> str:
    if isinstance(v, int | float) and math.isfinite(v):
        return f"{100 * float(v):{sign}.1f} %"
    return "–"


def sidecar_path(output: Path) -> Path:
    """The JSON sidecar of an output G-code: ``<output>.flowtwin.json``."""
    return output.with_name(output.name + SIDECAR_SUFFIX)


def _melt(result: object, lines: LineMap) -> dict[str, object]:
    """Moves beyond the melt capacity: how many, and the worst (flow over limit)."""
    from flowtwin.simulation import SimulationResult

    assert isinstance(result, SimulationResult)
    p = result.parameters
    over = p.over_flow_limit
    if over is None or p.flow_limit_mm3_s is None or not np.any(over):
        return {"moves": 0, "text": "No move asks for more than the hot end can melt."}
    tab = result.plan.table
    m = tab.moves
    d = result.dynamics.moves
    dur = np.asarray(d["duration_s"], dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        flow = np.where(dur > 0, np.asarray(d["cmd_mm3"], dtype=np.float64) / dur, 0.0)
        ratio = np.where(over, flow / p.flow_limit_mm3_s, 0.0)
    i = int(np.nanargmax(ratio))
    k = int(m["feature"][i])
    feature = tab.features[k] if 0 <= k < len(tab.features) else ""
    n = int(np.count_nonzero(over))
    line = lines(int(m["line"][i]))
    return {"moves": n, "worst_line": line, "worst_layer": int(m["layer"][i]),
            "worst_feature": feature, "worst_flow_mm3_s": float(flow[i]),
            "limit_mm3_s": float(p.flow_limit_mm3_s[i]),
            "text": (f"{n} moves ask for more than the hot end can melt; worst at line {line} "
                     f"(layer {int(m['layer'][i])}, {feature or 'no feature'}): "
                     f"{flow[i]:.1f} mm³/s against {p.flow_limit_mm3_s[i]:.1f} mm³/s.")}


def _header(times: PlanTimes, choice: PrinterChoice, settings_source: str,
            compensations: tuple[str, ...]) -> list[str]:
    from flowtwin import __version__

    label = choice.label.replace("=", "-")
    comp = ", ".join(compensations) or "none"
    return [f"{FLOWTWIN_MARK} {__version__}: print time {format_dhms(times.total_s)} "
            f"({times.total_s:.2f} s), first layer {format_dhms(times.first_layer_s)}; model: "
            f"{choice.firmware.label} planner and extrusion twin of set-up "
            f"{choice.machine.name!r}; configuration: {label}; slicer settings: "
            f"{settings_source}; compensation: {comp}"]


def postprocess(gcode: str | os.PathLike[str], options: PostprocessOptions | None = None, *,
                env: Mapping[str, str] | None = None,
                progress: Progress | None = None) -> PostprocessResult:
    """Post-process ``gcode`` in place (see the module docstring).

    Parameters
    ----------
    gcode
        The G-code the slicer passed (plain, gzip or ``.bgcode``; may be a temporary copy).
    options
        What to do (:class:`PostprocessOptions`).
    env
        The environment to read the slicer's ``SLIC3R_*`` variables from (default
        ``os.environ``).
    progress
        Called with the name of each stage as it starts.

    Returns
    -------
    PostprocessResult

    Raises
    ------
    GcodeError, ProfileError, PrinterConnectionError, FileAccessError
        Unreadable G-code, bad profiles or configuration, an unreachable Moonraker, an
        output that cannot be written. The G-code is then left as it was.
    """
    from flowtwin.gcode.writer import rewrite_gcode
    from flowtwin.report.verdict import build_verdict
    from flowtwin.simulation import simulate

    opts = options or PostprocessOptions()
    step = progress or (lambda _s: None)
    path = Path(gcode)
    if not path.is_file():
        raise GcodeError("no such G-code file", source=path,
                         allowed="the G-code path the slicer passes as the last argument")
    ctx = SlicerContext.from_environment(env)
    output = ctx.final_path(path)
    with tempfile.TemporaryDirectory(prefix="flowtwin-postprocess-") as tmp:
        step("printer")
        cfg: str | os.PathLike[str] | None = opts.klipper_config
        cfg_source = "klipper-config"
        if opts.moonraker:
            from flowtwin.postprocess.moonraker import moonraker_printer_cfg

            cfg, cfg_source = moonraker_printer_cfg(opts.moonraker, tmp), opts.moonraker
        from flowtwin.planner.plan_stream import is_large

        streamed = opts.stream if opts.stream is not None else is_large(path)
        settings = ctx.settings(None)
        if settings is None:
            # the embedded block from the comments alone: planning the file here, before
            # the printer that chooses the reader's options is known, would read it twice
            from flowtwin.postprocess.stream import slicer_config_streamed

            settings = ctx.settings(slicer_config_streamed(path))
        choice = resolve_printer(setup=opts.setup, klipper_config=cfg, settings=settings,
                                 config_source=cfg_source)
        if streamed:
            from flowtwin.postprocess.stream import check_stream

            streamed = check_stream(path, choice, opts)
        settings_source = settings.source if settings else "none"
        if streamed:
            return _finish_streamed(path, output, ctx, choice, settings_source, opts, step)
        work = path
        comp_summary = None
        comp_report = None
        result = None
        if opts.compensations:
            step("compensate")
            work = Path(tmp) / ("compensated" + "".join(path.suffixes[-2:]))
            comp_report, result = _compensate(path, work, choice, opts)
            comp_summary = comp_report.as_dict()
            comp_summary.pop("slowed_lines", None)
            comp_summary.pop("paced_lines", None)
        if result is None:
            step("simulate")
            result = simulate(work, machine=choice.machine,
                              klipper_config=choice.klipper_config,
                              pressure_advance=not opts.advance)
        times = PlanTimes.of(result.plan.table, result.plan.timeline)
        silent = None if choice.silent is None else _silent_times(work, choice)
        step("verdict")
        verdict = build_verdict(result)
        step("times")
        edits = _time_edits(work, result, times, silent, choice,
                            settings.source if settings else "none", opts.compensations)
        lines = LineMap(edits.edits, edits.original_index)
        melt = _melt(result, lines)
        failures = _failures(opts.fail_on, verdict, melt, lines)
        report = None
        if opts.report:
            step("report")
            report = _write_report(result, verdict, comp_report, output)
        written = False
        if not failures:
            step("write")
            rewrite_gcode(work, path, edits.edits)
            written = True
    slicer_time = result.plan.table.metadata.get("slicer_time_s")
    times_out: dict[str, object] = {
        "total_s": times.total_s, "first_layer_s": times.first_layer_s,
        "before_first_layer_s": times.before_first_layer_s,
        "silent_total_s": None if silent is None else silent.total_s,
        "slicer_estimate_s": slicer_time,
        "slicer_estimate": (None if not isinstance(slicer_time, int | float)
                            else format_dhms(float(slicer_time))),
        "rewritten": edits.rewritten, "progress_added": edits.progress_added,
        "per_layer": result.plan.per_layer(),
    }
    warnings = (*choice.notes, *result.plan.table.warnings[:20],
                *result.plan.timeline.warnings[:20], *result.warnings[:20])
    out = PostprocessResult(
        gcode=path, output=output, written=written, failures=tuple(failures),
        verdict=remap_lines(verdict.as_dict(), lines),  # type: ignore[arg-type]
        sentences=tuple(remap_lines(verdict.sentences(), lines)),  # type: ignore[arg-type]
        melt=melt, times=times_out, choice=choice, slicer=ctx,
        settings_source=settings.source if settings else "none",
        compensation=comp_summary, sidecar=sidecar_path(output), report=report,
        warnings=tuple(str(w) for w in warnings))
    return _with_sidecar(out)


def _with_sidecar(out: PostprocessResult) -> PostprocessResult:
    """``out`` after writing its sidecar (a sidecar that cannot be written is noted: the
    G-code is done, not worth failing for it)."""
    problem = _write_sidecar(out)
    if problem is not None:
        from dataclasses import replace

        out = replace(out, sidecar_written=False,
                      warnings=(*out.warnings, f"sidecar not written: {problem}"))
    return out


def _finish_streamed(path: Path, output: Path, ctx: SlicerContext, choice: PrinterChoice,
                     settings_source: str, opts: PostprocessOptions,
                     step: Progress) -> PostprocessResult:
    """The bounded-memory pass (:mod:`flowtwin.postprocess.stream`): times, verdict,
    ``--fail-on``, the rewrite and the sidecar."""
    from flowtwin.gcode.writer import rewrite_gcode
    from flowtwin.postprocess.stream import streamed_failures, streamed_pass

    sp = streamed_pass(path, choice, lambda t: _header(t, choice, settings_source, ()), step)
    failures = streamed_failures(opts.fail_on, sp.verdict, sp.melt, sp.lines)
    if not failures:
        step("write")
        rewrite_gcode(path, path, sp.edits.edits)
    t, slicer_time = sp.times, sp.slicer_time_s
    times_out: dict[str, object] = {
        "total_s": t.total_s, "first_layer_s": t.first_layer_s,
        "before_first_layer_s": t.before_first_layer_s,
        "silent_total_s": None if sp.silent is None else sp.silent.total_s,
        "slicer_estimate_s": slicer_time,
        "slicer_estimate": (None if not isinstance(slicer_time, int | float)
                            else format_dhms(float(slicer_time))),
        "rewritten": sp.edits.rewritten, "progress_added": sp.edits.progress_added,
        "per_layer": sp.per_layer,
    }
    out = PostprocessResult(
        gcode=path, output=output, written=not failures, failures=tuple(failures),
        verdict=remap_lines(sp.verdict, sp.lines),  # type: ignore[arg-type]
        sentences=tuple(remap_lines(sp.sentences, sp.lines)),  # type: ignore[arg-type]
        melt=sp.melt, times=times_out, choice=choice, slicer=ctx,
        settings_source=settings_source, compensation=None, sidecar=sidecar_path(output),
        report=None, warnings=tuple(str(w) for w in (*choice.notes, *sp.warnings)),
        streamed=True)
    return _with_sidecar(out)


#: Commands that set Marlin-style machine limits.
_LIMIT_CODES = frozenset({"M201", "M203", "M204", "M205"})


def _silent_times(work: Path, choice: PrinterChoice) -> PlanTimes:
    """Times in PrusaSlicer's silent (stealth) mode: the slicer's second machine limits,
    and, as PrusaSlicer's estimator has it (``GCodeProcessor::process_M201`` …), the
    file's limit commands before its first move set the normal mode only."""
    from dataclasses import replace

    from flowtwin.gcode.reader import read_gcode
    from flowtwin.planner.from_profile import marlin_settings, read_options
    from flowtwin.planner.marlin import plan_marlin

    assert choice.silent is not None
    table = read_gcode(work, options=read_options(choice.silent))
    table = replace(table, events=[e for e in table.events
                                   if not (e.move_index == 0 and e.code in _LIMIT_CODES)])
    return PlanTimes.of(table, plan_marlin(table, marlin_settings(choice.silent)))


def _compensate(src: Path, dst: Path, choice: PrinterChoice, opts: PostprocessOptions
                ) -> tuple[CompensationReport, SimulationResult | None]:
    """The compensations asked for, through the public API (defaults for every option):
    the report and its simulation of the written file (``None``: simulate it)."""
    from flowtwin.compensation import PaceOptions, compensate

    rep = compensate(src, dst, machine=choice.machine, klipper_config=choice.klipper_config,
                     advance=opts.advance or None, slip=opts.slip or None,
                     pace=PaceOptions(time_budget=opts.pace_budget) if opts.pace else None,
                     guard=opts.guard or None)
    after = getattr(rep, "compensated_result", None)
    if after is not None and Path(after.plan.table.source) != dst:
        after = None
    return rep, after


def _time_edits(work: Path, result: object, times: PlanTimes, silent: PlanTimes | None,
                choice: PrinterChoice, settings_source: str,
                compensations: tuple[str, ...]) -> TimeEdits:
    from flowtwin.postprocess.scan import scan_gcode
    from flowtwin.postprocess.times import time_edits
    from flowtwin.simulation import SimulationResult

    assert isinstance(result, SimulationResult)
    progress: list[int] | None = None
    if choice.firmware.planner is PlannerFamily.MARLIN and times.move_lines.size:
        # M73 before the first move, at each layer's first move and after the last move
        layer = np.asarray(result.plan.table.moves["layer"], dtype=np.int64)
        starts = np.flatnonzero(np.diff(layer, prepend=layer[0] - 1) != 0)
        progress = sorted({int(times.move_lines[0]),
                           *(int(times.move_lines[i]) for i in starts.tolist()
                             if layer[i] >= 0),
                           int(times.move_lines[-1]) + 1})
    scan = scan_gcode(work, wanted=progress or ())
    header = _header(times, choice, settings_source, compensations)
    return time_edits(scan, times, silent=silent, header=header, progress_at=progress)


def _failures(fail_on: frozenset[str], verdict: object, melt: dict[str, object],
              lines: LineMap) -> list[str]:
    from flowtwin.report.verdict import Verdict

    assert isinstance(verdict, Verdict)
    out = []
    g = verdict.grinding
    if "grinding" in fail_on and g.level == "grinds":
        fix = ""
        if math.isfinite(g.flow_limit_mm3_s):
            fix = (f" Keep the volumetric flow below {g.flow_limit_mm3_s:.1f} mm³/s or print "
                   f"that feature at most {g.speed_limit_mm_s:.0f} mm/s, or add --guard.")
        out.append(f"the twin predicts the drive grinds the filament ({g.grinding_moves} "
                   f"moves, {g.grinding_events} episodes); the smallest margin is at line "
                   f"{lines(g.line)} (layer {g.layer}, {g.feature or 'no feature'}).{fix}")
    if "melt-limit" in fail_on and int(melt.get("moves", 0)):  # type: ignore[call-overload]
        out.append(f"{melt['text']} Lower the slicer's maximum volumetric speed below "
                   f"{float(melt['limit_mm3_s']):.1f} mm³/s or raise the temperature.")  # type: ignore[arg-type]
    return out


def _write_report(result: SimulationResult, verdict: object,
                  comp: CompensationReport | None, output: Path) -> Path:
    """The HTML report beside the output: before / after for a compensated file (when the
    compensation kept its simulations), else the simulation's report."""
    from flowtwin.report import write_comparison, write_report
    from flowtwin.report.verdict import Verdict

    assert isinstance(verdict, Verdict)
    target = output.with_name(output.name + REPORT_SUFFIX)
    if comp is not None and comp.original_result is not None and \
            comp.compensated_result is not None and comp.piece_row is not None:
        return write_comparison(comp, target)
    return write_report(result, target, verdict=verdict)


def _write_sidecar(result: PostprocessResult) -> str | None:
    """Write the sidecar; the error message when it cannot be written."""
    import json

    from flowtwin.atomic import atomic_write_text
    from flowtwin.errors import FlowtwinError

    try:
        atomic_write_text(result.sidecar, json.dumps(json_clean(result.as_dict()), indent=1,
                                                     allow_nan=False) + "\n")
    except FlowtwinError as exc:
        return str(exc)
    return None


def json_clean(value: object) -> object:
    """``value`` with non-finite numbers as ``None`` and tuples as lists (strict JSON)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {str(k): json_clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_clean(v) for v in value]
    return value
