"""Adaptive pressure advance: advance factors measured at several flows and accelerations.

OrcaSlicer's filament setting ``adaptive_pressure_advance_model`` ("Adaptive pressure
advance measurements") holds one measurement per line as three comma-separated numbers,
**advance factor, volumetric flow (mm³/s), acceleration (mm/s²)**, e.g.::

    0.04,3.96,3000
    0.033,3.96,10000
    0.029,7.91,3000
    0.026,7.91,10000

OrcaSlicer models the factor per acceleration as a monotone cubic (PCHIP) in flow, then
interpolates the per-acceleration values with a second PCHIP in acceleration, holding
each curve at its end values outside the measured range, and rounds to 0.001. It reads the
acceleration as a whole number, and ignores an acceleration measured at fewer than two
flows. :class:`AdaptivePaTable` follows the same scheme with the same end-derivative rule
(one-sided secants; interior slopes are the Fritsch–Butland weighted harmonic mean, as in
:class:`scipy.interpolate.PchipInterpolator`), vectorised over the queries (the tests
check it against :class:`scipy.interpolate.CubicHermiteSpline`), and *clamps* at the
edges of the data: no
extrapolation beyond the measured flows and accelerations. Unlike OrcaSlicer it keeps an
acceleration measured at one flow (as a factor independent of flow) and reports that
OrcaSlicer would drop it (:meth:`AdaptivePaTable.orca_warnings`).

Measurements come from a CSV with columns ``k_s``, ``accel_mm_s2`` and either
``flow_mm3_s`` or ``speed_mm_s`` with ``line_width_mm`` and ``layer_height_mm`` (the flow
is then the slicer bead [001 Eq. 7] times the speed, as OrcaSlicer computes it for its
test patterns), and optionally ``k_err_s``, the 1σ error ``flowtwin calibrate fit-k``
reports (``fit-k --append-to`` writes exactly such rows). Repeated measurements at the
same flow and acceleration are averaged, weighted by ``1/k_err_s²`` when the errors are
given.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.atomic import atomic_write_text
from flowtwin.calibration.csvdata import Column, Table
from flowtwin.errors import DataError
from flowtwin.firmware import MAX_K_S
from flowtwin.gcode.emitter import format_number
from flowtwin.physics.deposition import bead_area_mm2

__all__ = [
    "ADAPTIVE_PA_COLUMNS",
    "FIT_K_MEASUREMENT_HEADER",
    "AdaptivePaTable",
    "append_measurement",
    "hermite_slopes",
    "parse_orca_model",
    "read_orca_model",
    "table_from_measurements",
    "write_orca_model",
]

FloatArray = npt.NDArray[np.float64]

#: Columns of a measurements file.
ADAPTIVE_PA_COLUMNS = (
    Column("k_s", "best advance factor at that flow and acceleration, s", lower=0.0,
           upper=MAX_K_S),
    Column("accel_mm_s2", "print acceleration of the test, mm/s²", lower=0.0,
           lower_open=True, upper=1e6),
    Column("flow_mm3_s", "volumetric flow of the test, mm³/s", required=False, lower=0.0,
           lower_open=True, upper=1e4),
    Column("speed_mm_s", "print speed of the test, mm/s", required=False, lower=0.0,
           lower_open=True, upper=1e4),
    Column("line_width_mm", "line width of the test, mm", required=False, lower=0.0,
           lower_open=True, upper=10.0),
    Column("layer_height_mm", "layer height of the test, mm", required=False, lower=0.0,
           lower_open=True, upper=10.0),
    Column("k_err_s", "1-sigma error of k_s (from fit-k), s; repeats are weighted by "
                      "1/error²", required=False, lower=0.0, lower_open=True, upper=MAX_K_S),
)

#: Header of the measurements file ``flowtwin calibrate fit-k --append-to`` writes.
FIT_K_MEASUREMENT_HEADER = "k_s,k_err_s,flow_mm3_s,accel_mm_s2"


def hermite_slopes(x: npt.ArrayLike, y: npt.ArrayLike) -> FloatArray:
    """Node slopes of OrcaSlicer's PCHIP: harmonic-mean interior, secant ends.

    Interior node ``i`` with secants ``δ₀ = δ_{i−1}``, ``δ₁ = δ_i`` and spacings ``h₀, h₁``:
    ``d_i = (w₁ + w₂)/(w₁/δ₀ + w₂/δ₁)`` with ``w₁ = 2h₁ + h₀``, ``w₂ = h₁ + 2h₀`` when the
    secants have the same sign, else 0 (Fritsch–Butland; keeps the curve monotone).
    End nodes take the adjacent secant.

    Parameters
    ----------
    x
        Strictly increasing nodes, shape ``(m,)``, ``m >= 2``.
    y
        Values, shape ``(m,)`` or ``(m, k)`` (``k`` curves on the same nodes).

    Returns
    -------
    ndarray
        Slopes ``dy/dx`` at the nodes, shape of ``y``.
    """
    xs = np.asarray(x, dtype=np.float64)
    ys = np.asarray(y, dtype=np.float64)
    shape = (-1,) + (1,) * (ys.ndim - 1)
    h = np.diff(xs).reshape(shape)
    delta = np.diff(ys, axis=0) / h
    d = np.empty_like(ys)
    d[0], d[-1] = delta[0], delta[-1]
    if xs.size > 2:
        d0, d1 = delta[:-1], delta[1:]
        h0, h1 = h[:-1], h[1:]
        w1, w2 = 2.0 * h1 + h0, h1 + 2.0 * h0
        same = d0 * d1 > 0.0
        # where a secant is 0 (or tiny) the mean is 0 (or tiny) and unused if signs differ
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            mean = (w1 + w2) / (w1 / d0 + w2 / d1)
        d[1:-1] = np.where(same, mean, 0.0)
    return d


def _clamped_pchip(x: FloatArray, y: FloatArray, q: FloatArray) -> FloatArray:
    """Evaluate PCHIP curves through ``(x, y[:, j])`` at ``q[j]``, held at the end values.

    ``x`` shape ``(m,)``; ``y`` shape ``(m,)`` (one curve for every query) or ``(m, k)``
    (curve ``j`` for query ``j``); ``q`` shape ``(k,)``. Cubic Hermite form on the
    interval ``[x_i, x_{i+1}]`` with ``t = (q − x_i)/h_i``:
    ``p = h00·y_i + h10·h_i·d_i + h01·y_{i+1} + h11·h_i·d_{i+1}``.
    """
    if y.ndim == 1:
        y = np.broadcast_to(y[:, None], (y.size, q.size))
    if x.size == 1:
        return np.array(y[0], dtype=np.float64, copy=True)
    d = hermite_slopes(x, y)
    qc = np.clip(q, x[0], x[-1])
    i = np.clip(np.searchsorted(x, qc, side="right") - 1, 0, x.size - 2)
    cols = np.arange(q.size)
    h = x[i + 1] - x[i]
    t = (qc - x[i]) / h
    t2, t3 = t * t, t * t * t
    return ((2 * t3 - 3 * t2 + 1) * y[i, cols] + (t3 - 2 * t2 + t) * h * d[i, cols]
            + (-2 * t3 + 3 * t2) * y[i + 1, cols] + (t3 - t2) * h * d[i + 1, cols])


@dataclass(frozen=True)
class AdaptivePaTable:
    """Advance factors at (flow, acceleration) points, interpolated as OrcaSlicer does.

    Attributes
    ----------
    k_s
        Advance factor of each point, s, shape ``(n,)``.
    flow_mm3_s
        Volumetric flow of each point, mm³/s, shape ``(n,)``.
    accel_mm_s2
        Acceleration of each point, mm/s² (whole numbers), shape ``(n,)``.

    Points are sorted by acceleration, then flow; each (flow, acceleration) pair is
    unique. Build with :meth:`from_points`.
    """

    k_s: FloatArray
    flow_mm3_s: FloatArray
    accel_mm_s2: FloatArray

    @classmethod
    def from_points(cls, k_s: npt.ArrayLike, flow_mm3_s: npt.ArrayLike,
                    accel_mm_s2: npt.ArrayLike, *, source: str = "<data>",
                    lines: npt.ArrayLike | None = None,
                    k_err_s: npt.ArrayLike | None = None) -> AdaptivePaTable:
        """Sort, validate and average repeated points.

        With ``k_err_s`` (1σ errors, s, shape ``(n,)``) repeats are averaged with weights
        ``1/k_err_s²``; otherwise with equal weights.

        Raises
        ------
        DataError
            Unequal lengths, no points, a negative or non-finite value, or an acceleration
            that is not a whole number (OrcaSlicer reads it as an integer).
        """
        k = np.asarray(k_s, dtype=np.float64).ravel()
        q = np.asarray(flow_mm3_s, dtype=np.float64).ravel()
        a = np.asarray(accel_mm_s2, dtype=np.float64).ravel()
        where = None if lines is None else np.asarray(lines, dtype=np.int64).ravel()
        if not k.size or k.shape != q.shape or k.shape != a.shape:
            raise DataError("advance measurements need equal numbers of k_s, flow and "
                            "acceleration values", source=source, value=(k.size, q.size, a.size))
        for name, arr, ok in (("k_s", k, (k >= 0.0) & (k <= MAX_K_S)),
                              ("flow_mm3_s", q, q > 0.0), ("accel_mm_s2", a, a > 0.0)):
            bad = np.nonzero(~(ok & np.isfinite(arr)))[0]
            if bad.size:
                i = int(bad[0])
                raise DataError("invalid advance measurement", source=source,
                                line=None if where is None else int(where[i]), field=name,
                                value=float(arr[i]), allowed="finite, > 0 (k_s: 0 .. 10 s)")
        frac = np.abs(a - np.round(a))
        bad = np.nonzero(frac > 1e-6 * np.maximum(a, 1.0))[0]
        if bad.size:
            i = int(bad[0])
            raise DataError("acceleration must be a whole number of mm/s² (OrcaSlicer reads "
                            "it as an integer)", source=source,
                            line=None if where is None else int(where[i]),
                            field="accel_mm_s2", value=float(a[i]), allowed="an integer")
        a = np.round(a)
        weights = np.ones_like(k)
        if k_err_s is not None:
            err = np.asarray(k_err_s, dtype=np.float64).ravel()
            if err.shape != k.shape:
                raise DataError("one advance-factor error per measurement is needed",
                                source=source, field="k_err_s", value=(err.size, k.size))
            bad = np.nonzero(~((err > 0.0) & np.isfinite(err)))[0]
            if bad.size:
                i = int(bad[0])
                raise DataError("invalid advance-factor error", source=source,
                                line=None if where is None else int(where[i]),
                                field="k_err_s", value=float(err[i]), allowed="finite, > 0 s")
            weights = 1.0 / err ** 2
        keys = np.stack([a, q])
        uniq, inverse = np.unique(keys, axis=1, return_inverse=True)
        inverse = inverse.ravel()
        k_mean = np.bincount(inverse, weights=weights * k) / np.bincount(inverse,
                                                                         weights=weights)
        order = np.lexsort((uniq[1], uniq[0]))
        return cls(k_mean[order], uniq[1][order].copy(), uniq[0][order].copy())

    def __len__(self) -> int:
        return int(self.k_s.shape[0])

    @property
    def accelerations(self) -> FloatArray:
        """Distinct accelerations, ascending, mm/s²."""
        return np.unique(self.accel_mm_s2)

    def k_at(self, flow_mm3_s: npt.ArrayLike, accel_mm_s2: npt.ArrayLike, *,
             orca_rounding: bool = False) -> FloatArray:
        """Interpolated advance factor (s), clamped at the edges of the data.

        Parameters
        ----------
        flow_mm3_s
            Volumetric flow, mm³/s, any shape.
        accel_mm_s2
            Acceleration, mm/s², broadcast.
        orca_rounding
            Round to 0.001 s like OrcaSlicer.

        Returns
        -------
        ndarray
            Advance factor, s, broadcast shape.
        """
        q, a = np.broadcast_arrays(np.asarray(flow_mm3_s, dtype=np.float64),
                                   np.asarray(accel_mm_s2, dtype=np.float64))
        accs = self.accelerations
        # per acceleration: factor at each query flow, shape (n_acc, n_query); then, per
        # query, the curve over acceleration through those values
        per_acc = np.vstack([
            _clamped_pchip(self.flow_mm3_s[self.accel_mm_s2 == acc],
                           self.k_s[self.accel_mm_s2 == acc], q.ravel())
            for acc in accs])
        out = _clamped_pchip(accs, per_acc, a.ravel()).reshape(q.shape)
        return np.round(out, 3) if orca_rounding else out

    def orca_warnings(self) -> list[str]:
        """What OrcaSlicer would do differently with this table."""
        notes = []
        for acc in self.accelerations:
            n = int(np.count_nonzero(self.accel_mm_s2 == acc))
            if n < 2:
                notes.append(f"acceleration {acc:g} mm/s² has one flow only: OrcaSlicer "
                             "ignores it (measure it at two or more flows)")
        if len(self.accelerations) == len(self):
            notes.append("no acceleration has two flows: OrcaSlicer cannot use this table "
                         "and falls back to the fixed pressure advance")
        return notes

    def to_orca_text(self) -> str:
        """The table in OrcaSlicer's format: ``k,flow,accel`` per line."""
        return "".join(f"{format_number(k, 4)},{format_number(q, 2)},{a:.0f}\n"
                       for k, q, a in zip(self.k_s.tolist(), self.flow_mm3_s.tolist(),
                                          self.accel_mm_s2.tolist(), strict=True))


