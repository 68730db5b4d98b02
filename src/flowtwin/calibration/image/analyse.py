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

When the layout's marks do not tell which way the photo is turned, the widths do: the
twin explains them clearly better in the right reading (:mod:`.direction`); when they do
not decide either, the analysis refuses and asks for ``view``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from flowtwin.calibration.fits.kfit import machine_for_pattern
from flowtwin.calibration.fits.lagfit import LagFit, WidthProfile, fit_lag
from flowtwin.calibration.fits.lagmodel import LagModel, lag_model
from flowtwin.calibration.image.beadwidth import (
    Strip,
    area_widths,
    dark_level,
    edge_widths,
    sample_strip,
    window_widths,
)
from flowtwin.calibration.image.bestline import best_line, zero_crossing
from flowtwin.calibration.image.detect import LineSet, detect_lines
from flowtwin.calibration.image.direction import choose_by_twin
from flowtwin.calibration.image.geometry import LayoutGeometry, layout_geometry
from flowtwin.calibration.image.kimage import LineReading, load_grey, score_line
from flowtwin.calibration.image.quality import MIN_LINES, answer_reason, blur_reason
from flowtwin.calibration.image.register import Reading, local_scale, register_layout
from flowtwin.calibration.image.scale import homography_to_photo, scale_note, working_copy
from flowtwin.calibration.image.widths import (
    band_half_mm,
    bead_contrast,
    contrast_strip,
    contrast_widths,
)
from flowtwin.calibration.patterns.pattern import Pattern
from flowtwin.errors import CalibrationError, VisionError
from flowtwin.profiles.machine import Machine

__all__ = ["PhotoResult", "analyse_line_photo"]

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
    k_cross_s
        Zero crossing of the Theil–Sen line through all lines' signed errors, s
        (:mod:`.bestline`; ``None``: the errors do not rise with K).
    best_by
        How the best line was chosen: ``"errors"`` (nearest the crossing) or ``"score"``.
    disagreement
        ``|K_best − K_lag|`` over their combined uncertainty
        (:func:`~.quality.disagreement`; NaN: no lag, or not commensurable).
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
    k_cross_s: float | None = None
    best_by: str = "score"
    disagreement: float = math.nan

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
            "k_best_line_s": self.k_best_line_s, "best_by": self.best_by,
            "k_cross_s": self.k_cross_s, "k_accel_s": self.k_accel_s,
            "k_decel_s": self.k_decel_s,
            "lag": None if self.lag is None else self.lag.summary(),
            "lag_problem": self.lag_problem, "disagreement": _num(self.disagreement),
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



