"""The lag ``K`` (and optionally a dead time and a gain) from bead widths along test lines.

The measured width profile of one or more test lines is compared with the twin's
prediction (:class:`~flowtwin.calibration.fits.lagmodel.LagModel`: planner + dynamics with a
free lag, [001 Eqs. 7, 10, 15]) and ``K`` — with the dead time ``τ`` and the gain ``g`` of
Bellini's ``g·e^(−τs)/(1 + K·s)`` if asked — is found by nonlinear least squares
(:func:`scipy.optimize.least_squares`, trust region with bounds) on the width residuals.

Fitting hygiene (docs/calibration.md):

* **Start.** ``K`` is first scanned on a logarithmic grid (12 values, 5 ms … 2 s, each
  72 % above the last) with ``τ = 0`` and ``g = 1``; the best grid point starts the fit,
  so a machine profile far from the truth does not trap it in a local minimum.
* **Jacobian.** Central differences with steps chosen per parameter: ``1e-3·K`` for the
  lag (the integrator is exact, the width smooth in ``K``), one flow-series sample for
  the dead time (the series is interpolated linearly in time), ``1e-3`` for the gain.
  Only ``K`` changes the dynamics: the flow series is computed once per ``K`` and reused
  for the other parameters.
* **Uncertainty.** ``cov = s²·(JᵀJ)⁻¹`` with ``s² = Σr²/(n − p)``: the noise level is
  estimated from the scatter, the errors are taken as independent (width samples closer
  than the measurement's own resolution are correlated, which makes ``σ`` optimistic).
* **Degenerate data** raise :class:`~flowtwin.errors.CalibrationError` with the reason:
  fewer usable points than parameters + 1, a singular ``JᵀJ`` (e.g. a line at one speed:
  its width does not depend on ``K``), a standard error larger than half the value, a
  parameter that ends on its bound, or a sum of squares that does not rise by ``s²`` 2σ
  to either side of the optimum (the data bound the parameter from one side only, e.g.
  a constant-speed line whose start transient only says "K is not large"; the Gaussian
  ``σ`` would be a false statement there).
"""

from __future__ import annotations

import functools
import itertools
import math
import os
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from flowtwin.calibration.csvdata import Column, Table, read_table
from flowtwin.calibration.fits.lagmodel import DEAD_TIME_MAX_S, LagModel, LagParams, TestLine
from flowtwin.calibration.fragment import render_fragment
from flowtwin.errors import CalibrationError, DataError

__all__ = [
    "PROFILE_COLUMNS",
    "LagFit",
    "WidthProfile",
    "fit_lag",
    "profiles_from_table",
    "read_width_profiles",
]

FloatArray = npt.NDArray[np.float64]

#: Columns of a width-profile file (fit-k).
PROFILE_COLUMNS = (
    Column("position_mm", "distance along the test line from its start, in the print "
                          "direction, mm", lower=0.0, upper=10000.0),
    Column("width_mm", "measured bead width at that position, mm", lower=0.0, upper=20.0),
    Column("gcode_line", "G-code line of the first move of the test line the row belongs "
                         "to (several lines in one file)", required=False, lower=1.0,
           upper=1e9),
)

#: Parameter bounds of the fit: (lower, upper).
_BOUNDS = {"k_s": (1e-3, 5.0), "dead_time_s": (0.0, DEAD_TIME_MAX_S), "gain": (0.2, 5.0),
           "shift_mm": (-5.0, 5.0), "stretch": (-0.1, 0.1)}
#: Finite-difference step of each parameter (K: relative).
_STEPS = {"k_s": 1e-3, "gain": 1e-3, "shift_mm": 0.01, "stretch": 1e-4}
#: Typical size of each parameter for the trust region (where its start is 0).
_X_SCALE = {"shift_mm": 0.1, "stretch": 1e-3}
#: Spacing of the points the model is averaged over within a measurement window, mm: a
#: junction's slow-down bulge is a few hundredths of a millimetre long, and a coarser
#: average makes the fit's sum of squares jump as the window slides over it.
_WINDOW_STEP_MM = 0.01
#: Grid of the start scan of K, s.
_K_SCAN = np.geomspace(0.005, 2.0, 12)
#: A dead time known worse than this (s) is "not determined".
_DEAD_TIME_MAX_ERR_S = 0.1


