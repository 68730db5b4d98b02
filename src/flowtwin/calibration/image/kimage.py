"""The advance factor from an image of a printed K-factor pattern.

``analyse_kline_image`` reads a flatbed scan or a photo of the K-line pattern [001
Fig. 10] (:func:`~flowtwin.calibration.patterns.kline.kline_pattern`), finds and registers its lines
(:mod:`~flowtwin.calibration.image.linefind`), measures the bead width along every K-line, scores
each line and fits the lag:

* **Widths.** Each line is resampled on the bed's own coordinates through the homography
  (:mod:`~flowtwin.calibration.image.beadwidth`: the strip is in mm, so rotation, scale and
  perspective are gone) and the width of every ``step_mm`` along it measured from the
  bead's integrated darkness (blur-invariant; default) or from the extrema of the first
  derivative across the bead ([003 §2.2]). A stretch where the bead is missing (a gap) has
  no width. ``mm_per_px`` — the scan's resolution, 25.4/dpi — replaces the pattern's own
  scale across the lines when given.
* **Scores** (how Tronvoll et al. read the pattern by eye [001 Fig. 14, Table II], made
  quantitative). The width relative to the line's steady width ``r = w/w_steady`` (a gap
  counts as ``r = 0``) is averaged over 8 mm (at most half the next segment) after each
  speed change: after a step up, a too-low K under-extrudes (``r < 1``), after a step
  down it over-extrudes. The signed *acceleration error* ``e_acc = mean(r − 1)`` after
  steps up and *deceleration error* ``e_dec = −mean(r − 1)`` after steps down both grow
  with the line's K; the score is the RMS of ``r − 1`` in those windows, the best line the
  one with the lowest score, and ``K_acc``/``K_dec`` the zero crossings of ``e_acc`` and
  ``e_dec`` between neighbouring lines (linear interpolation) — the two columns of [001
  Table II].
* **Lag fit.** All lines' width profiles together are fitted with the twin
  (:func:`~flowtwin.calibration.fits.lagfit.fit_lag`): one lag ``K`` for the printer, each line
  predicted with the advance factor it was printed with, a free flow gain (which also
  absorbs a scale error of the widths) and a free shift and stretch of the positions
  along the lines (the registration takes the line ends from the beads' ends, which the
  lag itself moves by a few tenths of a millimetre: the flow starts late or with a blob).
  Lines with gaps are left out of this fit (the bead model is ill-defined where the
  nozzle runs empty [001 Fig. 12]). That ``K`` is the advance factor to set [001 Eqs. 11,
  15], with its standard error.

Nothing is invented: an unreadable or blank image, no lines, a line count or tick layout
that does not match the pattern, or too few measurable widths raise
:class:`~flowtwin.errors.VisionError` / :class:`~flowtwin.errors.CalibrationError`.
"""

from __future__ import annotations

import itertools
import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from flowtwin.calibration.fits.kfit import machine_for_pattern
from flowtwin.calibration.fits.lagfit import LagFit, WidthProfile, fit_lag
from flowtwin.calibration.fits.lagmodel import (
    LagModel,
    TestLine,
    lag_model,
    printed_runs,
)
from flowtwin.calibration.image.beadwidth import (
    area_widths,
    dark_level,
    edge_widths,
    sample_strip,
    window_widths,
)
from flowtwin.calibration.image.linefind import (
    Registration,
    find_lines,
    local_scale,
    register_pattern,
)
from flowtwin.calibration.patterns.pattern import Pattern
from flowtwin.errors import CalibrationError, VisionError
from flowtwin.profiles.machine import Machine
from flowtwin.vision.loader import load_grey

__all__ = ["KLineImageResult", "LineReading", "analyse_kline_image", "load_grey",
           "score_line"]

FloatArray = npt.NDArray[np.float64]

#: Length of the window after a speed change that is scored, mm (at most half the next
#: segment): at 70 mm/s it spans 0.11 s, about two lags of a direct drive.
_TRANSITION_MM = 8.0
#: Part of each segment, at its end, taken as steady.
_STEADY_FRACTION = 0.3
#: Fewest measured widths along a line, as a fraction of its samples, for a usable line.
_MIN_MEASURED = 0.5
#: Lines in the lag fit: measured along this fraction of their length (no gaps: where the
#: nozzle ran empty the bead model is ill-defined [001 Fig. 12] and the width unknown).
_FIT_MEASURED = 0.98


@dataclass(frozen=True)
class LineReading:
    """What one K-line shows.

    Attributes
    ----------
    k_la_s
        Advance factor the line was printed with, s.
    positions_mm, widths_mm
        Sample positions along the line and measured widths (NaN: no bead edges), mm.
    steady_width_mm
        Median width in the steady parts of the segments, mm.
    score
        RMS of ``w/w_steady − 1`` after the speed changes (0: even).
    accel_error, decel_error
        Signed mean deviation after steps up / down (negative: K too low).
    measured_fraction
        Fraction of the samples with a width.
    """

    k_la_s: float
    positions_mm: FloatArray
    widths_mm: FloatArray
    steady_width_mm: float
    score: float
    accel_error: float
    decel_error: float
    measured_fraction: float


