"""Self-contained HTML report: the verdict first, then a toolpath viewer, time plots and tables.

The page works offline: its scripts (``assets/*.js``, plain JavaScript + WebGL2, no library)
and its data (:mod:`.payload`) are inside the file. The verdict, the worst places and the
advice are rendered here as HTML; everything that comes from the G-code or a profile (file
names, feature names, warnings, the G-code text) is escaped, or travels as JSON / bytes
that the page puts on screen as text.

* :func:`report_html` / :func:`write_report`: one simulation;
* :func:`comparison_html` / :func:`write_comparison`: before and after ``compensate``,
  one viewer with a before/after toggle on the original moves, one colour scale.
"""

from __future__ import annotations

import html
import math
import os
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from flowtwin.atomic import atomic_write_text
from flowtwin.errors import GcodeError
from flowtwin.gcode.inputs import open_source
from flowtwin.report.payload import Variant, build_payload
from flowtwin.report.spots import Spot, locate_spots, result_windowed
from flowtwin.report.variants import comparison_variants, prediction_variant
from flowtwin.report.verdict import Verdict, build_verdict
from flowtwin.simulation import SimulationResult

if TYPE_CHECKING:
    from flowtwin.calibration.tuning.advance_settings import AdvanceFit
    from flowtwin.compensation.pipeline import CompensationReport

__all__ = ["comparison_html", "report_html", "source_text", "write_comparison", "write_report"]

_ASSETS = ("data.js", "viewer.js", "charts.js", "app.js")


def _asset(name: str) -> str:
    return resources.files("flowtwin.report").joinpath("assets", name).read_text("utf-8")


def source_text(result: SimulationResult) -> bytes | None:
    """The G-code text of a simulation's file (plain or gzip), or ``None`` when it cannot be
    read back (standard input, bytes, a file that has gone)."""
    name = result.plan.table.source
    if not name or name.startswith("<") or not Path(name).is_file():
        return None
    try:
        stream, _ = open_source(name)
        with stream:
            return stream.read()
    except (GcodeError, OSError):
        return None


def _e(v: object) -> str:
    return html.escape(str(v), quote=True)


def _pct(v: float | None, digits: int = 1) -> str:
    return "–" if v is None or not math.isfinite(v) else f"{100 * v:+.{digits}f} %"


def _figure(key: str, value: str, note: str = "") -> str:
    return (f"<div class='figure'><div class='k'>{_e(key)}</div><div class='v'>{_e(value)}</div>"
            f"<div class='w'>{_e(note)}</div></div>")


def _go(line: int, text: str | None = None) -> str:
    return f"<a class='go' data-line='{int(line)}'>{_e(text or f'line {line}')}</a>"


def _spot_table(spots: Sequence[Spot], caption: str) -> str:
    if not spots:
        return f"<p class='muted'>{_e(caption)}: none.</p>"
    head = ("<tr><th>#</th><th>flow error</th><th>excess (mm³)</th><th>bead (mm)</th>"
            "<th>G-code lines</th><th>layer</th><th>z (mm)</th><th>feature</th><th></th></tr>")
    rows = []
    for k, s in enumerate(spots, 1):
        lines = (_go(s.line_first, f"{s.line_first}") if s.line_first == s.line_last else
                 _go(s.line_first, f"{s.line_first}–{s.line_last}"))
        rows.append(
            f"<tr><td>{k}</td><td>{_e(_pct(s.error))}</td><td>{s.excess_mm3:+.4f}</td>"
            f"<td>{s.width_nominal_mm:.2f} → {s.width_predicted_mm:.2f}</td><td>{lines}</td>"
            f"<td>{s.layer}</td><td>{s.z_mm:.2f}</td><td>{_e(s.feature or '(none)')}</td>"
            f"<td>{'after a retraction' if s.after_retraction else ''}</td></tr>")
    return f"<h3>{_e(caption)}</h3><table>{head}{''.join(rows)}</table>"


