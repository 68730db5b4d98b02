"""The data a report page draws, packed compactly: a JSON header and one deflated blob.

Geometry is stored once per report: every move's end point quantised to 16 bits over the
print's bounding box (x, y, z; 4.6 µm on a 300 mm bed), its kind, layer, feature, nominal
width (10 µm) and the difference of its G-code line to the previous move's. Each *variant*
(the prediction; or before and after compensation) adds one array per
:class:`~.quantities.Quantity` (float16 rounded to :data:`VALUE_BITS` mantissa bits, or
float32 where a value exceeds float16's range), the start time of each move (whole
milliseconds, as differences), a time track bucketed to at most :data:`TRACK_BUCKETS`
columns (min, max and mean per bucket), the per-layer rows (as columns: a spiral vase has a
"layer" per move) and the per-feature rows. The G-code text itself is included (for the
line a click shows) up to :data:`GCODE_EMBED_MAX_BYTES`.

Multi-byte arrays are stored as byte planes (all first bytes, then all second bytes, …),
which deflate packs far better than interleaved bytes; the page restores them after the
browser's own ``DecompressionStream('deflate')`` has inflated the blob. Every string from
the G-code (feature names, the text) travels as JSON or as bytes and is put on the page as
text, never as markup.
"""

from __future__ import annotations

import base64
import json
import math
import zlib
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from flowtwin.gcode.moves import MoveKind
from flowtwin.report.quantities import Quantity
from flowtwin.simulation import SimulationResult

__all__ = ["GCODE_EMBED_MAX_BYTES", "TRACK_BUCKETS", "VALUE_BITS", "Blob", "Track", "Variant",
           "build_payload", "moves_track", "series_track", "to_script_json"]

#: Columns of a time track: enough for a full-width plot and a few zoom steps.
TRACK_BUCKETS = 20_000
#: G-code text larger than this (uncompressed) is not embedded: clicks show line numbers.
GCODE_EMBED_MAX_BYTES = 48 * 1024 * 1024
_F16_MAX = 60000.0
#: Mantissa bits kept in the per-move values (relative rounding ≤ 2⁻⁸ ≈ 0.4 %).
VALUE_BITS = 7
_PRINTING = int(MoveKind.EXTRUDE | MoveKind.XY)

FloatArray = npt.NDArray[np.float64]


@dataclass(slots=True)
class Blob:
    """Arrays concatenated into one byte string, described by name in :attr:`index`."""

    parts: list[bytes] = field(default_factory=list)
    index: dict[str, dict[str, object]] = field(default_factory=dict)
    size: int = 0

    def add(self, name: str, arr: npt.NDArray[np.generic], *, planes: bool = True) -> str:
        """Append ``arr`` (1-D, native little-endian) under ``name``; return the name."""
        a = np.ascontiguousarray(arr)
        code = {"u1": "u8", "i1": "i8", "u2": "u16", "i2": "i16", "u4": "u32", "i4": "i32",
                "f2": "f16", "f4": "f32", "f8": "f64"}[a.dtype.str[1:]]
        raw = a.view(np.uint8).reshape(-1, a.dtype.itemsize)
        shuffled = planes and a.dtype.itemsize > 1
        data = (raw.T.tobytes() if shuffled else raw.tobytes())
        pad = (-self.size) % 8
        if pad:
            self.parts.append(b"\0" * pad)
            self.size += pad
        self.index[name] = {"type": code, "offset": self.size, "length": int(a.shape[0]),
                            "planes": shuffled}
        self.parts.append(data)
        self.size += len(data)
        return name

    def add_bytes(self, name: str, data: bytes) -> str:
        """Append raw bytes (e.g. UTF-8 text) under ``name``."""
        return self.add(name, np.frombuffer(data, dtype=np.uint8), planes=False)

    def encode(self) -> str:
        """Deflate (zlib format) and base64-encode the concatenated arrays."""
        return base64.b64encode(zlib.compress(b"".join(self.parts), 6)).decode("ascii")