def score_line(line: TestLine, positions_mm: FloatArray, widths_mm: FloatArray
               ) -> tuple[float, float, float, float]:
    """Steady width, score, acceleration and deceleration error of one line.

    Parameters
    ----------
    line
        The test line (speed changes from its planned cruise speeds).
    positions_mm, widths_mm
        Samples along it (NaN width: no bead there), mm.

    Returns
    -------
    tuple
        ``(w_steady mm, score, e_acc, e_dec)`` (module docstring); NaN where a quantity
        has no samples (e.g. ``e_dec`` of a line without a step down).
    """
    cum = line.cum_length_mm
    x, w = positions_mm, widths_mm
    steady = np.zeros(x.shape, dtype=bool)
    for a, b in itertools.pairwise(cum.tolist()):
        steady |= (x >= b - _STEADY_FRACTION * (b - a)) & (x < b)
    ref = float(np.nanmedian(w[steady])) if np.any(np.isfinite(w[steady])) else math.nan
    if not (ref > 0.0):
        return math.nan, math.nan, math.nan, math.nan
    r = np.where(np.isfinite(w), w / ref, 0.0)
    dev_all: list[FloatArray] = []
    acc: list[float] = []
    dec: list[float] = []
    v = line.cruise_mm_s
    for j in range(1, cum.size - 1):
        c = cum[j]
        span = min(_TRANSITION_MM, 0.5 * (cum[j + 1] - c))
        sel = (x >= c) & (x < c + span)
        if not np.any(sel):
            continue
        dev = r[sel] - 1.0
        dev_all.append(dev)
        if v[j] > v[j - 1]:
            acc.append(float(np.mean(dev)))
        elif v[j] < v[j - 1]:
            dec.append(-float(np.mean(dev)))
    if not dev_all:
        return ref, math.nan, math.nan, math.nan
    score = float(np.sqrt(np.mean(np.concatenate(dev_all) ** 2)))
    return (ref, score, float(np.mean(acc)) if acc else math.nan,
            float(np.mean(dec)) if dec else math.nan)


def _zero_crossing(k: FloatArray, e: FloatArray, near: float) -> float | None:
    """K where ``e`` (growing with K) crosses zero, nearest to ``near``; ``None`` if never."""
    ok = np.isfinite(e)
    k, e = k[ok], e[ok]
    found: list[float] = []
    for i in range(k.size - 1):
        if e[i] <= 0.0 < e[i + 1]:
            found.append(float(k[i] + (k[i + 1] - k[i]) * (-e[i]) / (e[i + 1] - e[i])))
    if not found:
        return None
    return min(found, key=lambda kk: abs(kk - near))


@dataclass(frozen=True)
class KLineImageResult:
    """Reading of a K-line pattern image.

    Attributes
    ----------
    source
        Image name.
    lines
        One reading per K-line, in pattern order.
    best_index
        Index of the most even line.
    k_accel_s, k_decel_s
        Zero crossings of the acceleration and deceleration errors, s (``None``: outside
        the tested range).
    lag
        The twin's lag fitted to all lines (``None`` if the fit failed: ``lag_problem``).
    lag_problem
        Why there is no lag fit.
    view
        ``"top"`` or ``"mirrored"``.
    prime_seen
        The prime line was found.
    px_per_mm
        Image scale at the pattern's centre, px/mm.
    reprojection_rms_mm
        How well the line ends fit the pattern's geometry, mm.
    homography
        Bed (mm) → image (px), 3 × 3.
    notes
        Facts worth knowing.
    """

    source: str
    lines: tuple[LineReading, ...]
    best_index: int
    k_accel_s: float | None
    k_decel_s: float | None
    lag: LagFit | None
    lag_problem: str | None
    view: str
    prime_seen: bool
    px_per_mm: float
    reprojection_rms_mm: float
    homography: FloatArray
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def k_best_line_s(self) -> float:
        """Advance factor of the most even line, s."""
        return self.lines[self.best_index].k_la_s

    def summary(self) -> dict[str, Any]:
        """Plain JSON-able description."""
        return {
            "image": self.source,
            "k_best_line_s": self.k_best_line_s, "k_accel_s": self.k_accel_s,
            "k_decel_s": self.k_decel_s,
            "lag": None if self.lag is None else self.lag.summary(),
            "lag_problem": self.lag_problem,
            "view": self.view, "prime_line_seen": self.prime_seen,
            "px_per_mm": self.px_per_mm, "reprojection_rms_mm": self.reprojection_rms_mm,
            "lines": [{"k_s": r.k_la_s, "score": _num(r.score),
                       "accel_error": _num(r.accel_error), "decel_error": _num(r.decel_error),
                       "steady_width_mm": _num(r.steady_width_mm),
                       "measured_fraction": r.measured_fraction} for r in self.lines],
            "notes": list(self.notes),
        }