def _read(gray32: npt.NDArray[np.float32], light: bool, reading: Reading, model: LagModel, *,
          pitch_mm: float, line_width_mm: float, step_mm: float, method: str,
          mm_per_px: float | None) -> tuple[list[LineReading], FloatArray, float]:
    """Widths and scores of every test line; the mean bead contrast across and its spacing.

    ``"area"``: the contrast relative to the local sheet integrated over the bead's band
    (:mod:`.widths`); ``"area-global"``: the integrated darkness with one bead level for
    the photo and the sheet from the strip's outer fifths
    (:func:`flowtwin.calibration.image.beadwidth.area_widths`, beads made dark; worse on the
    independent renderer, docs/calibration.md); ``"edges"``: the bead's edges
    (:func:`flowtwin.calibration.image.beadwidth.edge_widths`, beads made dark).
    """
    dv = 0.5 / reading.px_per_mm
    band = band_half_mm(line_width_mm, pitch_mm)
    half = 0.5 * pitch_mm
    strips = [contrast_strip(gray32, reading.homography, ln.vertices_xy_mm[0],
                             ln.vertices_xy_mm[-1], light=light, step_mm=step_mm,
                             band_mm=band, half_span_mm=half, dv_mm=dv) for ln in model.lines]
    bead = bead_contrast(strips) if method == "area" else math.nan
    dark_strips: list[Strip] = []
    dark = math.nan
    if method == "area-global":
        g_dark = np.asarray(255.0 - gray32 if light else gray32, dtype=np.float32)
        dark_strips = [sample_strip(g_dark, reading.homography, ln.vertices_xy_mm[0],
                                    ln.vertices_xy_mm[-1], step_mm=step_mm,
                                    half_span_mm=min(0.4 * pitch_mm, 3.0), dv_mm=dv)
                       for ln in model.lines]
        dark = dark_level(dark_strips)
    out: list[LineReading] = []
    profiles = []
    for i, (line, cs) in enumerate(zip(model.lines, strips, strict=True)):
        if method == "area":
            cols = contrast_widths(cs, bead)
        elif method == "area-global":
            cols = area_widths(dark_strips[i], dark)
        else:
            vals = cs.strip.values if not light else 255.0 - cs.strip.values
            cols = edge_widths(Strip(np.asarray(vals, dtype=np.float32), cs.strip.dv_mm,
                                     cs.strip.per, cs.strip.positions_mm))
        if mm_per_px is not None:
            mid = 0.5 * (line.vertices_xy_mm[0] + line.vertices_xy_mm[-1])
            cols = cols * (mm_per_px * local_scale(reading.homography, mid))
        wid = window_widths(cols, cs.strip.per, min_width_mm=0.5 * line.layer_height_mm)
        ref, score, e_acc, e_dec = score_line(line, cs.strip.positions_mm, wid)
        out.append(LineReading(line.advance_k_s, cs.strip.positions_mm, wid, ref, score,
                               e_acc, e_dec, float(np.mean(np.isfinite(wid)))))
        profiles.append(np.median(cs.contrast, axis=1))
    return out, np.median(np.vstack(profiles), axis=0), dv


