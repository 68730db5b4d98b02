"""K from a photo of a printed line pattern: lines, widths, scores and the twin's lag.

:func:`analyse_line_photo` runs, in order: the bead signal and the lines
(:mod:`.detect`, polarity from the image), the refusals that need only the lines
(:mod:`.quality`: too few, cut by the frame), the registration without ticks
(:mod:`.register`), the widths along every test line on the bed grid
(:mod:`flowtwin.calibration.image.beadwidth`; light beads are measured on the inverted image,
so the integrated "darkness" is the bead's contrast either way), the blur refusal, the
per-line scores (:func:`flowtwin.calibration.image.kimage.score_line`, [001 Fig. 14, Table II]
made quantitative) and the lag fitted with the twin to all gap-free lines
(:func:`flowtwin.calibration.fits.lagfit.fit_lag`, free gain and registration along the lines).

When the layout's marks do not tell which way the photo is turned, the widths do: in the
right reading the acceleration and deceleration errors grow with the lines' K (a too-low
K under-extrudes after a step up [001 Fig. 2]); when they do not decide either, the
analysis refuses and asks for ``view``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from flowtwin.calibration.fits.kfit import pattern_firmware
from flowtwin.calibration.fits.lagfit import LagFit, WidthProfile, fit_lag
from flowtwin.calibration.fits.lagmodel import DEFAULT_MACHINE, LagModel, lag_model, printed_runs
from flowtwin.calibration.image.beadwidth import (
    area_widths,
    dark_level,
    edge_widths,
    sample_strip,
    window_widths,
)
from flowtwin.calibration.image.detect import LineSet, detect_lines
from flowtwin.calibration.image.kimage import LineReading, load_grey, score_line
from flowtwin.calibration.image.quality import MIN_LINES, blur_reason
from flowtwin.calibration.image.register import LayoutGeometry, Reading, register_layout
from flowtwin.calibration.patterns.pattern import Pattern
from flowtwin.errors import CalibrationError, VisionError
from flowtwin.profiles.machine import Machine, load_machine

__all__ = ["PhotoResult", "analyse_line_photo", "layout_geometry"]

FloatArray = npt.NDArray[np.float64]

_MIN_MEASURED = 0.5
_FIT_MEASURED = 0.98


@dataclass(frozen=True)
class PhotoResult:
    """What a photo of a line pattern shows.

    Attributes
    ----------
    source, pattern
        Image name and layout name.
    lines
        One reading per test line, front to back.
    best_index
        The most even line.
    k_accel_s, k_decel_s
        Zero crossings of the acceleration / deceleration errors [001 Table II], s.
    lag, lag_problem
        The twin's lag fitted to the gap-free lines, or why there is none.
    light_beads
        Beads lighter than the sheet (decided from the image unless given).
    reading
        How the found lines were matched (and what decided it).
    px_per_mm, reprojection_rms_mm
        Image scale at the pattern's centre; fit of the line ends to the layout.
    homography
        Bed (mm) → image (px).
    image_lines
        Each test line's ends in the image, px, shape ``(n, 2, 2)``.
    notes
        Facts worth knowing.
    """

    source: str
    pattern: str
    lines: tuple[LineReading, ...]
    best_index: int
    k_accel_s: float | None
    k_decel_s: float | None
    lag: LagFit | None
    lag_problem: str | None
    light_beads: bool
    reading: str
    px_per_mm: float
    reprojection_rms_mm: float
    homography: FloatArray
    image_lines: FloatArray
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def k_best_line_s(self) -> float:
        """Advance factor of the most even line, s."""
        return self.lines[self.best_index].k_la_s

    def summary(self) -> dict[str, Any]:
        """Plain JSON-able description (``k_s``: the fitted lag, or ``None``)."""
        return {
            "image": self.source, "pattern": self.pattern,
            "k_s": None if self.lag is None else self.lag.k_s,
            "k_err_s": None if self.lag is None else self.lag.k_err_s,
            "k_best_line_s": self.k_best_line_s, "k_accel_s": self.k_accel_s,
            "k_decel_s": self.k_decel_s,
            "lag": None if self.lag is None else self.lag.summary(),
            "lag_problem": self.lag_problem,
            "beads": "light" if self.light_beads else "dark", "reading": self.reading,
            "px_per_mm": self.px_per_mm, "reprojection_rms_mm": self.reprojection_rms_mm,
            "lines": [{"k_s": r.k_la_s, "score": _num(r.score),
                       "accel_error": _num(r.accel_error), "decel_error": _num(r.decel_error),
                       "steady_width_mm": _num(r.steady_width_mm),
                       "measured_fraction": r.measured_fraction} for r in self.lines],
            "notes": list(self.notes),
        }


def _num(x: float) -> float | None:
    return x if math.isfinite(x) else None


def layout_geometry(pattern: Pattern, full: LagModel) -> tuple[LayoutGeometry, list[int]]:
    """The layout's lines and marks from its planned G-code; and the test lines' run indices."""
    runs = printed_runs(full.plan)
    firsts = [next(s.line for s in pattern.segments if s.group == g)
              for g in range(len(pattern.values))]
    k_index = [runs.index(f) for f in firsts]
    starts = np.array([full.lines[i].vertices_xy_mm[0] for i in k_index])
    ends = np.array([full.lines[i].vertices_xy_mm[-1] for i in k_index])
    d = ends[0] - starts[0]
    length = float(np.hypot(*d))
    u = d / length
    across = np.array([-u[1], u[0]])
    par: list[tuple[FloatArray, FloatArray, int]] = []
    marks: list[FloatArray] = []
    for r, ln in enumerate(full.lines):
        if r in k_index:
            par.append((ln.vertices_xy_mm[0], ln.vertices_xy_mm[-1], k_index.index(r)))
            continue
        v = np.asarray(ln.vertices_xy_mm, dtype=np.float64)
        seg = v[-1] - v[0]
        seg_len = float(np.hypot(*seg))
        if (v.shape[0] == 2 and seg_len >= 0.5 * length
                and abs(float(seg @ u)) >= 0.99 * seg_len):
            a, b = (v[0], v[-1]) if float(seg @ u) > 0 else (v[-1], v[0])
            par.append((a, b, -1))
        else:
            marks.append(v)
    par.sort(key=lambda p: float(0.5 * (p[0] + p[1]) @ across))
    return LayoutGeometry(starts, ends, tuple(par), tuple(marks)), k_index


def _read(gray_dark32: npt.NDArray[np.float32], reading: Reading, model: LagModel, *,
          pitch_mm: float, step_mm: float, method: str, mm_per_px: float | None
          ) -> tuple[list[LineReading], FloatArray, float]:
    """Widths and scores of every test line; the mean bead profile across and its spacing."""
    half = min(0.4 * pitch_mm, 3.0)
    dv = 0.5 / reading.px_per_mm
    strips = [sample_strip(gray_dark32, reading.homography, ln.vertices_xy_mm[0],
                           ln.vertices_xy_mm[-1], step_mm=step_mm, half_span_mm=half,
                           dv_mm=dv) for ln in model.lines]
    dark = dark_level(strips) if method == "area" else math.nan
    out: list[LineReading] = []
    profiles = []
    for line, strip in zip(model.lines, strips, strict=True):
        cols = area_widths(strip, dark) if method == "area" else edge_widths(strip)
        if mm_per_px is not None:
            from flowtwin.calibration.image.register import local_scale
            mid = 0.5 * (line.vertices_xy_mm[0] + line.vertices_xy_mm[-1])
            cols = cols * (mm_per_px * local_scale(reading.homography, mid))
        wid = window_widths(cols, strip.per, min_width_mm=0.5 * line.layer_height_mm)
        ref, score, e_acc, e_dec = score_line(line, strip.positions_mm, wid)
        out.append(LineReading(line.advance_k_s, strip.positions_mm, wid, ref, score, e_acc,
                               e_dec, float(np.mean(np.isfinite(wid)))))
        q = max(2, strip.values.shape[0] // 5)
        bg = np.median(np.vstack([strip.values[:q], strip.values[-q:]]), axis=0)
        profiles.append(np.median(bg[None, :] - strip.values, axis=1))
    return out, np.median(np.vstack(profiles), axis=0), dv


def _trend(readings: list[LineReading]) -> float:
    """Mean rank correlation of the acceleration and deceleration errors with K."""
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


def _zero_crossing(k: FloatArray, e: FloatArray, near: float) -> float | None:
    ok = np.isfinite(e)
    k, e = k[ok], e[ok]
    found = [float(k[i] + (k[i + 1] - k[i]) * (-e[i]) / (e[i + 1] - e[i]))
             for i in range(k.size - 1) if e[i] <= 0.0 < e[i + 1]]
    return min(found, key=lambda kk: abs(kk - near)) if found else None


def analyse_line_photo(image: str | os.PathLike[str] | npt.NDArray[Any], pattern: Pattern, *,
                       machine: Machine | str | os.PathLike[str] | None = None,
                       mm_per_px: float | None = None, polarity: str = "auto",
                       view: str = "auto", step_mm: float = 0.25, method: str = "area",
                       fit: bool = True, fit_dead_time: bool = False, fit_gain: bool = True,
                       end_margin_mm: float = 1.0) -> PhotoResult:
    """Read a photo or scan of a printed line pattern (module docstring).

    Parameters
    ----------
    image
        Image file or array (grey or BGR).
    pattern
        The pattern as printed (:func:`~.layouts.line_layout_pattern` or
        :func:`flowtwin.calibration.patterns.kline.kline_pattern`), for the machine's firmware.
    machine
        Set-up for the twin.
    mm_per_px
        Image resolution across the lines (a scan: 25.4/dpi); default the pattern's own
        scale (line length and pitch).
    polarity
        ``"auto"``, ``"light"`` or ``"dark"`` beads.
    view
        ``"auto"``, ``"top"`` or ``"mirrored"`` (scanned face down).
    step_mm, method
        Width sample spacing along the lines; ``"area"`` or ``"edges"``.
    fit, fit_dead_time, fit_gain, end_margin_mm
        The lag fit (see :func:`flowtwin.calibration.fits.lagfit.fit_lag`).

    Returns
    -------
    PhotoResult

    Raises
    ------
    VisionError
        The photo cannot support an answer (blank, too few lines, lines cut by the frame,
        blur, a line count or geometry that does not match, a reading neither the marks
        nor the widths decide).
    CalibrationError
        Bad options, or a pattern for another firmware than the machine's.
    """
    if mm_per_px is not None and not (0.0 < mm_per_px < 10.0):
        raise CalibrationError("image resolution out of range", field="mm_per_px",
                               value=mm_per_px, allowed="0 < mm/px < 10 (25.4/dpi)")
    if method not in ("area", "edges"):
        raise CalibrationError("unknown width measurement", field="method", value=method,
                               allowed="area, edges")
    if not (0.05 <= step_mm <= 5.0):
        raise CalibrationError("sample step out of range", field="step_mm", value=step_mm,
                               allowed="0.05 .. 5 mm")
    m = machine if isinstance(machine, Machine) else load_machine(machine or DEFAULT_MACHINE)
    if pattern.settings.firmware is not pattern_firmware(m):
        raise CalibrationError("the pattern is written for another firmware than the "
                               "machine's printer: its advance commands would be ignored",
                               field="firmware", value=pattern.settings.firmware.value,
                               allowed=f"{pattern_firmware(m).value} (printer "
                                       f"{m.printer.name})")
    gray, name = load_grey(image)
    full = lag_model(pattern.text().encode(), None, machine=m)
    geo, k_index = layout_geometry(pattern, full)
    model = full.subset(k_index)
    n = len(k_index)
    ls: LineSet = detect_lines(gray, polarity=polarity, source=name)
    if len(ls.lines) < min(MIN_LINES, n):
        raise VisionError("too few lines found to compare", source=name,
                          value=f"{len(ls.lines)} line(s)",
                          allowed=f"at least {MIN_LINES} lines of the pattern in view")
    cut = [i for i, f in enumerate(ls.lines) if f.cut]
    if cut:
        raise VisionError("lines are cut by the edge of the photo", source=name,
                          value=f"{len(cut)} of {len(ls.lines)} lines",
                          allowed="the whole pattern in the frame, with a margin")
    readings = register_layout(ls, geo, view=view, source=name)
    pitch_mm = float(np.median(np.hypot(*np.diff(geo.starts, axis=0).T))) if n > 1 else 5.0
    g32 = (255.0 - gray.astype(np.float32)) if ls.light else gray.astype(np.float32)
    g32 = np.asarray(g32, dtype=np.float32)
    read = [_read(g32, r, model, pitch_mm=pitch_mm, step_mm=step_mm, method=method,
                  mm_per_px=mm_per_px) for r in readings]
    choice = 0
    how = "the pattern's marks" if geo.marks else "the only reading"
    if len(readings) > 1:
        trends = [_trend(r[0]) for r in read]
        good = [i for i, t in enumerate(trends) if t > 0.5]
        if len(good) != 1 or any(t > 0.0 for i, t in enumerate(trends) if i != good[0]):
            raise VisionError("the photo does not show which way the pattern lies (its marks "
                              "are not seen or read the same both ways, and the widths do "
                              "not decide)", source=name, field="view",
                              value={r.name: round(t, 2)
                                     for r, t in zip(readings, trends, strict=True)},
                              allowed="view top or mirrored, or a photo showing the "
                                      "pattern's marks (prime line, numbers)")
        choice = good[0]
        how = "the widths (errors growing with K)"
    reading = readings[choice]
    lines, profile, dv = read[choice]
    reason = blur_reason(profile, dv, reading.px_per_mm)
    if reason is not None:
        raise VisionError(reason, source=name, field="image")
    usable = [i for i, r in enumerate(lines)
              if r.measured_fraction >= _MIN_MEASURED and math.isfinite(r.score)]
    if len(usable) < min(MIN_LINES, n):
        raise VisionError("too few lines could be measured along their length", source=name,
                          value=f"{len(usable)} of {n}",
                          allowed=f"at least {MIN_LINES} lines with beads along their length")
    best = min(usable, key=lambda i: lines[i].score)
    ks = np.array([r.k_la_s for r in lines])
    k_acc = _zero_crossing(ks, np.array([r.accel_error for r in lines]), ks[best])
    k_dec = _zero_crossing(ks, np.array([r.decel_error for r in lines]), ks[best])
    notes = [f"{n} test lines, K {ks[0]:g} to {ks[-1]:g} s; beads "
             f"{'lighter' if ls.light else 'darker'} than the sheet; reading "
             f"{reading.name}, decided by {how}"]
    if len(usable) < n:
        notes.append(f"{n - len(usable)} line(s) with widths on fewer than "
                     f"{_MIN_MEASURED:.0%} of their length")
    lag: LagFit | None = None
    problem: str | None = None
    if fit:
        whole = [i for i in usable if lines[i].measured_fraction >= _FIT_MEASURED]
        profiles = [WidthProfile(lines[i].positions_mm, lines[i].widths_mm, name,
                                 window_mm=step_mm) for i in whole]
        try:
            lag = fit_lag(model.subset(whole), profiles, fit_dead_time=fit_dead_time,
                          fit_gain=fit_gain, fit_registration=True,
                          end_margin_mm=end_margin_mm)
        except CalibrationError as exc:
            problem = exc.message
    ends = np.array([[ln.start_px, ln.end_px] for ln in reading.lines])
    return PhotoResult(name, pattern.kind, tuple(lines), best, k_acc, k_dec, lag, problem,
                       ls.light, f"{reading.name} (decided by {how})", reading.px_per_mm,
                       reading.reprojection_rms_mm, reading.homography, ends, tuple(notes))
