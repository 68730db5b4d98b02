"""The twin's lag fitted to the widths of a chevron photo's bands.

A band is ``walls`` touching walls of the top layer (:mod:`.chevron_geom`). At a distance
``d`` from the band's apex along one arm, each wall ``i`` is at the point of its own path
nearest the band's centreline point ``P + d·u`` — a position ``s_i`` along the wall — and
the twin (:class:`~flowtwin.calibration.fits.lagmodel.LagModel`, [001 Eqs. 7, 10, 15]) gives
its width ``w_i(s_i)`` for a trial lag ``K`` and gain ``g``. Touching walls overlap by
``(1 − π/4)·h`` each (the slicer's line spacing), so the band is

    ``W(d) = Σ_i w_i(s_i) − (walls − 1)·(1 − π/4)·h``,

averaged over each measurement window. ``K`` and ``g`` are fitted by nonlinear least
squares (:func:`scipy.optimize.least_squares`) to all bands' widths beyond ``d0``, where
the twin's nozzle moves at least half its cruise speed on every wall (nearer the apex the
width ``Q/(h·v)`` diverges as ``v → 0``). Start: the best ``K`` of a log grid; errors:
``cov = s²·(JᵀJ)⁻¹``; refused when ``K`` ends on a bound or its standard error exceeds
half its value. The result is a :class:`~flowtwin.calibration.fits.lagfit.LagFit` (its lines
the top layer's walls, each with its band's RMS).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares

from flowtwin.calibration.fits.lagfit import LagFit
from flowtwin.calibration.fits.lagmodel import LagModel, LagParams
from flowtwin.calibration.image.chevron_geom import ChevronGeometry
from flowtwin.calibration.image.kimage import LineReading
from flowtwin.errors import CalibrationError

__all__ = ["fit_chevron_lag"]

FloatArray = npt.NDArray[np.float64]

_K_SCAN = np.geomspace(0.005, 1.0, 12)
#: Bounds of (K s, gain).
_LOWER = (1e-3, 0.2)
_UPPER = (5.0, 5.0)
_WINDOW_POINTS = 5


def _wall_positions(path: FloatArray, pts: FloatArray) -> FloatArray:
    """Position along a two-arm wall path of the nearest point to each of ``pts``."""
    best = np.full(pts.shape[0], np.inf)
    pos = np.zeros(pts.shape[0])
    start = 0.0
    for a, b in itertools.pairwise(path):
        d = b - a
        length = float(np.hypot(*d))
        t = np.clip((pts - a) @ d / (length * length), 0.0, 1.0)
        near = a + t[:, None] * d
        dist = np.hypot(*(pts - near).T)
        better = dist < best
        best = np.where(better, dist, best)
        pos = np.where(better, start + t * length, pos)
        start += length
    return pos


def fit_chevron_lag(full: LagModel, geo: ChevronGeometry, lines: Sequence[LineReading], *,
                    d0: float, step_mm: float, source: str = "<image>") -> LagFit:
    """Fit ``K`` and the gain to the bands' widths (module docstring).

    Parameters
    ----------
    full
        The twin's model of every printed run of the pattern.
    geo
        The bands (:func:`~.chevron_geom.chevron_geometry`).
    lines
        Per chevron, the measured band widths (``positions_mm``: negative along the
        upper arm, positive along the lower; :func:`~.chevron_read.analyse_chevron_photo`).
    d0, step_mm
        Nearest distance from the apex compared; width window length, mm.
    source
        For messages.

    Raises
    ------
    CalibrationError
        Too few usable widths, a lag on its bound or not determined.
    """
    model = full.subset(geo.wall_runs)
    h = geo.layer_height_mm
    overlap = (1.0 - math.pi / 4.0) * h
    offs = (np.linspace(-0.5, 0.5, _WINDOW_POINTS) * step_mm)
    # per wall: the positions to evaluate; per sample: which walls and points it sums
    wall_pts: list[list[FloatArray]] = [[] for _ in geo.wall_runs]
    samples: list[tuple[int, list[tuple[int, int, int]]]] = []   # (chevron, [(wall, block, n)])
    measured: list[float] = []
    excluded = 0
    arm = geo.arm_mm
    for j, r in enumerate(lines):
        p = geo.apex[j]
        for sign, end in ((-1.0, geo.upper[j]), (1.0, geo.lower[j])):
            u = (end - p) / np.hypot(*(end - p))
            sel = (np.sign(r.positions_mm) == sign) & (np.abs(r.positions_mm) >= d0) & (
                np.abs(r.positions_mm) <= arm - 1.0)
            d = np.abs(r.positions_mm[sel])
            w = np.asarray(r.widths_mm, dtype=np.float64)[sel]
            ok = np.isfinite(w)
            excluded += int(np.count_nonzero(~ok))
            d, w = d[ok], w[ok]
            if d.size == 0:
                continue
            dd = (d[:, None] + offs[None, :]).ravel()
            pts = p[None, :] + dd[:, None] * u[None, :]
            blocks = []
            for wi in geo.walls[j]:
                s = _wall_positions(geo.wall_paths[wi], pts)
                fast = model.usable(wi, s, end_margin_mm=0.5)
                blocks.append((wi, s, fast.reshape(-1, offs.size).all(axis=1)))
            good = np.all([b[2] for b in blocks], axis=0)
            excluded += int(np.count_nonzero(~good))
            for q in np.flatnonzero(good):
                entry = []
                for wi, s, _ in blocks:
                    entry.append((wi, len(wall_pts[wi]), offs.size))
                    wall_pts[wi].append(s[q * offs.size:(q + 1) * offs.size])
                samples.append((j, entry))
                measured.append(float(w[q]))
    n = len(measured)
    if n < 20:
        raise CalibrationError(f"only {n} band widths where the twin's nozzle cruises",
                               source=source, field="width_mm", value=n,
                               allowed=">= 20 samples beyond the apexes")
    m_arr = np.asarray(measured)
    flat = [np.concatenate(p) if p else np.zeros(0) for p in wall_pts]
    cache: dict[float, tuple[FloatArray, FloatArray]] = {}

    def predict(x: FloatArray) -> FloatArray:
        k, g = float(x[0]), float(x[1])
        if k not in cache:
            if len(cache) > 8:
                cache.pop(next(iter(cache)))
            cache[k] = model.flow_series(LagParams(k_s=k))
        ws = model.widths(LagParams(k_s=k, gain=g), flat, series=cache[k])
        per = [wv.reshape(-1, _WINDOW_POINTS).mean(axis=1) if wv.size else wv for wv in ws]
        out = np.empty(n)
        for idx, (_, entry) in enumerate(samples):
            out[idx] = sum(per[wi][blk] for wi, blk, _ in entry) - (len(entry) - 1) * overlap
        return out

    def residuals(x: FloatArray) -> FloatArray:
        return np.asarray(predict(x) - m_arr, dtype=np.float64)

    scan = [float(np.nansum(residuals(np.array([k, 1.0])) ** 2)) for k in _K_SCAN]
    x0 = np.array([float(_K_SCAN[int(np.argmin(scan))]), 1.0])
    lower, upper = list(_LOWER), list(_UPPER)
    sol = least_squares(residuals, x0, bounds=(lower, upper), x_scale=np.array([x0[0], 0.1]),
                        diff_step=np.array([1e-3, 1e-3]), xtol=1e-8, ftol=1e-10, max_nfev=100)
    k, g = (float(v) for v in sol.x)
    if k <= lower[0] * 1.001 or k >= upper[0] * 0.999:
        raise CalibrationError(f"the bands put the lag on the fit's bound ({k:.4g} s)",
                               source=source, field="k_s", value=k,
                               allowed=f"{lower[0]:g} .. {upper[0]:g} s")
    resid = residuals(sol.x)
    dof = max(n - 2, 1)
    s2 = float(resid @ resid) / dof
    jac = np.asarray(sol.jac, dtype=np.float64)
    try:
        cov = np.asarray(s2 * np.linalg.inv(jac.T @ jac), dtype=np.float64)
    except np.linalg.LinAlgError as exc:
        raise CalibrationError("the bands do not determine the lag (singular fit)",
                               source=source, field="k_s") from exc
    err = np.sqrt(np.maximum(np.diag(cov), 0.0))
    if not err[0] <= 0.5 * k:
        raise CalibrationError(f"the bands do not determine the lag: {k:.4g} ± {err[0]:.2g} s",
                               source=source, field="k_s", value=k,
                               allowed="standard error <= half the value")
    chev = np.array([c for c, _ in samples])
    band_rms = {j: float(np.sqrt(np.mean(resid[chev == j] ** 2)))
                for j in range(len(lines)) if np.any(chev == j)}
    wall_rms = tuple(band_rms.get(next(j for j, ws in enumerate(geo.walls) if wi in ws),
                                  math.nan) for wi in range(len(geo.wall_runs)))
    return LagFit(params=LagParams(k_s=k, gain=g), fitted=("k_s", "gain"),
                  stderr={"k_s": float(err[0]), "gain": float(err[1])},
                  covariance=cov, n_points=n, n_excluded=excluded,
                  rms_mm=float(np.sqrt(np.mean(resid ** 2))), line_rms_mm=wall_rms,
                  lines=model.lines, machine_lag_s=model.machine_lag_s,
                  notes=("fitted to the chevrons' bands: each the sum of its top-layer "
                         "walls' widths less their overlap",
                         "slip not modelled: a steady slip shows as a gain below 1"))