@dataclass(frozen=True)
class WidthProfile:
    """Widths measured along one test line.

    Attributes
    ----------
    positions_mm
        Distance from the line's start in the print direction, mm, shape ``(n,)``.
    widths_mm
        Measured width, mm, shape ``(n,)``; NaN where nothing could be measured.
    source
        Where the numbers come from (file name, image), for messages.
    window_mm
        Length along the line over which each width is averaged by the measurement
        (0: a point measurement); the model is averaged over the same window.
    """

    positions_mm: FloatArray
    widths_mm: FloatArray
    source: str = "<data>"
    window_mm: float = 0.0

    def __post_init__(self) -> None:
        if self.positions_mm.shape != self.widths_mm.shape or self.positions_mm.ndim != 1:
            raise DataError("positions and widths must be 1-D arrays of equal length",
                            source=self.source, field="widths_mm",
                            value=(self.positions_mm.shape, self.widths_mm.shape))


def profiles_from_table(table: Table) -> dict[int | None, WidthProfile]:
    """Width profiles from a read table: one per ``gcode_line`` value (or one, key ``None``).

    Raises
    ------
    DataError
        A ``gcode_line`` that is not a whole number.
    """
    x, w = table.get("position_mm"), table.get("width_mm")
    if not table.has("gcode_line"):
        return {None: WidthProfile(x.copy(), w.copy(), table.source)}
    gl = table.get("gcode_line")
    bad = np.flatnonzero(gl != np.round(gl))
    if bad.size:
        i = int(bad[0])
        raise DataError("gcode_line must be a whole line number", source=table.source,
                        line=int(table.lines[i]), field="gcode_line", value=float(gl[i]),
                        allowed="an integer >= 1")
    out: dict[int | None, WidthProfile] = {}
    for value in dict.fromkeys(gl.astype(np.int64).tolist()):
        sel = gl == value
        out[int(value)] = WidthProfile(x[sel].copy(), w[sel].copy(), table.source)
    return out


def read_width_profiles(path: str | os.PathLike[str]) -> dict[int | None, WidthProfile]:
    """Read a width-profile CSV (columns :data:`PROFILE_COLUMNS`).

    Returns
    -------
    dict
        ``gcode_line`` → profile, or ``{None: profile}`` without that column.

    Raises
    ------
    DataError
        Any problem of the file (see :mod:`~flowtwin.calibration.csvdata`).
    """
    return profiles_from_table(read_table(path, PROFILE_COLUMNS, min_rows=3))


