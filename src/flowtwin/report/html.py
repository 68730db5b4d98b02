"""Self-contained HTML report of a simulation (opens offline: plotly.js is inlined).

Sections: the summary, flow commanded vs delivered along the print, predicted bead width
against the nominal one, a toolpath map coloured by width deviation, slip and force margin
over time, and the per-layer table. Every text that comes from the G-code or a profile
(file names, feature names) is HTML-escaped.
"""

from __future__ import annotations

import html
import itertools
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import numpy.typing as npt
import plotly.graph_objects as go
from plotly.subplots import make_subplots

from flowtwin.atomic import atomic_write_text
from flowtwin.gcode.moves import MoveKind
from flowtwin.simulation.result import SimulationResult

__all__ = ["write_report"]

#: Points per line in the plots; longer series are decimated (min/max kept per bucket).
MAX_POINTS = 20_000


def _decimate(t: npt.NDArray[np.float64], *ys: npt.NDArray[np.float64]
              ) -> tuple[npt.NDArray[np.float64], ...]:
    """Keep at most :data:`MAX_POINTS` samples, each bucket's minimum and maximum of ``ys[0]``."""
    n = t.shape[0]
    if n <= MAX_POINTS:
        return (t, *ys)
    buckets = MAX_POINTS // 2
    edges = np.linspace(0, n, buckets + 1).astype(np.int64)
    keep: list[int] = []
    y0 = ys[0]
    for a, b in itertools.pairwise(edges.tolist()):
        if b <= a:
            continue
        seg = y0[a:b]
        i, j = a + int(np.argmin(seg)), a + int(np.argmax(seg))
        keep.extend(sorted({i, j}))
    idx = np.array(keep, dtype=np.int64)
    return (t[idx], *(y[idx] for y in ys))


def _move_times(result: SimulationResult) -> npt.NDArray[np.float64]:
    return np.asarray(result.plan.timeline.phases["t_start"], dtype=np.float64)


def _fig_flow(result: SimulationResult) -> go.Figure:
    fig = go.Figure()
    series = result.dynamics.series
    area = result.parameters.params.filament_area_mm2
    if series is not None and series.shape[0]:
        t, q_out, q_cmd = _decimate(series["t_s"], series["q_out_mm3_s"],
                                    series["v_cmd_mm_s"] * area)
        fig.add_trace(go.Scattergl(x=t, y=q_cmd, name="commanded (firmware, PA incl.)",
                                   line={"width": 1}))
        fig.add_trace(go.Scattergl(x=t, y=q_out, name="delivered melt", line={"width": 1}))
    else:
        d = result.dynamics.moves
        t = _move_times(result)
        with np.errstate(divide="ignore", invalid="ignore"):
            q_cmd = np.where(d["duration_s"] > 0, d["cmd_mm3"] / d["duration_s"], 0.0)
        fig.add_trace(go.Scattergl(x=t, y=q_cmd, name="commanded (per move)", mode="lines"))
        fig.add_trace(go.Scattergl(x=t, y=d["q_mean_mm3_s"], name="delivered (per move)",
                                   mode="lines"))
    fig.update_layout(title="Volume flow along the print", xaxis_title="time (s)",
                      yaxis_title="flow (mm³/s)", height=380)
    return fig


def _fig_width(result: SimulationResult) -> go.Figure:
    met = result.metrics
    t = _move_times(result)
    sel = np.isfinite(met["width_mean_mm"])
    fig = go.Figure()
    tt, nominal, mean = _decimate(t[sel], met["width_nominal_mm"][sel], met["width_mean_mm"][sel])
    fig.add_trace(go.Scattergl(x=tt, y=nominal, name="nominal (G-code)", mode="markers",
                               marker={"size": 3}))
    fig.add_trace(go.Scattergl(x=tt, y=mean, name="predicted", mode="markers",
                               marker={"size": 3}))
    fig.update_layout(title="Bead width per extruding move", xaxis_title="time (s)",
                      yaxis_title="width (mm)", height=380)
    return fig