def _verdict_html(v: Verdict) -> tuple[str, str]:
    """The verdict card, and the tables of the worst windows (shown under the viewer)."""
    g = v.grinding
    level = {"safe": "level-safe", "at risk": "level-risk", "grinds": "level-bad"}[g.level]
    worst = max((abs(s.error) for s in (v.over, v.under) if s is not None), default=0.0)
    if worst > 0.15 and level == "level-safe":
        level = "level-risk"
    figs = [
        _figure("grinding", g.level,
                f"margin {g.min_margin_n:.1f} N ({100 * g.min_margin_share:.0f} % of the "
                f"{g.grip_n:.0f} N grip)" if math.isfinite(g.min_margin_n) else "no extrusion"),
        _figure(f"worst over-extrusion / {v.window_mm:g} mm",
                _pct(v.over.error) if v.over else "none",
                f"line {v.over.line}, layer {v.over.layer}, {v.over.feature}" if v.over else ""),
        _figure(f"worst under-extrusion / {v.window_mm:g} mm",
                _pct(v.under.error) if v.under else "none",
                f"line {v.under.line}, layer {v.under.layer}, {v.under.feature}"
                if v.under else ""),
        _figure("volume delivered", _pct(v.volume_error),
                f"RMS flow error per move {100 * v.rms_flow_error:.1f} %"),
        _figure("ooze (travels, stops)", f"{v.ooze_mm3:.2f} mm³",
                f"most at line {v.ooze_line}" if v.ooze_line else ""),
        _figure("drive slip", f"{100 * v.mean_slip:.2f} %", f"lag factor K {v.lag_k_s:.3f} s"),
        _figure("print time", _duration(v.print_time_s), v.pressure_advance),
    ]
    advice = "".join(
        f"<li>{_e(a.text)}" + (f"<br><code class='cmd'>{_e(a.command)}</code>" if a.command
                                else "") + "</li>" for a in v.advice)
    sentences = "".join(f"<li>{_e(s)}</li>" for s in v.sentences()[1:])
    return f"""
<section id="ft-verdict" class="card {level}">
<p class="headline">{_e(v.headline)}</p>
<div class="figures">{''.join(figs)}</div>
<h3>What to do</h3><ol class="advice">{advice}</ol>
<details><summary>In words</summary><ul class="sentences">{sentences}</ul></details>
</section>""", f"""
<h2>Where: the worst {v.window_mm:g} mm of path</h2>
<p class="muted">Flow error over windows of one nozzle diameter ({v.window_mm:g} mm) of
continuously printed path: delivered / commanded − 1. Click a line to see it in the viewer.</p>
{_spot_table(v.worst_over, "Over-extrusion (more melt than meant)")}
{_spot_table(v.worst_under, "Under-extrusion (less melt than meant)")}
"""


def _duration(seconds: float) -> str:
    h, rem = divmod(seconds, 3600.0)
    m, s = divmod(rem, 60.0)
    return f"{int(h)} h {int(m):02d} min" if h >= 1 else f"{int(m)} min {int(s):02d} s"


_VIEWER = """
<h2 id="ft-viewer">Toolpath</h2>
<div class="toolbar">
 <label>colour by <select id="ft-quantity"></select></label>
 <span id="ft-variants"></span>
 <label><select id="ft-mode"><option value="upto">up to layer</option>
   <option value="single">single layer</option></select></label>
 <input id="ft-layer" type="range" min="0" max="0" value="0" aria-label="layer">
 <span id="ft-layer-label"></span>
 <label><input id="ft-travels" type="checkbox"> travels</label>
 <label><input id="ft-tilt" type="checkbox" checked> 3D</label>
 <button id="ft-fit" type="button">fit</button>
 <label>range <input id="ft-min" type="number" step="any"> to
   <input id="ft-max" type="number" step="any"></label>
 <button id="ft-auto" type="button">auto</button>
</div>
<div class="viewer-row">
 <div>
  <div class="canvas-wrap"><canvas id="ft-canvas"></canvas><div id="ft-tip" hidden></div></div>
  <canvas id="ft-legend"></canvas><div id="ft-legend-label"></div>
  <div id="ft-status">loading…</div>
  <p class="muted">Wheel: zoom · drag: pan · shift-drag or right-drag: turn (3D) ·
   hover or click a line for its G-code line, layer, feature and values.</p>
 </div>
 <div id="ft-details" class="card"></div>
</div>
<!--after-viewer-->
<h2>Along the print</h2>
<div class="toolbar"><span><span class="key" style="background:#7f8c8d"></span>commanded flow
 (firmware, pressure advance included)<span class="key" style="background:#c0392b"></span>
 delivered melt</span>
 <label><input id="ft-fullrange" type="checkbox"> full range (retractions)</label></div>
<canvas id="ft-flow" class="chart"></canvas>
<canvas id="ft-force" class="chart"></canvas>
<canvas id="ft-slip" class="chart"></canvas>
<p class="muted"><span id="ft-track-note"></span> The flow axis is scaled to the printing
 flow. Retractions (wipes included) and primes are left out of the flow; retractions are marked
 by grey triangles under the time axis; anything beyond the axis is clipped and marked red
 at its edge — tick "full range" to see it all. The red dashed line on the force
 plot is the roller's grip. Wheel: zoom in time · drag: pan · double click: all ·
 click: show that move.</p>
<h2>Per feature</h2>
<p class="muted">Worst under- (blue, left) and over-extrusion (orange, right) over one
 nozzle diameter of path per feature, with its share of the print time.</p>
<canvas id="ft-featurechart" class="hbars"></canvas>
<table id="ft-features"></table>
<h2>Per layer</h2>
<p class="muted">Worst over- (orange, up) and under-extrusion (blue, down) over
 one nozzle diameter of path per layer; dark bars are beyond the axis. Click a bar or a
 row to view that layer.</p>
<canvas id="ft-layerchart" class="bars"></canvas>
<p id="ft-layers-note" class="muted"></p>
<div class="scroll"><table id="ft-layers"></table></div>
"""