def _num(x: float) -> float | None:
    return x if math.isfinite(x) else None


def _read_lines(gray32: npt.NDArray[np.float32], reg: Registration, model: LagModel, *,
                pitch: float, step_mm: float, method: str, mm_per_px: float | None
                ) -> list[LineReading]:
    """Width profile and scores of every K-line under one registration."""
    half_span = min(0.4 * abs(pitch), 3.0)
    strips = [sample_strip(gray32, reg.homography, ln.vertices_xy_mm[0],
                           ln.vertices_xy_mm[-1], step_mm=step_mm, half_span_mm=half_span,
                           dv_mm=0.5 / reg.px_per_mm) for ln in model.lines]
    dark = dark_level(strips) if method == "area" else math.nan
    readings: list[LineReading] = []
    for line, strip in zip(model.lines, strips, strict=True):
        cols = area_widths(strip, dark) if method == "area" else edge_widths(strip)
        if mm_per_px is not None:
            mid = 0.5 * (line.vertices_xy_mm[0] + line.vertices_xy_mm[-1])
            cols = cols * (mm_per_px * local_scale(reg.homography, mid))
        wid = window_widths(cols, strip.per, min_width_mm=0.5 * line.layer_height_mm)
        pos = strip.positions_mm
        ref, score, e_acc, e_dec = score_line(line, pos, wid)
        readings.append(LineReading(line.advance_k_s, pos, wid, ref, score, e_acc, e_dec,
                                    float(np.mean(np.isfinite(wid)))))
    return readings


def _trend(readings: list[LineReading]) -> float:
    """Rank correlation of the acceleration/deceleration errors with the lines' K, mean."""
    k = np.array([r.k_la_s for r in readings])
    out = []
    for e in (np.array([r.accel_error for r in readings]),
              np.array([r.decel_error for r in readings])):
        ok = np.isfinite(e)
        if np.count_nonzero(ok) >= 3:
            rk = np.argsort(np.argsort(k[ok])).astype(float)
            re = np.argsort(np.argsort(e[ok])).astype(float)
            out.append(float(np.corrcoef(rk, re)[0, 1]))
    return float(np.mean(out)) if out else math.nan


def _by_trend(regs: list[Registration], readings_of: list[list[LineReading]],
              name: str) -> int:
    """The reading whose errors grow with K (physics: a too-low K under-extrudes after a
    step up, over-extrudes after a step down [001 Fig. 2]) when the ticks cannot tell."""
    trends = [_trend(r) for r in readings_of]
    good = [i for i, t in enumerate(trends) if t > 0.5]
    if len(good) == 1 and all(not t > 0.0 for i, t in enumerate(trends) if i != good[0]):
        return good[0]
    raise VisionError("the image does not show whether it is seen from above or mirrored "
                      "(scanned face down), and the widths do not decide it",
                      source=name, field="view",
                      value={r.view: round(t, 2) for r, t in zip(regs, trends, strict=True)},
                      allowed="view top or mirrored")