@dataclass(frozen=True)
class LagFit:
    """Result of :func:`fit_lag`.

    Attributes
    ----------
    params
        Best lag, dead time and gain (the ones not fitted at their fixed values).
    fitted
        Names of the fitted parameters, in order.
    stderr
        1σ standard error of each fitted parameter.
    covariance
        Covariance of the fitted parameters, shape ``(p, p)``.
    n_points
        Width samples used.
    n_excluded
        Samples left out (line ends, slow nozzle, no measurement, narrower than the layer).
    rms_mm
        RMS width residual, mm.
    line_rms_mm
        RMS residual per test line, mm.
    lines
        The test lines.
    machine_lag_s
        The lag the machine profile predicts for these lines, s (for comparison).
    registration
        Fitted shift (mm) and stretch of the measured positions (empty if not fitted).
    notes
        Facts worth knowing about the fit.
    """

    params: LagParams
    fitted: tuple[str, ...]
    stderr: dict[str, float]
    covariance: FloatArray
    n_points: int
    n_excluded: int
    rms_mm: float
    line_rms_mm: tuple[float, ...]
    lines: tuple[TestLine, ...]
    machine_lag_s: float
    registration: dict[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def k_s(self) -> float:
        """Fitted lag factor, s."""
        return self.params.k_s

    @property
    def k_err_s(self) -> float:
        """1σ standard error of the lag factor, s."""
        return self.stderr["k_s"]

    def correlation(self) -> FloatArray:
        """Correlation matrix of the fitted parameters, shape ``(p, p)``."""
        d = np.sqrt(np.diag(self.covariance))
        return np.asarray(self.covariance / np.outer(d, d), dtype=np.float64)

    def summary(self) -> dict[str, Any]:
        """Plain JSON-able description."""
        p = self.params
        return {
            "k_s": p.k_s, "k_err_s": self.stderr["k_s"],
            "dead_time_s": p.dead_time_s, "dead_time_err_s": self.stderr.get("dead_time_s"),
            "gain": p.gain, "gain_err": self.stderr.get("gain"),
            "fitted": list(self.fitted),
            "registration": {k: {"value": v, "err": self.stderr[k]}
                             for k, v in self.registration.items()},
            "correlation": self.correlation().tolist(),
            "points": self.n_points, "excluded": self.n_excluded, "rms_mm": self.rms_mm,
            "machine_lag_s": self.machine_lag_s,
            "lines": [{"gcode_line": ln.gcode_line, "length_mm": ln.length_mm,
                       "advance_k_s": ln.advance_k_s, "layer_height_mm": ln.layer_height_mm,
                       "flow_mm3_s": ln.flow_mm3_s, "accel_mm_s2": ln.accel_mm_s2,
                       "rms_mm": r} for ln, r in zip(self.lines, self.line_rms_mm,
                                                      strict=True)],
            "notes": list(self.notes),
        }

    def fragment(self, header: Sequence[str] = ()) -> str:
        """A ``[pressure_advance]`` printer-profile fragment with ``k_s = K`` (± as comment).

        With the firmware's advance factor equal to the lag, the output follows the
        command [001 Eqs. 11, 15]. Dead time and gain have no profile key: they are
        written as comments.
        """
        lines = list(header)
        if "dead_time_s" in self.fitted:
            lines.append(f"dead time {self.params.dead_time_s:.4g} ± "
                         f"{self.stderr['dead_time_s']:.2g} s (no profile key)")
        if "gain" in self.fitted:
            meaning = ("(< 1: under-extrusion; adjust the extrusion multiplier)"
                       if self.params.gain < 1.0 else
                       "(> 1: beads wider than the twin's for this flow: over-extrusion, a "
                       "squashed first layer, or a width scale that is off)")
            lines.append(f"flow gain {self.params.gain:.4g} ± {self.stderr['gain']:.2g} "
                         f"{meaning}")
        lines.append("paste into the printer profile in place of its [pressure_advance] "
                     "table (a Klipper smooth_time_s there stays as it was)")
        return render_fragment("pressure_advance", {"k_s": round(self.params.k_s, 6)},
                               stderr={"k_s": self.stderr["k_s"]}, header=lines)

    def measurement_row(self) -> dict[str, float]:
        """``k_s, k_err_s, flow_mm3_s, accel_mm_s2`` for an adaptive-PA measurements file.

        Raises
        ------
        CalibrationError
            The lines were printed at different flows or accelerations (fit each
            test condition separately).
        """
        flows = np.array([ln.flow_mm3_s for ln in self.lines])
        accs = np.array([ln.accel_mm_s2 for ln in self.lines])
        if np.ptp(flows) > 0.01 * np.max(flows) or np.ptp(accs) > 0.01 * np.max(accs):
            raise CalibrationError("the test lines differ in flow or acceleration: one "
                                   "adaptive-PA measurement needs one test condition",
                                   field="lines", value={"flow_mm3_s": flows.tolist(),
                                                         "accel_mm_s2": accs.tolist()},
                                   allowed="lines of one flow and one acceleration")
        return {"k_s": self.params.k_s, "k_err_s": self.stderr["k_s"],
                "flow_mm3_s": float(np.mean(flows)), "accel_mm_s2": float(round(accs[0]))}


def _usable_points(model: LagModel, profiles: Sequence[WidthProfile], end_margin_mm: float
                   ) -> tuple[list[FloatArray], list[FloatArray], int]:
    xs: list[FloatArray] = []
    ws: list[FloatArray] = []
    excluded = 0
    for i, (line, prof) in enumerate(zip(model.lines, profiles, strict=True)):
        x = np.asarray(prof.positions_mm, dtype=np.float64)
        w = np.asarray(prof.widths_mm, dtype=np.float64)
        outside = np.flatnonzero(x > line.length_mm + 1e-6)
        if outside.size:
            raise DataError("position beyond the end of the test line", source=prof.source,
                            field="position_mm", value=float(x[outside[0]]),
                            allowed=f"0 .. {line.length_mm:g} mm (the line from G-code "
                                    f"line {line.gcode_line})")
        ok = model.usable(i, x, end_margin_mm=end_margin_mm)
        ok &= np.isfinite(w) & (w >= line.layer_height_mm)
        excluded += int(x.size - np.count_nonzero(ok))
        xs.append(x[ok])
        ws.append(w[ok])
    return xs, ws, excluded


def _check_curvature(names: Sequence[str], values: FloatArray, err: FloatArray,
                     residuals: Callable[[FloatArray], FloatArray], ssr: float,
                     s2: float) -> None:
    """Refuse a σ the data do not back: the sum of squares must rise on both sides.

    For a model linear in its parameters, moving one parameter by 2σ (the others held)
    raises the sum of squares by at least ``4·s²``. Where it rises by less than ``s²`` on
    one side the likelihood is flat there — the widths bound the parameter from one side
    only (a lag longer than the line shows, or one too short to see) — and ``± σ`` would
    be a false statement.
    """
    for j, name in enumerate(names):
        lo, hi = _BOUNDS[name]
        for sign in (-1.0, 1.0):
            v = values.copy()
            v[j] = values[j] + sign * 2.0 * err[j]
            if not lo <= v[j] <= hi:
                continue    # the bound itself limits this side
            r = residuals(v)
            rise = float(np.sum(r ** 2)) - ssr
            if not rise >= s2:
                side = "below" if sign < 0 else "above"
                raise CalibrationError(
                    f"the widths do not determine {name}: {values[j]:.4g} ± {err[j]:.2g} "
                    f"is not backed by the data (the fit barely changes {side} it; they "
                    "bound it from one side only)", field=name, value=float(values[j]),
                    allowed="a sum of squares that rises on both sides (lines with speed "
                            "changes inside the measured part)")


def fit_lag(model: LagModel, profiles: Sequence[WidthProfile] | Mapping[Any, WidthProfile], *,
            fit_dead_time: bool = False, fit_gain: bool = False,
            fit_registration: bool = False, fixed: LagParams | None = None,
            end_margin_mm: float = 1.0, max_relative_error: float = 0.5) -> LagFit:
    """Fit the lag ``K`` (and optionally ``τ``, ``g``) of the twin to measured widths.

    Parameters
    ----------
    model
        The test lines in their planned G-code (:func:`~flowtwin.calibration.fits.lagmodel.
        lag_model`).
    profiles
        One measured profile per test line, in the order of ``model.lines`` (a mapping
        is taken in its iteration order).
    fit_dead_time, fit_gain
        Also fit the dead time ``τ`` / the flow gain ``g``; otherwise they stay at
        ``fixed``'s values (default ``τ = 0``, ``g = 1``).
    fit_registration
        Also fit a shift ``δ`` (mm) and a relative stretch ``ε`` of the measured
        positions, the same for every line: the model is evaluated at
        ``x_c + (1 + ε)·(x − x_c) + δ`` (``x_c`` the line's middle). For positions read
        from an image whose registration along the lines is uncertain by a fraction of a
        millimetre (the bead's ends are not the path's ends).
    fixed
        Values of the parameters that are not fitted (its ``k_s`` is ignored).
    end_margin_mm
        Samples this close to either end of a line are left out (end caps, start blob).
    max_relative_error
        A fitted parameter whose standard error exceeds this fraction of its value is
        "not determined" (the dead time, for which 0 is a valid answer: a standard error
        above 0.1 s).

    Returns
    -------
    LagFit

    Raises
    ------
    CalibrationError
        Too few usable points, degenerate data, an undetermined parameter or one on its
        bound (the message says which and why).
    """
    profs = list(profiles.values()) if isinstance(profiles, Mapping) else list(profiles)
    if len(profs) != len(model.lines):
        raise CalibrationError("one width profile per test line is needed", field="profiles",
                               value=len(profs), allowed=f"{len(model.lines)} profiles")
    base = fixed or LagParams(k_s=1.0)
    xs, ws, excluded = _usable_points(model, profs, end_margin_mm)
    names = (["k_s"] + (["dead_time_s"] if fit_dead_time else []) + (["gain"] if fit_gain
                                                                        else [])
             + (["shift_mm", "stretch"] if fit_registration else []))
    n = int(sum(x.size for x in xs))
    p = len(names)
    if n <= p + 1:
        raise CalibrationError(f"only {n} usable width samples for {p} parameter(s)",
                               field="width_mm", value=n,
                               allowed=f">= {p + 2} samples inside the lines, away from "
                                       f"their ends ({end_margin_mm:g} mm) and not narrower "
                                       "than the layer height")
    measured = np.concatenate(ws)
    # each sample is the mean of the model over its window: offsets within the window
    offsets = [np.linspace(-0.5, 0.5, 2 * int(np.ceil(0.5 * pr.window_mm / _WINDOW_STEP_MM))
                           + 1) * pr.window_mm if pr.window_mm > 0 else np.zeros(1)
               for pr in profs]
    centres = [0.5 * ln.length_mm for ln in model.lines]

    def params_of(v: FloatArray) -> LagParams:
        d = dict(zip(names, v.tolist(), strict=True))
        return LagParams(k_s=d["k_s"], dead_time_s=d.get("dead_time_s", base.dead_time_s),
                         gain=d.get("gain", base.gain))

    @functools.lru_cache(maxsize=9)
    def flow_at(k_s: float) -> tuple[FloatArray, FloatArray]:
        # the dynamics depend on K only (dead time, gain and positions act afterwards)
        return model.flow_series(LagParams(k_s=k_s))

    workers = min(2, os.cpu_count() or 1)

    def prefetch(ks: Sequence[float]) -> None:
        # the series of two trial lags side by side (a Jacobian's K ± h, two points of
        # the scan): the integrator's kernel releases the GIL, and each series is what
        # it would be alone (deterministic, nothing shared between the two)
        if workers >= 2 and len(set(ks)) > 1:
            with ThreadPoolExecutor(max_workers=workers) as pool:
                list(pool.map(flow_at, ks))

    @functools.lru_cache(maxsize=9)
    def positions(shift: float, stretch: float
                  ) -> tuple[list[FloatArray], list[tuple[FloatArray, FloatArray]]]:
        # the sample windows' positions and when the nozzle passes them depend on the
        # registration only (the lag, dead time and gain act on the flow)
        pts = []
        for x, off, c, ln in zip(xs, offsets, centres, model.lines, strict=True):
            xm = c + (1.0 + stretch) * (x - c) + shift
            pts.append(np.clip(xm[:, None] + off[None, :], 0.0, ln.length_mm).ravel())
        return pts, model.passes(pts)

    def predict(v: FloatArray) -> FloatArray:
        d = dict(zip(names, v.tolist(), strict=True))
        pts, at = positions(d.get("shift_mm", 0.0), d.get("stretch", 0.0))
        lp = params_of(v)
        w = model.widths(lp, pts, series=flow_at(lp.k_s), passes=at)
        return np.concatenate([wi.reshape(-1, off.size).mean(axis=1)
                               for wi, off in zip(w, offsets, strict=True)])

    def residuals(v: FloatArray) -> FloatArray:
        return np.asarray(predict(v) - measured, dtype=np.float64)

    def step(name: str, value: float) -> float:
        if name == "dead_time_s":
            return model.series_dt_s
        return _STEPS[name] * (abs(value) if name == "k_s" else 1.0)

    def jacobian(v: FloatArray) -> FloatArray:
        cols = []
        for j, name in enumerate(names):
            lo, hi = _BOUNDS[name]
            h = step(name, float(v[j]))
            a, b = max(v[j] - h, lo), min(v[j] + h, hi)
            va, vb = v.copy(), v.copy()
            va[j], vb[j] = a, b
            if name == "k_s":
                prefetch((float(vb[j]), float(va[j])))
            cols.append((residuals(vb) - residuals(va)) / (b - a))
        return np.column_stack(cols)

    # start: the best K of a log grid, other parameters at their fixed values
    rest = {"dead_time_s": min(max(base.dead_time_s, 0.002), DEAD_TIME_MAX_S / 2),
            "gain": base.gain, "shift_mm": 0.0, "stretch": 0.0}
    scan = []
    for i, k in enumerate(_K_SCAN):
        if i % 2 == 0:
            prefetch([float(x) for x in _K_SCAN[i:i + 2]])
        r = residuals(np.array([float(k)] + [rest[nm] for nm in names[1:]]))
        scan.append(float(np.sum(r[np.isfinite(r)] ** 2)))
    x0 = [float(_K_SCAN[int(np.argmin(scan))])] + [rest[nm] for nm in names[1:]]
    lower = [_BOUNDS[nm][0] for nm in names]
    upper = [_BOUNDS[nm][1] for nm in names]
    start = np.clip(np.asarray(x0), lower, upper)
    if not np.all(np.isfinite(residuals(start))):
        raise CalibrationError("the model width is undefined at some measured positions "
                               "(the nozzle stands still there)", field="position_mm")
    sol = least_squares(residuals, start, jac=jacobian, bounds=(lower, upper),
                        x_scale=np.array([max(abs(v), _X_SCALE.get(nm, 1e-2))
                                          for v, nm in zip(start, names, strict=True)]),
                        method="trf",
                        xtol=1e-8, ftol=1e-10, gtol=1e-10, max_nfev=200)
    if sol.status <= 0:
        raise CalibrationError(f"the lag fit did not converge: {sol.message}",
                               field=",".join(names))
    values = np.asarray(sol.x, dtype=np.float64)
    for name, value in zip(names, values.tolist(), strict=True):
        lo, hi = _BOUNDS[name]
        if name in ("shift_mm", "stretch"):
            at_lo, at_hi = value <= lo * (1 - 1e-6), value >= hi * (1 - 1e-6)
        else:
            at_lo = value <= lo * (1 + 1e-6) + 1e-12 and name != "dead_time_s"
            at_hi = value >= hi * (1 - 1e-6)
        if at_lo or at_hi:
            raise CalibrationError(f"the lag fit ends on the bound of {name} ({value:.4g}): "
                                   "the widths do not determine it", field=name,
                                   value=value, allowed=f"{lo:g} .. {hi:g}")
    jac = jacobian(values)
    resid = residuals(values)
    dof = n - p
    s2 = float(np.sum(resid ** 2)) / dof
    jtj = jac.T @ jac
    scale = np.sqrt(np.diag(jtj))
    if not np.all(scale > 0.0) or not np.all(np.isfinite(jtj)):
        raise CalibrationError("the widths do not depend on " + ", ".join(
            nm for nm, s in zip(names, scale.tolist(), strict=True) if not s > 0.0)
            + ": the lines need speed changes inside the measured part",
            field=",".join(names))
    normed = jtj / np.outer(scale, scale)
    if np.linalg.cond(normed) > 1e10:
        raise CalibrationError("the fit is degenerate: the widths do not determine "
                               + " and ".join(names) + " separately (fit fewer parameters "
                               "or measure more lines / a finer profile)",
                               field=",".join(names))
    cov = s2 * np.linalg.inv(normed) / np.outer(scale, scale)
    err = np.sqrt(np.diag(cov))
    for name, value, e in zip(names, values.tolist(), err.tolist(), strict=True):
        if name == "dead_time_s":
            # τ = 0 is a valid answer, so no relative test; but an error this large means
            # the widths say nothing about the delay
            if not e <= _DEAD_TIME_MAX_ERR_S:
                raise CalibrationError(f"the fit does not determine the dead time: "
                                       f"{value:.3g} ± {e:.2g} s", field=name, value=value,
                                       allowed=f"standard error <= {_DEAD_TIME_MAX_ERR_S:g} s")
            continue
        if name in ("shift_mm", "stretch"):
            continue   # nuisance parameters: 0 is a valid value
        if not e <= max_relative_error * abs(value):
            raise CalibrationError(f"the fit does not determine {name}: {value:.4g} ± "
                                   f"{e:.2g} (measure lines with larger speed steps, a finer "
                                   "profile or less scatter)", field=name, value=value,
                                   allowed=f"standard error <= {max_relative_error:g}·|value|")
    _check_curvature(names, values, err, residuals, float(np.sum(resid ** 2)), s2)
    bounds_per_line = np.cumsum([0] + [x.size for x in xs])
    line_rms = tuple(float(np.sqrt(np.mean(resid[a:b] ** 2))) if b > a else math.nan
                     for a, b in itertools.pairwise(bounds_per_line.tolist()))
    notes: list[str] = []
    if model.advance is not None:
        notes.append("firmware advance on the lines: " + ", ".join(
            f"{ln.advance_k_s:g}" for ln in model.lines) + " s")
    if not model.slip:
        notes.append("slip not modelled: a steady slip shows as a gain below 1")
    return LagFit(params=params_of(values), fitted=tuple(names),
                  stderr=dict(zip(names, err.tolist(), strict=True)), covariance=cov,
                  n_points=n, n_excluded=excluded, rms_mm=float(np.sqrt(np.mean(resid ** 2))),
                  line_rms_mm=line_rms, lines=model.lines, machine_lag_s=model.machine_lag_s,
                  registration={nm: float(v) for nm, v in zip(names, values.tolist(),
                                                               strict=True)
                                if nm in ("shift_mm", "stretch")},
                  notes=tuple(notes))