def table_from_measurements(table: Table) -> AdaptivePaTable:
    """An :class:`AdaptivePaTable` from a measurements CSV table (see module docstring).

    Raises
    ------
    DataError
        Neither ``flow_mm3_s`` nor the three columns it can be computed from, or both.
    """
    has_flow = table.has("flow_mm3_s")
    bead = [c for c in ("speed_mm_s", "line_width_mm", "layer_height_mm") if table.has(c)]
    if has_flow == bool(bead) or (bead and len(bead) != 3):
        raise DataError("give the flow either as flow_mm3_s or as speed_mm_s with "
                        "line_width_mm and layer_height_mm", source=table.source,
                        field="flow_mm3_s", value=",".join(table.columns),
                        allowed="flow_mm3_s, or speed_mm_s + line_width_mm + layer_height_mm")
    if has_flow:
        flow = table.get("flow_mm3_s")
    else:
        w, h = table.get("line_width_mm"), table.get("layer_height_mm")
        narrow = np.nonzero(w < h)[0]
        if narrow.size:
            i = int(narrow[0])
            raise DataError("line narrower than the layer height: the bead model [001 "
                            "Eq. 7] is ill-defined", source=table.source,
                            line=int(table.lines[i]), field="line_width_mm",
                            value=float(w[i]), allowed=f">= layer height {h[i]:g} mm")
        flow = bead_area_mm2(w, h) * table.get("speed_mm_s")
    return AdaptivePaTable.from_points(table.get("k_s"), flow, table.get("accel_mm_s2"),
                                       source=table.source, lines=table.lines,
                                       k_err_s=table.get("k_err_s") if table.has("k_err_s")
                                       else None)