def analyse_kline_image(image: str | os.PathLike[str] | npt.NDArray[Any], pattern: Pattern, *,
                        machine: Machine | str | os.PathLike[str] | None = None,
                        mm_per_px: float | None = None, view: str = "auto",
                        step_mm: float = 0.25, method: str = "area", fit: bool = True,
                        fit_dead_time: bool = False, fit_gain: bool = True,
                        end_margin_mm: float = 1.0) -> KLineImageResult:
    """Read a K-line pattern image: widths along each line, scores, the fitted lag.

    Parameters
    ----------
    image
        Image file (PNG, JPEG, TIFF…) or array (grey or BGR).
    pattern
        The K-line pattern as printed (:func:`~flowtwin.calibration.patterns.catalog.
        generate_pattern` with the same settings and parameters).
    machine
        Set-up for the twin (planner, column): default the lag model's.
    mm_per_px
        Image resolution across the lines, mm/px (a scan: 25.4/dpi); default: the
        pattern's own scale from its line length and pitch.
    view
        ``"auto"``, ``"top"`` or ``"mirrored"`` (scanned face down).
    step_mm
        Spacing of the width samples along the lines, mm.
    method
        ``"area"`` (integrated darkness; blur-invariant) or ``"edges"`` (derivative
        extrema [003 §2.2]); see :mod:`~flowtwin.calibration.image.beadwidth`.
    fit
        Fit the twin's lag to all lines.
    fit_dead_time, fit_gain
        Also fit a dead time / a flow gain (the gain also absorbs an image scale error).
    end_margin_mm
        Samples this close to a line's ends are left out of the lag fit.

    Returns
    -------
    KLineImageResult

    Raises
    ------
    VisionError
        Unreadable or blank image, no lines, lines that do not match the pattern.
    CalibrationError
        Not a K-line pattern, bad options, too few measurable widths.
    """
    if pattern.kind != "kline":
        raise CalibrationError("from-image reads K-line patterns", field="pattern",
                               value=pattern.kind, allowed="kline")
    if mm_per_px is not None and not (0.0 < mm_per_px < 10.0):
        raise CalibrationError("image resolution out of range", field="mm_per_px",
                               value=mm_per_px, allowed="0 < mm/px < 10 (25.4/dpi)")
    if method not in ("area", "edges"):
        raise CalibrationError("unknown width measurement", field="method", value=method,
                               allowed="area, edges")
    if not (0.05 <= step_mm <= 5.0):
        raise CalibrationError("sample step out of range", field="step_mm", value=step_mm,
                               allowed="0.05 .. 5 mm")
    m = machine_for_pattern(pattern, machine)
    gray, name = load_grey(image)
    firsts = [next(s.line for s in pattern.segments if s.group == g)
              for g in range(len(pattern.values))]
    full = lag_model(pattern.text().encode(), None, machine=m)
    runs = printed_runs(full.plan)
    k_index = [runs.index(f) for f in firsts]
    model: LagModel = full.subset(k_index)
    prime_i = runs.index(firsts[0]) - 1
    prime_line = full.lines[prime_i] if prime_i >= 0 else None
    starts = np.array([ln.vertices_xy_mm[0] for ln in model.lines])
    ends = np.array([ln.vertices_xy_mm[-1] for ln in model.lines])
    found, direction = find_lines(gray, line_length_mm=float(np.median(
        np.hypot(*(ends - starts).T))), source=name)
    k_runs = set(k_index)
    ticks = [r + 1 < len(runs) and r + 1 not in k_runs for r in k_index]
    prime = None if prime_line is None else (prime_line.vertices_xy_mm[0],
                                             prime_line.vertices_xy_mm[-1])
    regs = register_pattern(found, direction, starts_mm=starts, ends_mm=ends,
                            prime_mm=prime, ticks=ticks, view=view, source=name)
    pitch = float(np.median(np.diff(starts[:, 1]))) if len(starts) > 1 else 5.0
    gray32 = gray.astype(np.float32)
    readings_of = [_read_lines(gray32, reg, model, pitch=pitch, step_mm=step_mm,
                               method=method, mm_per_px=mm_per_px) for reg in regs]
    choice = 0
    if len(regs) > 1:
        choice = _by_trend(regs, readings_of, name)
    reg, readings = regs[choice], readings_of[choice]
    profiles = [WidthProfile(r.positions_mm, r.widths_mm, name, window_mm=step_mm)
                for r in readings]
    usable = [i for i, r in enumerate(readings) if r.measured_fraction >= _MIN_MEASURED
              and math.isfinite(r.score)]
    whole = [i for i in usable if readings[i].measured_fraction >= _FIT_MEASURED]
    if not usable:
        raise VisionError("no line could be measured along its length", source=name,
                          allowed="a sharp image with at least ~4 px across a bead")
    best = min(usable, key=lambda i: readings[i].score)
    ks = np.array([r.k_la_s for r in readings])
    k_acc = _zero_crossing(ks, np.array([r.accel_error for r in readings]), ks[best])
    k_dec = _zero_crossing(ks, np.array([r.decel_error for r in readings]), ks[best])
    notes = [f"{len(readings)} K-lines from {ks[0]:g} to {ks[-1]:g} s; view {reg.view}"
             + ("" if reg.prime_seen else " (prime line not seen)")]
    if len(usable) < len(readings):
        notes.append(f"{len(readings) - len(usable)} line(s) with widths on fewer than "
                     f"{_MIN_MEASURED:.0%} of their length")
    lag: LagFit | None = None
    problem: str | None = None
    if fit:
        try:
            lag = fit_lag(model.subset(whole), [profiles[i] for i in whole],
                          fit_dead_time=fit_dead_time, fit_gain=fit_gain,
                          fit_registration=True, end_margin_mm=end_margin_mm)
        except CalibrationError as exc:
            problem = exc.message
    return KLineImageResult(source=name, lines=tuple(readings), best_index=best,
                            k_accel_s=k_acc, k_decel_s=k_dec, lag=lag, lag_problem=problem,
                            view=reg.view, prime_seen=reg.prime_seen,
                            px_per_mm=reg.px_per_mm,
                            reprojection_rms_mm=reg.reprojection_rms_mm,
                            homography=reg.homography, notes=tuple(notes))