def _page(title: str, head_html: str, body_top: str, header_json: str, blob: str,
          warnings: Sequence[str], after_viewer: str = "") -> str:
    warn = ""
    if warnings:
        items = "".join(f"<li class='warn'>{_e(w)}</li>" for w in warnings[:200])
        warn = f"<h2>Warnings</h2><ul>{items}</ul>"
    scripts = "\n".join(f"<script>{_asset(a)}</script>" for a in _ASSETS)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{_e(title)}</title>
<style>{_asset("report.css")}</style></head>
<body><main>
{head_html}
{body_top}
{_VIEWER.replace("<!--after-viewer-->", after_viewer)}
{warn}
<p class="muted">flowtwin report · all data and scripts are inside this file (no network).</p>
</main>
<script type="application/json" id="ft-header">{header_json}</script>
<script type="application/octet-stream" id="ft-blob">{blob}</script>
{scripts}
</body></html>
"""


def _meta(result: SimulationResult, window_mm: float) -> dict[str, object]:
    kind = result.plan.table.moves["kind"].astype(np.int64)
    grip = np.broadcast_to(np.asarray(result.parameters.params.max_feed_force_n,
                                      dtype=np.float64), kind.shape)
    fin = grip[np.isfinite(grip)]
    s = result.summary()
    return {"file": Path(s.file).name, "machine": s.machine,
            "printer": s.printer, "firmware": s.firmware, "window_mm": window_mm,
            "grip_n": float(fin.min()) if fin.size else None}


def report_html(result: SimulationResult, *, fit: AdvanceFit | None = None,
                gcode_text: bytes | None = None, verdict: Verdict | None = None) -> str:
    """The HTML report of one simulation (see the module docstring).

    Parameters
    ----------
    result
        The simulation (with a time series if the time plots should show the integrator's
        samples rather than per-move means).
    fit
        The fitted firmware pressure advance, for the advice.
    gcode_text
        The G-code source (default: read back from the simulated file when possible).
    verdict
        The verdict if already built (default: built here).
    """
    windowed = result_windowed(result)
    v = verdict if verdict is not None else build_verdict(result, fit=fit, windowed=windowed)
    spots = (v.worst_over, v.worst_under) if verdict is not None else \
        locate_spots(result, windowed)
    variant = prediction_variant(result, windowed, spots)
    text = gcode_text if gcode_text is not None else source_text(result)
    header, blob = build_payload(result, [variant], meta=_meta(result, windowed.window_mm),
                                 gcode_text=text)
    name = Path(v.file).name
    head = (f"<h1>What {_e(name)} really extrudes</h1><p class='sub'>on <b>{_e(v.machine)}"
            f"</b> ({_e(v.printer)}, {_e(v.firmware)}; pressure advance "
            f"{_e(v.pressure_advance)})</p>")
    card, where = _verdict_html(v)
    return _page(f"flowtwin: {name}", head, card, header, blob, result.warnings, where)


def write_report(result: SimulationResult, path: str | os.PathLike[str], *,
                 fit: AdvanceFit | None = None, gcode_text: bytes | None = None,
                 verdict: Verdict | None = None) -> Path:
    """Write :func:`report_html` of ``result`` to ``path`` atomically; return the path."""
    out = Path(path)
    atomic_write_text(out, report_html(result, fit=fit, gcode_text=gcode_text, verdict=verdict))
    return out


def _compare_top(summary: dict[str, object], before: Variant, after: Variant,
                 window_mm: float) -> str:
    def f(key: str) -> float:
        v = summary.get(key)
        return float(v) if isinstance(v, int | float) else math.nan

    rows = [("RMS flow error per move", f"{100 * f('rms_flow_error_before'):.2f} %",
             f"{100 * f('rms_flow_error_after'):.2f} %"),
            (f"worst over-extrusion over {window_mm:g} mm",
             _pct(f("peak_overextrusion_window_before")),
             _pct(f("peak_overextrusion_window_after"))),
            ("worst under-extrusion per move", _pct(-f("peak_underextrusion_before")),
             _pct(-f("peak_underextrusion_after"))),
            ("print time", _duration(f("time_before_s")), _duration(f("time_after_s"))),
            ("max feed force", f"{f('max_force_before_n'):.1f} N",
             f"{f('max_force_after_n'):.1f} N"),
            ("grinding moves", str(summary.get("grinding_moves_before", "–")),
             str(summary.get("grinding_moves_after", "–")))]
    body = "".join(f"<tr><td>{_e(a)}</td><td>{_e(b)}</td><td>{_e(c)}</td></tr>"
                   for a, b, c in rows)
    steps = summary.get("transformations") or []
    names = ", ".join(str(s) for s in steps) if isinstance(steps, list) and steps else "none"
    headline = (f"Compensation ({names}): RMS flow error {100 * f('rms_flow_error_before'):.1f} %"
                f" → {100 * f('rms_flow_error_after'):.1f} %, worst over-extrusion over "
                f"{window_mm:g} mm {_pct(f('peak_overextrusion_window_before'))} → "
                f"{_pct(f('peak_overextrusion_window_after'))}.")
    spots = []
    for var in (before, after):
        over = var.spots["over"][:5]
        items = "".join(
            f"<li>{_e(_pct(float(str(s['error']))))} at {_go(int(str(s['line'])))}"
            f" (layer {_e(s['layer'])}, {_e(s['feature'] or '(none)')})</li>" for s in over)
        spots.append(f"<div><h3>worst over-extrusion, {_e(var.label)}</h3>"
                     f"<ol>{items or '<li>none</li>'}</ol></div>")
    return f"""
