"""What the report page carries: packed arrays, quantities, rows, tracks, size, escaping."""

from __future__ import annotations

import base64
import dataclasses
import json
import re
import zlib
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from flowtwin.gcode.moves import MoveKind
from flowtwin.report import report_html, result_windowed, write_report
from flowtwin.report.payload import Blob, moves_track
from flowtwin.report.quantities import simulation_quantities
from flowtwin.report.variants import prediction_variant
from flowtwin.simulation import METRIC_DTYPE, SimulationResult


def _unpack(doc: str) -> tuple[dict, dict[str, np.ndarray]]:
    """The header and every array of a report page, decoded as the page's script does."""
    header = json.loads(re.search(r'<script type="application/json" id="ft-header">(.*?)'
                                  r"</script>", doc, re.S).group(1))  # type: ignore[union-attr]
    b64 = re.search(r'id="ft-blob">(.*?)</script>', doc, re.S).group(1)  # type: ignore[union-attr]
    raw = zlib.decompress(base64.b64decode(b64))
    types = {"u8": np.uint8, "u16": np.uint16, "i32": np.int32, "u32": np.uint32,
             "f16": np.float16, "f32": np.float32}
    arrays = {}
    for name, info in header["arrays"].items():
        dt = np.dtype(types[info["type"]])
        n = info["length"]
        chunk = np.frombuffer(raw, np.uint8, n * dt.itemsize, info["offset"])
        if info["planes"]:
            chunk = chunk.reshape(dt.itemsize, n).T.copy()
        arrays[name] = chunk.reshape(-1).view(dt)
    return header, arrays


def test_blob_round_trip_with_byte_planes() -> None:
    blob = Blob()
    a = np.arange(1000, dtype=np.float32) * 0.37
    b = np.array([3, 1, 4, 1, 5], dtype=np.uint16)
    blob.add("a", a)
    blob.add("b", b, planes=False)
    raw = zlib.decompress(base64.b64decode(blob.encode()))
    ia, ib = blob.index["a"], blob.index["b"]
    got_a = np.frombuffer(raw, np.uint8, 4000, ia["offset"]).reshape(4, 1000).T.copy()  # type: ignore[arg-type]
    assert np.array_equal(got_a.reshape(-1).view(np.float32), a)
    assert np.array_equal(np.frombuffer(raw, np.uint16, 5, ib["offset"]), b)  # type: ignore[arg-type]
    assert ia["offset"] % 8 == 0 and ib["offset"] % 8 == 0  # type: ignore[operator]


def test_page_data_matches_the_result(demo_result: SimulationResult) -> None:
    doc = report_html(demo_result)
    header, arr = _unpack(doc)
    m = demo_result.plan.table.moves
    n = len(m)
    assert header["n"] == n
    assert np.array_equal(np.cumsum(arr["dline"].astype(np.int64)), m["line"])
    assert np.array_equal(arr["layer"].astype(np.int64) - 1, m["layer"])
    lo, hi = np.array(header["lo"]), np.array(header["hi"])
    x = lo[0] + arr["x"] / 65535.0 * (hi[0] - lo[0])
    assert np.max(np.abs(x - m["x"])) <= (hi[0] - lo[0]) / 65535.0   # 16-bit grid
    var = header["variants"][0]
    q = {qq["key"]: qq for qq in var["quantities"]}
    win = result_windowed(demo_result)
    got = arr[q["flow_error_window"]["array"]].astype(np.float64)
    want = 100.0 * win.centred_error
    both = np.isfinite(want)
    assert np.array_equal(np.isfinite(got), both)
    # float16 rounded to 7 mantissa bits: relative error <= 2^-8 (subnormals: absolute)
    assert np.allclose(got[both], want[both], rtol=2.0 ** -8, atol=1e-4)
    assert not np.array_equal(got[both], want[both])
    text = arr["gcode"].tobytes().decode()
    assert text.splitlines()[int(m["line"][100]) - 1].startswith(("G0", "G1", "G2", "G3"))


def test_every_per_move_array_of_the_result_becomes_a_quantity(
        demo_result: SimulationResult) -> None:
    # a model that adds a per-move melt temperature shows up without a change in the report
    n = len(demo_result.plan.table)
    extra = np.dtype([*METRIC_DTYPE.descr, ("melt_temperature_c", np.float64)])
    metrics = np.zeros(n, extra)
    for name in METRIC_DTYPE.names or ():
        metrics[name] = demo_result.metrics[name]
    metrics["melt_temperature_c"] = np.linspace(200.0, 210.0, n)
    result = dataclasses.replace(demo_result, metrics=metrics)
    qs = {q.key: q for q in simulation_quantities(result, result_windowed(result))}
    melt = qs["melt_temperature_c"]
    assert (melt.label, melt.unit) == ("melt temperature", "°C")
    assert np.array_equal(melt.values, metrics["melt_temperature_c"])
    assert "viscosity_pa_s" in qs and qs["viscosity_pa_s"].unit == "Pa·s"   # from the params
    header, _ = _unpack(report_html(result))
    assert "melt_temperature_c" in [q["key"] for q in header["variants"][0]["quantities"]]