def _fig_map(result: SimulationResult) -> go.Figure:
    m = result.plan.table.moves
    met = result.metrics
    ext = ((m["kind"] & MoveKind.EXTRUDE) != 0) & np.isfinite(met["width_mean_mm"])
    dev = met["width_mean_mm"] - met["width_nominal_mm"]
    layers = m["layer"]
    fig = go.Figure()
    if not np.any(ext):
        fig.update_layout(title="Toolpath map (no extrusion)")
        return fig
    per_layer_worst: dict[int, float] = {}
    for lay, d in zip(layers[ext].tolist(), np.abs(dev[ext]).tolist(), strict=True):
        per_layer_worst[lay] = max(per_layer_worst.get(lay, 0.0), d)
    ordered = sorted(per_layer_worst)
    worst = max(per_layer_worst, key=lambda k: per_layer_worst[k])
    picks = list(dict.fromkeys([worst, ordered[0], ordered[len(ordered) // 2], ordered[-1]]))
    x0 = np.concatenate(([result.plan.table.start_xyze[0]], m["x"][:-1]))
    y0 = np.concatenate(([result.plan.table.start_xyze[1]], m["y"][:-1]))
    lim = float(np.nanmax(np.abs(dev[ext]))) or 0.01
    for k, lay in enumerate(picks):
        sel = ext & (layers == lay)
        xs = np.column_stack([x0[sel], m["x"][sel], np.full(int(sel.sum()), np.nan)]).ravel()
        ys = np.column_stack([y0[sel], m["y"][sel], np.full(int(sel.sum()), np.nan)]).ravel()
        fig.add_trace(go.Scattergl(x=xs, y=ys, mode="lines", line={"color": "#cccccc",
                                                                    "width": 1},
                                   visible=k == 0, showlegend=False, hoverinfo="skip"))
        fig.add_trace(go.Scattergl(
            x=(x0[sel] + m["x"][sel]) / 2, y=(y0[sel] + m["y"][sel]) / 2, mode="markers",
            marker={"color": dev[sel], "colorscale": "RdBu_r", "cmin": -lim, "cmax": lim,
                    "size": 5, "colorbar": {"title": "Δw (mm)"}},
            text=[f"line {ln}" for ln in m["line"][sel].tolist()], visible=k == 0,
            name=f"layer {lay}"))
    buttons = []
    for k, lay in enumerate(picks):
        vis = [False] * (2 * len(picks))
        vis[2 * k] = vis[2 * k + 1] = True
        label = f"layer {lay}" + (" (worst)" if lay == worst else "")
        buttons.append({"label": label, "method": "update", "args": [{"visible": vis}]})
    fig.update_layout(title="Toolpath coloured by predicted − nominal width",
                      updatemenus=[{"buttons": buttons, "direction": "down", "x": 1.0,
                                    "y": 1.15}],
                      xaxis_title="X (mm)", yaxis_title="Y (mm)", height=520,
                      yaxis={"scaleanchor": "x"})
    return fig


def _fig_slip_force(result: SimulationResult) -> go.Figure:
    fig = make_subplots(specs=[[{"secondary_y": True}]])
    series = result.dynamics.series
    if series is not None and series.shape[0]:
        t, slip = _decimate(series["t_s"], series["slip"] * 100.0)
        fig.add_trace(go.Scattergl(x=t, y=slip, name="slip (%)", line={"width": 1}),
                      secondary_y=False)
    else:
        fig.add_trace(go.Scattergl(x=_move_times(result),
                                   y=result.dynamics.moves["slip"] * 100.0, name="slip (%)"),
                      secondary_y=False)
    margin = result.metrics["force_margin_n"]
    t = _move_times(result)
    finite = np.isfinite(margin)
    if np.any(finite):
        tt, mm = _decimate(t[finite], margin[finite])
        fig.add_trace(go.Scattergl(x=tt, y=mm, name="force margin to grinding (N)",
                                   mode="markers", marker={"size": 3}), secondary_y=True)
    fig.update_layout(title="Drive slip and feed-force margin", height=380,
                      xaxis_title="time (s)")
    fig.update_yaxes(title_text="slip (%)", secondary_y=False)
    fig.update_yaxes(title_text="margin (N)", secondary_y=True)
    return fig


def _fmt(value: object) -> str:
    if isinstance(value, float):
        if not math.isfinite(value):
            return "–"
        return f"{value:.4g}"
    return html.escape(str(value))


def _table(rows: Sequence[Mapping[str, object]], columns: list[str]) -> str:
    head = "".join(f"<th>{html.escape(c)}</th>" for c in columns)
    body = "".join("<tr>" + "".join(f"<td>{_fmt(r.get(c))}</td>" for c in columns) + "</tr>"
                   for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


_CSS = """
body{font-family:system-ui,sans-serif;margin:2em;max-width:1200px;color:#222}
table{border-collapse:collapse;font-size:0.9em;margin:1em 0}
td,th{border:1px solid #ddd;padding:3px 8px;text-align:right}
th{background:#f3f3f3} td:first-child,th:first-child{text-align:left}
.warn{color:#a15c00} h1{font-size:1.5em} h2{font-size:1.2em;margin-top:2em}
"""


def write_report(result: SimulationResult, path: str | os.PathLike[str]) -> Path:
    """Write the HTML report of ``result`` to ``path`` atomically and return the path."""
    s = result.summary().as_dict()
    figs = [_fig_flow(result), _fig_width(result), _fig_map(result), _fig_slip_force(result)]
    parts = []
    for k, fig in enumerate(figs):
        parts.append(fig.to_html(full_html=False, include_plotlyjs="inline" if k == 0 else False,
                                 config={"displaylogo": False}))
    keys = ["file", "machine", "printer", "firmware", "pressure_advance", "total_time_s",
            "moves", "layers", "commanded_volume_mm3", "delivered_volume_mm3", "volume_error",
            "rms_flow_error", "peak_overextrusion", "peak_underextrusion",
            "worst_width_error_mm", "mean_slip", "max_feed_force_n", "min_force_margin_n",
            "grinding_events", "ooze_volume_mm3", "narrow_beads"]
    summary_rows = [{"quantity": k, "value": s.get(k)} for k in keys]
    warn_list = s.get("warnings")
    warnings = "".join(f"<li class='warn'>{html.escape(str(w))}</li>"
                       for w in (warn_list if isinstance(warn_list, list) else []))
    layer_cols = ["layer", "time_s", "commanded_mm3", "delivered_mm3", "rms_flow_error",
                  "worst_width_error_mm", "max_feed_force_n", "grinding_moves", "ooze_mm3"]
    feature_cols = ["feature", *layer_cols[1:]]
    worst_cols = ["line", "layer", "width_nominal_mm", "width_mean_mm", "flow_error",
                  "peak_force_n", "force_margin_n"]
    doc = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<title>flowtwin report: {html.escape(str(s['file']))}</title><style>{_CSS}</style></head>
<body>
<h1>flowtwin: what {html.escape(Path(str(s['file'])).name)} really extrudes</h1>
<p>Set-up <b>{html.escape(str(s['machine']))}</b>, printer
<b>{html.escape(str(s['printer']))}</b> ({html.escape(str(s['firmware']))}).</p>
{_table(summary_rows, ['quantity', 'value'])}
{f'<h2>Warnings</h2><ul>{warnings}</ul>' if warnings else ''}
<h2>Flow</h2>{parts[0]}
<h2>Bead width</h2>{parts[1]}
<h2>Toolpath map</h2>{parts[2]}
<h2>Slip and force margin</h2>{parts[3]}
<h2>Worst moves by width error</h2>{_table(result.worst_moves('width'), worst_cols)}
<h2>Per feature</h2>{_table(result.per_feature(), feature_cols)}
<h2>Per layer</h2>{_table(result.per_layer(), layer_cols)}
</body></html>
"""
    out = Path(path)
    atomic_write_text(out, doc)
    return out