def _find_and_register(gray: npt.NDArray[np.uint8], polarity: str, geo: LayoutGeometry,
                       view: str, name: str) -> tuple[LineSet, list[Reading]]:
    """The lines (:mod:`.detect`), the refusals that need only them, the readings."""
    ls = detect_lines(gray, polarity=polarity, source=name)
    n = geo.starts.shape[0]
    if len(ls.lines) < min(MIN_LINES, n):
        raise VisionError("too few lines found to compare", source=name,
                          value=f"{len(ls.lines)} line(s)",
                          allowed=f"at least {MIN_LINES} lines of the pattern in view")
    cut = [i for i, f in enumerate(ls.lines) if f.cut]
    if cut:
        raise VisionError("lines are cut by the edge of the photo", source=name,
                          value=f"{len(cut)} of {len(ls.lines)} lines",
                          allowed="the whole pattern in the frame, with a margin")
    return ls, register_layout(ls, geo, view=view, source=name)


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
        Width sample spacing along the lines; ``"area"`` (contrast against the local
        sheet), ``"area-global"`` (one bead level for the photo) or ``"edges"``.
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
        nor the widths decide), or does not support the answer it gives
        (:func:`~flowtwin.calibration.image.quality.answer_reason`).
    CalibrationError
        Bad options, or a pattern for another firmware than the machine's.
    """
    if mm_per_px is not None and not (0.0 < mm_per_px < 10.0):
        raise CalibrationError("image resolution out of range", field="mm_per_px",
                               value=mm_per_px, allowed="0 < mm/px < 10 (25.4/dpi)")
    if method not in ("area", "area-global", "edges"):
        raise CalibrationError("unknown width measurement", field="method", value=method,
                               allowed="area, area-global, edges")
    if not (0.05 <= step_mm <= 5.0):
        raise CalibrationError("sample step out of range", field="step_mm", value=step_mm,
                               allowed="0.05 .. 5 mm")
    m = machine_for_pattern(pattern, machine)
    gray, name = load_grey(image)
    # a large photo is read at the pitch the reader needs; px figures come back in its own
    gray, scale = working_copy(gray)
    mm_per_px = None if mm_per_px is None else mm_per_px / scale
    full = lag_model(pattern.text().encode(), None, machine=m)
    geo, k_index = layout_geometry(pattern, full)
    model = full.subset(k_index)
    n = len(k_index)
    extra_notes: list[str] = []
    try:
        ls, readings = _find_and_register(gray, polarity, geo, view, name)
    except VisionError as exc:
        if polarity != "auto" or exc.field != "polarity":
            raise
        # the image does not tell the polarity: the layout does, if the lines of only
        # one polarity register (fat beads leave gaps narrower than the beads, which the
        # other polarity's top-hat finds as lines too)
        fits = []
        for pol in ("light", "dark"):
            try:
                fits.append(_find_and_register(gray, pol, geo, view, name))
            except VisionError:
                continue
        if len(fits) != 1:
            raise
        ls, readings = fits[0]
        extra_notes.append(f"bead polarity decided by the layout: only the "
                           f"{'light' if ls.light else 'dark'} lines register "
                           f"(image evidence {exc.value})")
    pitch_mm = float(np.median(np.hypot(*np.diff(geo.starts, axis=0).T))) if n > 1 else 5.0
    g32 = np.asarray(gray, dtype=np.float32)
    read = [_read(g32, ls.light, r, model, pitch_mm=pitch_mm,
                  line_width_mm=pattern.settings.line_width_mm, step_mm=step_mm,
                  method=method, mm_per_px=mm_per_px) for r in readings]
    choice = 0
    how = "the pattern's marks" if geo.marks else "the only reading"
    if len(readings) > 1:
        pick = choose_by_twin(model, [r[0] for r in read])
        if pick.index is None:
            raise VisionError("the photo does not show which way the pattern lies (its marks "
                              "are not seen or read the same both ways, and the twin does "
                              "not explain the widths clearly better in one reading)",
                              source=name, field="view",
                              value={r.name: f"twin RMS {v:.3f}, trend {t:+.2f}"
                                     for r, v, t in zip(readings, pick.rms, pick.trends,
                                                        strict=True)},
                              allowed="view top or mirrored, or a photo showing the "
                                      "pattern's marks (prime line, numbers)")
        choice = pick.index
        how = (f"the widths (the twin explains them with RMS {pick.rms[choice]:.3f}, the "
               f"next reading {min(v for i, v in enumerate(pick.rms) if i != choice):.3f})")
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
    ks = np.array([r.k_la_s for r in lines])
    choice_best = best_line(ks, [r.score for r in lines], [r.accel_error for r in lines],
                            [r.decel_error for r in lines], usable)
    best = choice_best.index
    k_acc = zero_crossing(ks, np.array([r.accel_error for r in lines]), ks[best])
    k_dec = zero_crossing(ks, np.array([r.decel_error for r in lines]), ks[best])
    notes = [*extra_notes, f"{n} test lines, K {ks[0]:g} to {ks[-1]:g} s; beads "
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
            if exc.field in ("shift_mm", "stretch"):
                # the widths do not pin the registration along the lines: the photo's
                # own (the line ends) stands, and the lag is fitted without it
                try:
                    lag = fit_lag(model.subset(whole), profiles,
                                  fit_dead_time=fit_dead_time, fit_gain=fit_gain,
                                  fit_registration=False, end_margin_mm=end_margin_mm)
                    problem = None
                    notes.append(f"lag fitted on the photo's registration along the lines "
                                 f"(the widths do not pin it: {exc.message})")
                except CalibrationError as exc2:
                    problem = exc2.message
    check = answer_reason(ks, best, usable, k_lag_s=None if lag is None else lag.k_s,
                          k_lag_err_s=None if lag is None else lag.k_err_s,
                          dead_time=lag is not None and "dead_time_s" in lag.fitted,
                          best_by=choice_best.by, lag_problem=problem)
    if check.reason is not None:
        raise VisionError(check.reason, source=name, field="k_best_line_s",
                          value=check.values)
    ends = np.array([[ln.start_px, ln.end_px] for ln in reading.lines]) / scale
    if scale < 1.0:
        notes.append(scale_note(scale, ls.pitch_px))
    return PhotoResult(name, pattern.kind, tuple(lines), best, k_acc, k_dec, lag, problem,
                       ls.light, f"{reading.name} (decided by {how})",
                       reading.px_per_mm / scale, reading.reprojection_rms_mm,
                       homography_to_photo(reading.homography, scale),
                       ends, tuple(notes),
                       k_cross_s=choice_best.k_cross_s, best_by=choice_best.by,
                       disagreement=check.z)