def append_measurement(path: str | os.PathLike[str], row: dict[str, float]) -> int:
    """Append one ``k_s,k_err_s,flow_mm3_s,accel_mm_s2`` row to a measurements file.

    The file is created with :data:`FIT_K_MEASUREMENT_HEADER` if missing; an existing file
    must have exactly that header. The whole file is rewritten atomically.

    Parameters
    ----------
    path
        Measurements CSV (the input of :func:`table_from_measurements`).
    row
        ``k_s``, ``k_err_s``, ``flow_mm3_s``, ``accel_mm_s2`` (whole number).

    Returns
    -------
    int
        Number of measurement rows in the file afterwards.

    Raises
    ------
    DataError
        An existing file with another header, or unreadable.
    """
    name = os.fspath(path)
    text = ""
    if os.path.exists(name):
        try:
            with open(name, encoding="utf-8") as fh:
                text = fh.read()
        except (OSError, UnicodeDecodeError) as exc:
            raise DataError(f"cannot read the measurements file: {exc}", source=name) from exc
    header = next((ln.strip() for ln in text.splitlines()
                   if ln.strip() and not ln.lstrip().startswith("#")), None)
    if header is None:
        text = FIT_K_MEASUREMENT_HEADER + "\n"
    elif header.replace(" ", "") != FIT_K_MEASUREMENT_HEADER:
        raise DataError("the measurements file has other columns", source=name, field="header",
                        value=header, allowed=FIT_K_MEASUREMENT_HEADER)
    elif not text.endswith("\n"):
        text += "\n"
    text += (f"{row['k_s']:.6g},{row['k_err_s']:.3g},{row['flow_mm3_s']:.6g},"
             f"{row['accel_mm_s2']:.0f}\n")
    atomic_write_text(name, text)
    return sum(1 for ln in text.splitlines() if ln.strip() and not ln.startswith("#")) - 1