@dataclass(frozen=True, slots=True)
class Track:
    """A time track: channels bucketed over time (min and max per bucket).

    Attributes
    ----------
    t0_s, dt_s
        Start and width of the buckets, s.
    channels
        Name → ``(low, high, mean)`` per bucket, shape ``(n_buckets,)`` each. The flow
        channels leave out retractions (wipes included) and primes; the retractions are
        marked by :attr:`retractions_s`.
    retractions_s
        Start times of the retractions, s.
    source
        ``"series"`` (the integrator's samples) or ``"moves"`` (per-move means).
    """

    t0_s: float
    dt_s: float
    channels: dict[str, tuple[FloatArray, FloatArray, FloatArray]]
    retractions_s: FloatArray
    source: str


@dataclass(frozen=True, slots=True)
class Variant:
    """One set of per-move values on the report's geometry.

    Attributes
    ----------
    name, label
        Identifier and words (``"prediction"``; ``"before"``, ``"after"``).
    quantities
        The quantities, in the viewer's order.
    t_start_s
        Start time of every move of the geometry in this variant, s, shape ``(n_moves,)``.
    track
        The time plots' data.
    layers, features
        Per-layer and per-feature rows (JSON-able).
    spots
        The worst windows, JSON-able (``{"over": [...], "under": [...]}``).
    flow_scale_mm3_s
        The flow plot's default top (:func:`flow_scale`).
    """

    name: str
    label: str
    quantities: list[Quantity]
    t_start_s: FloatArray
    track: Track
    layers: list[dict[str, object]]
    features: list[dict[str, object]]
    spots: dict[str, list[dict[str, object]]]
    flow_scale_mm3_s: float