<section id="ft-verdict" class="card level-safe">
<p class="headline">{_e(headline)}</p>
<table><tr><th></th><th>before</th><th>after</th></tr>{body}</table>
<p class="muted">Both against what the original file means, on the original's moves; the
viewer's before/after buttons switch the colours on one scale.</p>
<div class="pair">{''.join(spots)}</div>
</section>"""


def comparison_html(original: SimulationResult, compensated: SimulationResult,
                    piece_row: np.ndarray, *, summary: dict[str, object] | None = None,
                    gcode_text: bytes | None = None, warnings: Sequence[str] = ()) -> str:
    """The before/after report of a compensation (see the module docstring).

    Parameters
    ----------
    original, compensated
        The original and the compensated file simulated on the same machine.
    piece_row
        Original move of every compensated move, shape ``(n_pieces,)``.
    summary
        :meth:`CompensationReport.summary` (the before/after figures of the table).
    gcode_text
        The original G-code (default: read back from its file).
    warnings
        Shown at the end.
    """
    before, after = comparison_variants(original, compensated, np.asarray(piece_row))
    win = result_windowed(original)
    text = gcode_text if gcode_text is not None else source_text(original)
    header, blob = build_payload(original, [before, after],
                                 meta=_meta(original, win.window_mm), gcode_text=text)
    name = Path(original.plan.table.source).name
    head = (f"<h1>Compensating {_e(name)}: before and after</h1><p class='sub'>on "
            f"<b>{_e(original.machine_name)}</b></p>")
    return _page(f"flowtwin compensate: {name}", head,
                 _compare_top(summary or {}, before, after, win.window_mm), header, blob,
                 list(warnings))


def write_comparison(report: CompensationReport, path: str | os.PathLike[str]) -> Path:
    """Write the before/after report of ``report`` (which must carry its simulations) to
    ``path`` atomically; return the path."""
    from flowtwin.errors import DataError

    if report.original_result is None or report.compensated_result is None or \
            report.piece_row is None:
        raise DataError("this compensation report does not carry its simulations",
                        field="CompensationReport", allowed="a report from compensate()")
    out = Path(path)
    atomic_write_text(out, comparison_html(report.original_result, report.compensated_result,
                                           report.piece_row, summary=report.as_dict(),
                                           warnings=report.warnings))
    return out