def read_orca_model(path: str | os.PathLike[str]) -> AdaptivePaTable:
    """Read OrcaSlicer's ``k,flow,accel`` text (one triple per line; ``\\n`` escapes too).

    Raises
    ------
    DataError
        A line that is not three numbers (the message names the line and the value).
    """
    name = os.fspath(path)
    try:
        with open(name, encoding="utf-8") as fh:
            text = fh.read()
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"cannot read the table: {exc}", source=name) from exc
    return parse_orca_model(text, source=name)


def parse_orca_model(text: str, *, source: str = "<text>") -> AdaptivePaTable:
    """Parse OrcaSlicer's adaptive-PA text (see :func:`read_orca_model`)."""
    text = text.strip().strip('"').replace("\\n", "\n")
    ks: list[float] = []
    qs: list[float] = []
    accs: list[float] = []
    lines: list[int] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        cells = [c.strip() for c in line.split(",")]
        numbers = [_float(c) for c in cells]
        if len(cells) != 3 or any(v is None for v in numbers):
            raise DataError("an adaptive pressure advance line must be three numbers",
                            source=source, line=lineno, value=line,
                            allowed="advance factor, flow (mm³/s), acceleration (mm/s²)")
        k, q, a = (float(v) for v in numbers)  # type: ignore[arg-type]
        ks.append(k)
        qs.append(q)
        accs.append(a)
        lines.append(lineno)
    if not ks:
        raise DataError("no measurements in the table", source=source,
                        allowed="lines 'k,flow,accel'")
    return AdaptivePaTable.from_points(ks, qs, accs, source=source, lines=lines)


def write_orca_model(path: str | os.PathLike[str], table: AdaptivePaTable) -> None:
    """Write ``table`` in OrcaSlicer's format, atomically."""
    atomic_write_text(path, table.to_orca_text())


def _float(cell: str) -> float | None:
    try:
        value = float(cell)
    except ValueError:
        return None
    return value if math.isfinite(value) else None