def _bucket(t: FloatArray, y: FloatArray, t0: float, dt: float, nb: int
            ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Min, max and mean of samples ``(t, y)`` (``t`` sorted) per bucket; ``nan`` samples
    are left out; a bucket without samples is ``nan`` (a gap)."""
    b = np.clip(((t - t0) / dt).astype(np.int64), 0, nb - 1)
    lo = np.full(nb, np.nan)
    hi = np.full(nb, np.nan)
    mean = np.full(nb, np.nan)
    ok = np.isfinite(y)
    b, yy = b[ok], y[ok]
    if b.size:
        starts = np.flatnonzero(np.concatenate(([True], np.diff(b) != 0)))
        keys = b[starts]
        lo[keys] = np.minimum.reduceat(yy, starts)
        hi[keys] = np.maximum.reduceat(yy, starts)
        counts = np.diff(np.append(starts, yy.size))
        mean[keys] = np.add.reduceat(yy, starts) / counts
    return lo, hi, mean


def _buckets(t_end: float) -> tuple[float, int]:
    nb = TRACK_BUCKETS
    return max(t_end, 1e-6) / nb, nb


def series_track(result: SimulationResult) -> Track:
    """The time track of a simulation with a time series (the integrator's samples)."""
    s = result.dynamics.series
    assert s is not None
    area = float(result.parameters.params.filament_area_mm2)
    t = np.asarray(s["t_s"], dtype=np.float64)
    t_end = float(t[-1]) if t.size else 0.0
    dt, nb = _buckets(t_end)
    if t.size < nb:        # fewer samples than buckets: one bucket per sample
        nb = max(int(t.size), 1)
        dt = max(t_end, 1e-6) / nb
    e_only = _e_only(result)
    move = np.searchsorted(np.asarray(result.plan.timeline.phases["t_start"], dtype=np.float64),
                           t, side="right") - 1
    hide = e_only[np.clip(move, 0, max(e_only.size - 1, 0))] if e_only.size else \
        np.zeros(t.shape, dtype=np.bool_)
    chans = {"q_cmd": np.where(hide, np.nan, np.asarray(s["v_cmd_mm_s"], dtype=np.float64)
                               * area),
             "q_out": np.where(hide, np.nan, np.asarray(s["q_out_mm3_s"], dtype=np.float64)),
             "force": np.asarray(s["feed_force_n"], dtype=np.float64),
             "slip": 100.0 * np.asarray(s["slip"], dtype=np.float64)}
    return Track(0.0, dt, {k: _bucket(t, v, 0.0, dt, nb) for k, v in chans.items()},
                 _retraction_times(result), "series")


def _steps(t0: FloatArray, t1: FloatArray, lo_v: FloatArray, hi_v: FloatArray,
           mean_v: FloatArray, dt: float, nb: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Buckets of a step signal: move ``i`` holds ``mean_v[i]`` (ranging over
    ``[lo_v[i], hi_v[i]]``) from ``t0[i]`` to ``t1[i]`` (moves in time order, not
    overlapping; ``nan``: left out). Min and max over the moves touching a bucket; the
    time-weighted mean over the time the bucket is covered; ``nan`` where nothing is."""
    ok = np.isfinite(mean_v) & (t1 >= t0)
    a, b = t0[ok], t1[ok]
    lo_v, hi_v, mean_v = lo_v[ok], hi_v[ok], mean_v[ok]
    lo = np.full(nb, np.nan)
    hi = np.full(nb, np.nan)
    mean = np.full(nb, np.nan)
    if a.size == 0:
        return lo, hi, mean
    b0 = np.clip((a / dt).astype(np.int64), 0, nb - 1)
    b1 = np.clip((b / dt).astype(np.int64), b0, nb - 1)
    counts = b1 - b0 + 1               # buckets each move touches (Σ <= moves + buckets)
    owner = np.repeat(np.arange(a.size), counts)
    first = np.cumsum(counts) - counts
    bucket = b0[owner] + (np.arange(owner.size) - first[owner])
    order = np.argsort(bucket, kind="stable")
    bucket, owner = bucket[order], owner[order]
    starts = np.flatnonzero(np.concatenate(([True], np.diff(bucket) != 0)))
    keys = bucket[starts]
    lo[keys] = np.minimum.reduceat(np.fmin(lo_v, mean_v)[owner], starts)
    hi[keys] = np.maximum.reduceat(np.fmax(hi_v, mean_v)[owner], starts)
    # overlap of each (move, bucket) pair in time → weighted mean
    edge0 = bucket * dt
    overlap = np.minimum(b[owner], edge0 + dt) - np.maximum(a[owner], edge0)
    w = np.maximum(overlap, 0.0) + 1e-12
    wsum = np.add.reduceat(w, starts)
    mean[keys] = np.add.reduceat(w * mean_v[owner], starts) / wsum
    return lo, hi, mean


def moves_track(result: SimulationResult) -> Track:
    """The time track from per-move figures (no time series needed, any print length).

    Delivered melt: each move's lowest and highest flow and its mean (the integrator's
    per-move ``q_min``, ``q_max``, ``q_mean``); commanded flow: the firmware's feed of the
    move (pressure advance included) over its duration; force: each move's peak; slip:
    each move's slip. Retractions and primes are left out of the flows.
    """
    d = result.dynamics.moves
    t0 = np.asarray(result.plan.timeline.phases["t_start"], dtype=np.float64)
    dur = np.asarray(d["duration_s"], dtype=np.float64)
    t1 = t0 + dur
    t_end = float(t1.max()) if t1.size else 0.0
    dt, nb = _buckets(t_end)
    hide = _e_only(result) | (dur <= 0)

    def f(name: str) -> FloatArray:
        return np.where(hide, np.nan, np.asarray(d[name], dtype=np.float64))

    with np.errstate(divide="ignore", invalid="ignore"):
        q_cmd = np.where(hide, np.nan, np.asarray(d["fed_cmd_mm3"], dtype=np.float64) / dur)
    force = np.where(dur > 0, np.asarray(d["peak_force_n"], dtype=np.float64), np.nan)
    slip = np.where(dur > 0, 100.0 * np.asarray(d["slip"], dtype=np.float64), np.nan)
    chans = {"q_cmd": _steps(t0, t1, q_cmd, q_cmd, q_cmd, dt, nb),
             "q_out": _steps(t0, t1, f("q_min_mm3_s"), f("q_max_mm3_s"), f("q_mean_mm3_s"),
                             dt, nb),
             "force": _steps(t0, t1, force, force, force, dt, nb),
             "slip": _steps(t0, t1, slip, slip, slip, dt, nb)}
    return Track(0.0, dt, chans, _retraction_times(result), "moves")


def _e_only(result: SimulationResult) -> npt.NDArray[np.bool_]:
    """Retractions (negative E, with or without XY motion: a wipe) and primes (E without XY
    motion): the extruder's own moves, left out of the flow plots."""
    kind = result.plan.table.moves["kind"].astype(np.int64)
    return (((kind & int(MoveKind.RETRACT)) != 0)
            | (((kind & int(MoveKind.XY)) == 0) & ((kind & int(MoveKind.EXTRUDE)) != 0)))


def _retraction_times(result: SimulationResult) -> FloatArray:
    kind = result.plan.table.moves["kind"].astype(np.int64)
    sel = (kind & int(MoveKind.RETRACT)) != 0
    return np.asarray(result.plan.timeline.phases["t_start"][sel], dtype=np.float64)


def flow_scale(result: SimulationResult) -> float:
    """1.3 × the 99.5th percentile of the G-code's flow on printing moves (pressure advance
    left out), mm³/s: the top of the flow plot."""
    d = result.dynamics.moves
    kind = result.plan.table.moves["kind"].astype(np.int64)
    dur = np.asarray(d["duration_s"], dtype=np.float64)
    sel = ((kind & _PRINTING) == _PRINTING) & (dur > 0) & (d["cmd_mm3"] > 0)
    if not np.any(sel):
        return 1.0
    q = np.asarray(d["cmd_mm3"], dtype=np.float64)[sel] / dur[sel]
    return float(1.3 * max(np.percentile(q, 99.5), 1e-3))


def _values_array(values: FloatArray) -> npt.NDArray[np.generic]:
    """float16 rounded to :data:`VALUE_BITS` bits of mantissa (float32 beyond float16's
    range): three significant figures are what a colour and a hover show, and the dropped
    bits are noise that deflate cannot pack."""
    fin = values[np.isfinite(values)]
    if fin.size and float(np.max(np.abs(fin))) > _F16_MAX:
        return values.astype(np.float32)
    # round once, from the full value (rounding the float16 again would round twice: a
    # value just below a half step can end a whole step away)
    with np.errstate(invalid="ignore"):
        mant, expo = np.frexp(values)
        kept = np.ldexp(np.round(np.ldexp(mant, VALUE_BITS + 1)), expo - VALUE_BITS - 1)
    return np.where(np.isfinite(values), kept, values).astype(np.float16)


def _quantise(v: FloatArray, lo: float, hi: float) -> npt.NDArray[np.uint16]:
    span = hi - lo if hi > lo else 1.0
    return np.round(np.clip((v - lo) / span, 0.0, 1.0) * 65535.0).astype(np.uint16)


def build_payload(geometry: SimulationResult, variants: list[Variant], *,
                  meta: dict[str, object], gcode_text: bytes | None) -> tuple[str, str]:
    """Pack a report's data.

    Parameters
    ----------
    geometry
        The simulation whose moves are drawn (the original file).
    variants
        Value sets on those moves (one, or before and after).
    meta
        JSON-able facts for the page (file, machine, window, …).
    gcode_text
        The G-code source (drawn on when a move is clicked), or ``None``.

    Returns
    -------
    header_json, blob_base64
        The header (already safe inside a ``<script>`` element) and the data blob.
    """
    tab = geometry.plan.table
    m = tab.moves
    n = len(m)
    blob = Blob()
    xyz = np.column_stack([m["x"], m["y"], m["z"]]).astype(np.float64)
    start = np.asarray(tab.start_xyze[:3], dtype=np.float64)
    pts = np.vstack([start[None, :], xyz])
    lo = np.min(pts, axis=0)
    hi = np.max(pts, axis=0)
    hi = np.where(hi > lo, hi, lo + 1.0)
    for k, axis in enumerate("xyz"):
        blob.add(axis, _quantise(xyz[:, k], float(lo[k]), float(hi[k])))
    blob.add("kind", m["kind"].astype(np.uint8))
    blob.add("layer", (m["layer"].astype(np.int64) + 1).clip(0, 65535).astype(np.uint16))
    nf = len(tab.features)
    feat = (m["feature"].astype(np.int64) + 1).clip(0, None)
    blob.add("feature", feat.astype(np.uint8 if nf < 255 else np.uint16))
    wnom = np.asarray(geometry.metrics["width_nominal_mm"], dtype=np.float64)
    blob.add("wnom", np.round(np.nan_to_num(wnom, nan=0.0).clip(0.0, 2.55) * 100.0
                              ).astype(np.uint8))
    lines = m["line"].astype(np.int64)
    blob.add("dline", np.diff(np.concatenate(([0], lines))).astype(np.int32))
    var_json = []
    for vi, var in enumerate(variants):
        qs = []
        for q in var.quantities:
            name = blob.add(f"v{vi}.{q.key}", _values_array(q.values))
            dom = q.domain()
            qs.append({"key": q.key, "label": q.label, "unit": q.unit, "array": name,
                       "diverging": q.diverging, "reverse": q.reverse,
                       "domain": [_num(dom[0]), _num(dom[1])]})
        ms = np.round(np.nan_to_num(var.t_start_s, nan=0.0) * 1000.0).astype(np.int64)
        blob.add(f"v{vi}.t", np.diff(np.concatenate(([0], ms))).clip(0, None).astype(np.uint32))
        tr = var.track
        chans = {}
        for cname, (clo, chi, cmean) in tr.channels.items():
            chans[cname] = [blob.add(f"v{vi}.{cname}.lo", clo.astype(np.float32)),
                            blob.add(f"v{vi}.{cname}.hi", chi.astype(np.float32)),
                            blob.add(f"v{vi}.{cname}.mean", cmean.astype(np.float32))]
        blob.add(f"v{vi}.retract", tr.retractions_s.astype(np.float32))
        layer_cols = {}
        for col in (var.layers[0].keys() if var.layers else ()):
            vals = np.array([float(r[col]) if r[col] is not None else np.nan  # type: ignore[arg-type]
                             for r in var.layers], dtype=np.float64)
            layer_cols[col] = blob.add(f"v{vi}.layers.{col}", vals.astype(
                np.int32 if col in ("layer", "grinding_moves") else np.float32))
        var_json.append({
            "name": var.name, "label": var.label, "quantities": qs, "t": f"v{vi}.t",
            "track": {"t0": tr.t0_s, "dt": tr.dt_s, "channels": chans,
                      "retract": f"v{vi}.retract", "source": tr.source},
            "layers": {"n": len(var.layers), "columns": layer_cols},
            "features": var.features, "spots": var.spots,
            "flow_scale": var.flow_scale_mm3_s})
    text_info = None
    if gcode_text is not None and len(gcode_text) <= GCODE_EMBED_MAX_BYTES:
        blob.add_bytes("gcode", gcode_text)
        text_info = "gcode"
    header = {
        "version": 1, "meta": meta, "n": n, "lo": lo.tolist(), "hi": hi.tolist(),
        "start": start.tolist(), "features": list(tab.features),
        "layer_z": [_num(z) for z in layer_heights_z(geometry)], "variants": var_json,
        "gcode": text_info,
        "gcode_skipped": gcode_text is not None and text_info is None,
        "arrays": blob.index}
    return to_script_json(header), blob.encode()


def layer_heights_z(result: SimulationResult) -> list[float]:
    """Z of every layer, mm: the reader's (from the slicer's layer comments) where it has
    one, else the Z of the layer's first printing move."""
    tab = result.plan.table
    m = tab.moves
    layer = m["layer"].astype(np.int64)
    n_layers = int(layer.max()) + 1 if layer.size else 0
    out = [float(z) for z in tab.layer_z[:n_layers]]
    out += [math.nan] * (n_layers - len(out))
    kind = m["kind"].astype(np.int64)
    printing = np.flatnonzero(((kind & _PRINTING) == _PRINTING) & (layer >= 0))
    if printing.size:
        first = np.unique(layer[printing], return_index=True)
        for k, i in zip(first[0].tolist(), first[1].tolist(), strict=True):
            if not math.isfinite(out[k]):
                out[k] = float(m["z"][printing[i]])
    return out


def _num(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def to_script_json(obj: object) -> str:
    """JSON that is safe inside a ``<script>`` element (no ``<``, ``>``, ``&`` as such)."""
    text = json.dumps(_finite(obj), allow_nan=False, separators=(",", ":"),
                      default=_json_default)
    return (text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")
            .replace("\u2028", "\\u2028").replace("\u2029", "\\u2029"))


def _finite(v: object) -> object:
    """Non-finite floats as ``None`` (JSON has no NaN), recursively."""
    if isinstance(v, float | np.floating):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, dict):
        return {str(k): _finite(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_finite(x) for x in v]
    return v


def _json_default(v: object) -> object:
    if isinstance(v, np.generic):
        return v.item()
    return str(v)