def test_layer_and_feature_rows_add_up(demo_result: SimulationResult) -> None:
    var = prediction_variant(demo_result)
    s = demo_result.summary()
    win = result_windowed(demo_result)
    assert sum(r["commanded_mm3"] for r in var.layers) == pytest.approx(  # type: ignore[misc]
        s.commanded_volume_mm3)
    assert sum(r["delivered_mm3"] for r in var.features) == pytest.approx(  # type: ignore[misc]
        s.delivered_volume_mm3)
    assert max(r["worst_over"] for r in var.layers  # type: ignore[type-var]
               if r["worst_over"] == r["worst_over"]) == pytest.approx(win.peak_over)
    ours = {int(r["layer"]): r["rms_flow_error"] for r in var.layers}  # type: ignore[call-overload]
    for row in demo_result.per_layer():
        assert ours[int(row["layer"])] == pytest.approx(row["rms_flow_error"], abs=1e-12)
    z = [r["z_mm"] for r in var.layers if int(r["layer"]) >= 0]  # type: ignore[call-overload]
    assert z == pytest.approx([0.2 * (k + 1) for k in range(10)])


def test_moves_track_keeps_the_delivered_volume(demo_result: SimulationResult) -> None:
    tr = moves_track(demo_result)
    lo, hi, mean = tr.channels["q_out"]
    kind = demo_result.plan.table.moves["kind"].astype(int)
    d = demo_result.dynamics.moves
    shown = ~(((kind & int(MoveKind.RETRACT)) != 0)
              | (((kind & int(MoveKind.XY)) == 0) & ((kind & int(MoveKind.EXTRUDE)) != 0)))
    # time-weighted means × covered time per column = the melt of the moves shown
    t0 = np.asarray(demo_result.plan.timeline.phases["t_start"])
    t1 = t0 + d["duration_s"]
    edges = np.arange(len(mean) + 1) * tr.dt_s
    covered = np.zeros(len(mean))
    for a, b, ok in zip(t0, t1, shown & (d["duration_s"] > 0), strict=True):
        if ok:
            covered += np.clip(np.minimum(edges[1:], b) - np.maximum(edges[:-1], a), 0, None)
    total = np.nansum(mean * covered)
    assert total == pytest.approx(float(np.sum(d["out_mm3"][shown & (d["duration_s"] > 0)])),
                                  rel=1e-6)
    assert np.all((lo <= mean + 1e-9) | np.isnan(mean)) and np.all((mean <= hi + 1e-9)
                                                                    | np.isnan(mean))
    assert tr.retractions_s.size == int(np.count_nonzero((kind & int(MoveKind.RETRACT)) != 0))


def test_demo_report_size_and_escaping(demo_result: SimulationResult, tmp_path: Path) -> None:
    evil = dataclasses.replace(demo_result, warnings=["<script>alert(1)</script>"])
    evil.plan.table.features[2] = "<script>alert(2)</script>"
    try:
        out = write_report(evil, tmp_path / "r" / "report.html")
    finally:
        evil.plan.table.features[2] = "External perimeter"
    doc = out.read_text()
    assert out.stat().st_size <= 3_000_000            # the built-in example's budget
    assert "<script>alert" not in doc
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in doc
    assert doc.count("<script") == doc.count("</script>") == 6
    assert not re.search(r"""<(script|link|img|iframe)[^>]*(src|href)=""", doc)  # offline
    assert [p.name for p in out.parent.iterdir()] == ["report.html"]  # written atomically


class _Tags(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append((tag, dict(attrs)))


def test_notebook_repr_is_a_sandboxed_frame_with_the_viewer(
        demo_result: SimulationResult) -> None:
    html = demo_result._repr_html_()
    p = _Tags()
    p.feed(html)
    p.close()
    assert [t for t, _ in p.tags] == ["iframe"]
    attrs = p.tags[0][1]
    assert attrs["sandbox"] == "allow-scripts"
    inner = _Tags()
    inner.feed(attrs["srcdoc"] or "")
    assert ("canvas", {"id": "ft-canvas"}) in inner.tags
    assert any(t == "script" and a.get("id") == "ft-blob" for t, a in inner.tags)
