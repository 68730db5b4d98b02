"""K from a photo of flowtwin's chevron pattern (nested 90° corners, one K per chevron).

A chevron's apex is where the advance factor shows: the nozzle slows into the corner and
speeds up out of it, so a lag the factor does not cancel leaves material at the apex (K
too low: a blob, the bands thick on both arms near the apex) or takes it away (K too
high: thin, a gap before the apex) [001 Fig. 2]. In a photo each chevron is one *band* of
its touching walls (:mod:`.chevron_geom`); the analysis:

1. **Two families of lines.** The arms run in two directions. The gradient directions of
   the photo (Sobel, weighted by magnitude, folded to 180°) have two peaks; for each, the
   lines in that direction are found as for a line pattern (:func:`.detect.detect_lines`
   with that angle: the other family lies across the top-hat and is removed by it).
2. **Pairing and order.** Each arm of one family meets one arm of the other at an apex
   (their ends within a pitch); the apex is where their axes cross. The chevrons are
   ordered along the apex direction, in which the pattern's K rises.
3. **Registration.** A homography bed → image from the bands' apexes and arm ends,
   refined on the arms' axes (:func:`.register.refine_homography`). Which family is the
   upper arm is what a mirrored photo changes; the pattern's marks (prime line and ticks
   in front) decide it, else the view from above is taken (it only swaps the arms; the
   best chevron does not depend on it).
4. **Widths along each arm** from the apex outwards (:mod:`.widths`, the band's contrast
   against the local sheet), from ``d0`` (half a band and half the sheet's smoothing
   length beyond the apex: nearer, the other arm is in the strip) to the arm's end.
5. **Scores.** ``r = w/w_steady`` with ``w_steady`` the median width over the outer part
   of both arms (55–90 % of their length, where the nozzle cruises); each arm's error
   ``−mean(r − 1)`` over :data:`NEAR_MM` beyond ``d0``, and the score, the RMS of
   ``r − 1`` over :data:`SCORE_MM` on both arms. Which way the error goes depends on the
   way the walls ran: with K too low a wall piles material on the arm it runs *into*
   the apex along (the pressure the lag leaves as the nozzle slows) and thins the arm it
   leaves along (the lag as it speeds up); with K too high the other way round. The
   walls alternate, so a band of three has two walls one way and one the other, and the
   majority changes from one chevron to the next: the arms' mean error nearly cancels,
   their difference does not. The chevron's signed error is
   ``s·(e_upper − e_lower)/2`` with ``s`` the sign of (walls run into the apex along the
   upper arm − along the lower) (:attr:`.chevron_geom.ChevronGeometry.upper_first`):
   negative when K is too low, positive when too high, as a line's. (An even number of
   walls cancels the difference too: then the mean is used, and said.) The best chevron
   is the one nearest the zero crossing of all chevrons' errors (:mod:`.bestline`).
6. **The twin's lag** fitted to the bands' widths (:mod:`.chevron_fit`).

Refusals as for line patterns (:mod:`.quality`): blur, a chevron count that is not the
pattern's, arms cut by the frame, too few chevrons measured.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.calibration.fits.kfit import machine_for_pattern
from flowtwin.calibration.fits.lagfit import LagFit
from flowtwin.calibration.fits.lagmodel import lag_model
from flowtwin.calibration.image.beadwidth import window_widths
from flowtwin.calibration.image.bestline import best_line
from flowtwin.calibration.image.chevron_geom import ChevronGeometry, chevron_geometry
from flowtwin.calibration.image.detect import FoundLine, LineSet, detect_lines
from flowtwin.calibration.image.geometry import LayoutGeometry
from flowtwin.calibration.image.kimage import LineReading, load_grey
from flowtwin.calibration.image.quality import MIN_LINES, answer_reason, blur_reason
from flowtwin.calibration.image.register import local_scale, marks_seen, refine_homography
from flowtwin.calibration.image.scale import homography_to_photo, scale_note, working_copy
from flowtwin.calibration.image.widths import (
    SHEET_SMOOTH_MM,
    ContrastStrip,
    band_half_mm,
    bead_contrast,
    contrast_strip,
    contrast_widths,
)
from flowtwin.calibration.patterns.pattern import Pattern
from flowtwin.errors import CalibrationError, VisionError
from flowtwin.profiles.machine import Machine

__all__ = ["NEAR_MM", "SCORE_MM", "ChevronResult", "analyse_chevron_photo", "arm_directions"]

FloatArray = npt.NDArray[np.float64]

#: Length beyond ``d0`` over which an arm's signed error is averaged, mm.
NEAR_MM = 4.0
#: Length beyond ``d0`` over which an arm's score is taken, mm.
SCORE_MM = 8.0
_MIN_MEASURED = 0.5
#: Top-hat element, pitches: a band of touching walls is 0.4 pitch wide, its gap 0.6.
_ELEMENT = 0.5


@dataclass(frozen=True)
class ChevronResult:
    """What a photo of a chevron pattern shows.

    Attributes
    ----------
    source, pattern
        Image name and ``"chevron"``.
    lines
        One reading per chevron (rising K): ``positions_mm`` the distance from the apex,
        negative along the upper arm, positive along the lower; ``accel_error`` the
        chevron's signed error (module docstring), ``decel_error`` NaN.
    best_index, k_cross_s, best_by
        The best chevron, the errors' zero crossing and how it was chosen
        (:mod:`.bestline`).
    lag, lag_problem
        The twin's lag fitted to the bands, or why there is none.
    light_beads, reading, px_per_mm, reprojection_rms_mm, homography
        As for line patterns.
    image_lines
        Each chevron's band in the image: upper end, apex, lower end, px, ``(n, 3, 2)``.
    notes
        Facts worth knowing.
    arm_errors
        Each chevron's upper and lower arm error, ``(n, 2)``.
    disagreement
        The best chevron's and the lag's disagreement (:func:`~.quality.disagreement`).
    """

    source: str
    pattern: str
    lines: tuple[LineReading, ...]
    best_index: int
    k_cross_s: float | None
    best_by: str
    lag: LagFit | None
    lag_problem: str | None
    light_beads: bool
    reading: str
    px_per_mm: float
    reprojection_rms_mm: float
    homography: FloatArray
    image_lines: FloatArray
    notes: tuple[str, ...] = field(default_factory=tuple)
    arm_errors: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    disagreement: float = math.nan

    @property
    def k_best_line_s(self) -> float:
        """Advance factor of the best chevron, s."""
        return self.lines[self.best_index].k_la_s

    def summary(self) -> dict[str, Any]:
        """Plain JSON-able description (``k_s``: the fitted lag, or ``None``)."""
        return {
            "image": self.source, "pattern": self.pattern,
            "k_s": None if self.lag is None else self.lag.k_s,
            "k_err_s": None if self.lag is None else self.lag.k_err_s,
            "k_best_line_s": self.k_best_line_s, "best_by": self.best_by,
            "k_cross_s": self.k_cross_s,
            "lag": None if self.lag is None else self.lag.summary(),
            "lag_problem": self.lag_problem, "disagreement": _num(self.disagreement),
            "beads": "light" if self.light_beads else "dark", "reading": self.reading,
            "px_per_mm": self.px_per_mm, "reprojection_rms_mm": self.reprojection_rms_mm,
            "chevrons": [{"k_s": r.k_la_s, "score": _num(r.score),
                          "error": _num(r.accel_error),
                          "upper_arm_error": _num(float(e[0])),
                          "lower_arm_error": _num(float(e[1])),
                          "steady_width_mm": _num(r.steady_width_mm),
                          "measured_fraction": r.measured_fraction}
                         for r, e in zip(self.lines, self.arm_errors, strict=True)],
            "notes": list(self.notes),
        }


def _num(x: float) -> float | None:
    return x if math.isfinite(x) else None


def arm_directions(gray: npt.NDArray[np.uint8]) -> tuple[float, float]:
    """The two line directions of a chevron photo, degrees from the image's +x axis.

    The gradient directions (Sobel on a lightly blurred image, weighted by the squared
    magnitude, folded to 0–180°, histogram smoothed over 3°): the strongest peak, and the
    strongest at least 40° from it. A line runs across its gradient.
    """
    g = cv2.GaussianBlur(gray.astype(np.float32), (0, 0), 1.0)
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3)
    mag2 = (gx * gx + gy * gy).ravel()
    ang = (np.degrees(np.arctan2(gy, gx)).ravel()) % 180.0
    hist, _ = np.histogram(ang, bins=180, range=(0.0, 180.0), weights=mag2)
    k = np.exp(-0.5 * (np.arange(-9, 10) / 3.0) ** 2)
    smooth = np.convolve(np.concatenate([hist[-9:], hist, hist[:9]]), k, mode="same")[9:-9]
    p1 = int(np.argmax(smooth))
    dist = np.abs((np.arange(180) - p1 + 90) % 180 - 90)
    p2 = int(np.argmax(np.where(dist >= 40, smooth, -1.0)))

    def line_angle(grad_deg: float) -> float:
        a = grad_deg + 0.5 + 90.0
        while a > 90.0:
            a -= 180.0
        return a

    return line_angle(float(p1)), line_angle(float(p2))


def _axis_cross(a: FoundLine, b: FoundLine) -> FloatArray | None:
    """Where the axes of two found lines cross, px."""
    d1 = a.end_px - a.start_px
    d2 = b.end_px - b.start_px
    m = np.column_stack([d1, -d2])
    if abs(float(np.linalg.det(m))) < 1e-9:
        return None
    t = np.linalg.solve(m, b.start_px - a.start_px)
    return np.asarray(a.start_px + t[0] * d1, dtype=np.float64)


def _pairs(fa: LineSet, fb: LineSet) -> list[tuple[FloatArray, FloatArray, FloatArray,
                                                   FoundLine, FoundLine]]:
    """``(apex, end of a, end of b, a, b)`` of arms that meet (mutually nearest ends)."""
    out = []
    reach = 1.0 * max(fa.pitch_px, fb.pitch_px)

    def nearest(f: FoundLine, others: tuple[FoundLine, ...]) -> tuple[int, float]:
        best, bd = -1, math.inf
        for j, g in enumerate(others):
            d = min(float(np.hypot(*(p - q))) for p in (f.start_px, f.end_px)
                    for q in (g.start_px, g.end_px))
            if d < bd:
                best, bd = j, d
        return best, bd

    for i, a in enumerate(fa.lines):
        j, d = nearest(a, fb.lines)
        if j < 0 or d > reach or nearest(fb.lines[j], fa.lines)[0] != i:
            continue
        b = fb.lines[j]
        apex = _axis_cross(a, b)
        if apex is None:
            continue
        far_a = max((a.start_px, a.end_px), key=lambda p: float(np.hypot(*(p - apex))))
        far_b = max((b.start_px, b.end_px), key=lambda p: float(np.hypot(*(p - apex))))
        out.append((apex, np.asarray(far_a), np.asarray(far_b), a, b))
    return out


@dataclass(frozen=True)
class _Reading:
    name: str
    hom: FloatArray
    across_rms_px: float
    mirrored: bool
    seen_mm: float
    total_mm: float
    paths: FloatArray          # (n, 3, 2): upper end, apex, lower end in the image


def _readings(pairs: list[tuple[FloatArray, FloatArray, FloatArray, FoundLine, FoundLine]],
              geo: ChevronGeometry, ls: LineSet) -> list[_Reading]:
    """Both assignments of the families to the upper and lower arms."""
    apex_dir = np.mean([p[0] - 0.5 * (p[1] + p[2]) for p in pairs], axis=0)
    order = sorted(range(len(pairs)), key=lambda i: float(pairs[i][0] @ apex_dir))
    bed_dir = geo.apex[0] - 0.5 * (geo.upper[0] + geo.lower[0])
    if len(geo.apex) > 1 and float((geo.apex[-1] - geo.apex[0]) @ bed_dir) < 0:
        order = order[::-1]          # K rises against the apex direction
    out = []
    centre = geo.apex.mean(axis=0)
    marks_geo = LayoutGeometry(np.vstack([geo.upper, geo.lower]),
                               np.vstack([geo.apex, geo.apex]), (), geo.marks, (),
                               geo.line_width_mm)
    for swap in (False, True):
        bed, img, arms = [], [], []
        paths = []
        for j, i in enumerate(order):
            apex, ea, eb, _, _ = pairs[i]
            up, lo = (eb, ea) if swap else (ea, eb)
            bed += [geo.upper[j], geo.apex[j], geo.lower[j]]
            img += [up, apex, lo]
            arms += [(geo.upper[j], geo.apex[j], up, apex), (geo.lower[j], geo.apex[j], lo, apex)]
            paths.append(np.vstack([up, apex, lo]))
        src = np.asarray(bed, dtype=np.float64)
        dst = np.asarray(img, dtype=np.float64)
        hom, _ = cv2.findHomography(src, dst, cv2.RANSAC, max(2.0, 0.05 * ls.pitch_px))
        if hom is None:
            continue
        hom, across = refine_homography(np.asarray(hom, dtype=np.float64), arms)
        if not np.all(np.isfinite(hom)):
            continue
        seen, total = marks_seen(ls, hom, marks_geo)
        mirrored = _det(hom, centre) > 0
        out.append(_Reading("arms of the first family upper" if not swap else
                            "arms of the first family lower", hom,
                            float(np.sqrt(np.mean(across ** 2))), mirrored, seen, total,
                            np.asarray(paths)))
    return out


def _det(h: FloatArray, xy: FloatArray) -> float:
    p = np.array([xy[0], xy[1], 1.0])
    q = h @ p
    eps = 1e-3
    qx = h @ (p + np.array([eps, 0.0, 0.0]))
    qy = h @ (p + np.array([0.0, eps, 0.0]))
    jx = (qx[:2] / qx[2] - q[:2] / q[2]) / eps
    jy = (qy[:2] / qy[2] - q[:2] / q[2]) / eps
    return float(jx[0] * jy[1] - jx[1] * jy[0])


def _arm_strips(g32: npt.NDArray[np.float32], light: bool, hom: FloatArray,
                geo: ChevronGeometry, step_mm: float, dv: float
                ) -> list[tuple[ContrastStrip, ContrastStrip]]:
    """Each chevron's two arms, from the apex outwards, as contrast strips."""
    band = band_half_mm(geo.band_mm, geo.pitch_mm)
    half = 0.5 * geo.pitch_mm

    def strip(j: int, end: FloatArray) -> ContrastStrip:
        return contrast_strip(g32, hom, geo.apex[j], end, light=light, step_mm=step_mm,
                              band_mm=band, half_span_mm=half, dv_mm=dv)

    return [(strip(j, geo.upper[j]), strip(j, geo.lower[j]))
            for j in range(geo.apex.shape[0])]


def _score(k: float, d: FloatArray, w_up: FloatArray, w_lo: FloatArray, d0: float,
           arm: float, upper_first: int) -> tuple[LineReading, tuple[float, float]]:
    steady_sel = (d >= 0.55 * arm) & (d <= 0.9 * arm)
    both = np.concatenate([w_up[steady_sel], w_lo[steady_sel]])
    ref = float(np.nanmedian(both)) if np.any(np.isfinite(both)) else math.nan
    pos = np.concatenate([-d[::-1], d])
    wid = np.concatenate([w_up[::-1], w_lo])
    measured = float(np.mean(np.isfinite(np.concatenate([w_up[d >= d0], w_lo[d >= d0]]))))
    if not ref > 0:
        return (LineReading(k, pos, wid, math.nan, math.nan, math.nan, math.nan, measured),
                (math.nan, math.nan))
    errs, devs = [], []
    for w in (w_up, w_lo):
        r = np.where(np.isfinite(w), w / ref, 0.0)
        near = (d >= d0) & (d < d0 + NEAR_MM)
        errs.append(-float(np.mean(r[near] - 1.0)) if np.any(near) else math.nan)
        sc = (d >= d0) & (d < d0 + SCORE_MM)
        devs.append(r[sc] - 1.0)
    score = float(np.sqrt(np.mean(np.concatenate(devs) ** 2)))
    s = float(np.sign(upper_first))
    err = s * 0.5 * (errs[0] - errs[1]) if s != 0 else 0.5 * (errs[0] + errs[1])
    return (LineReading(k, pos, wid, ref, score, err, math.nan, measured),
            (errs[0], errs[1]))


def analyse_chevron_photo(image: str | os.PathLike[str] | npt.NDArray[Any], pattern: Pattern,
                          *, machine: Machine | str | os.PathLike[str] | None = None,
                          polarity: str = "auto", view: str = "auto", step_mm: float = 0.25,
                          fit: bool = True) -> ChevronResult:
    """Read a photo of a printed chevron pattern (module docstring).

    Parameters
    ----------
    image
        Image file or array (grey or BGR).
    pattern
        The pattern as printed (:func:`flowtwin.calibration.patterns.chevron.chevron_pattern`),
        for the machine's firmware.
    machine
        Set-up for the twin.
    polarity, view
        As for line patterns (:func:`.analyse.analyse_line_photo`).
    step_mm
        Width sample spacing along the arms.
    fit
        Fit the twin's lag to the bands.

    Returns
    -------
    ChevronResult

    Raises
    ------
    VisionError
        The photo cannot support an answer.
    CalibrationError
        Bad options, a pattern that is not a chevron pattern or for another firmware.
    """
    if pattern.kind != "chevron":
        raise CalibrationError("not a chevron pattern", field="pattern", value=pattern.kind,
                               allowed="chevron")
    if view not in ("auto", "top", "mirrored"):
        raise VisionError("unknown view", field="view", value=view,
                          allowed="auto, top, mirrored")
    if not (0.05 <= step_mm <= 5.0):
        raise CalibrationError("sample step out of range", field="step_mm", value=step_mm,
                               allowed="0.05 .. 5 mm")
    m = machine_for_pattern(pattern, machine)
    gray, name = load_grey(image)
    # a large photo is read at the pitch the reader needs; px figures come back in its own
    gray, shrunk = working_copy(gray)
    full = lag_model(pattern.text().encode(), None, machine=m)
    geo = chevron_geometry(pattern, full)
    n = geo.apex.shape[0]
    a1, a2 = arm_directions(gray)
    fa = detect_lines(gray, polarity=polarity, source=name, angle_deg=a1,
                      element_pitches=_ELEMENT)
    fb = detect_lines(gray, polarity="light" if fa.light else "dark", source=name,
                      angle_deg=a2, element_pitches=_ELEMENT)
    cut = [f for f in fa.lines + fb.lines if f.cut]
    if cut:
        raise VisionError("chevron arms are cut by the edge of the photo", source=name,
                          value=f"{len(cut)} arms", allowed="the whole pattern in the frame")
    pairs = _pairs(fa, fb)
    if len(pairs) != n:
        raise VisionError(f"found {len(pairs)} chevrons (arms meeting at an apex), but the "
                          f"pattern has {n}", source=name,
                          value={"arms": [len(fa.lines), len(fb.lines)],
                                 "chevrons": len(pairs)},
                          allowed=f"{n} chevrons (give k-start, k-end, k-step as printed; "
                                  "the whole pattern in view)")
    if n < MIN_LINES:
        raise VisionError("too few chevrons to compare", source=name, value=n,
                          allowed=f"at least {MIN_LINES}")
    readings = _readings(pairs, geo, fa)
    if view != "auto":
        readings = [r for r in readings if r.mirrored == (view == "mirrored")]
    if not readings:
        raise VisionError("the chevrons do not fit the pattern's geometry", source=name,
                          allowed="a flat print, seen whole")
    readings.sort(key=lambda r: -r.seen_mm)
    margin = max(5.0, 0.05 * readings[0].total_mm)
    if len(readings) > 1 and readings[0].seen_mm - readings[1].seen_mm >= margin:
        reading = readings[0]
        how = "the pattern's marks (prime line, ticks)"
    elif len(readings) > 1:
        reading = next(r for r in readings if not r.mirrored)
        how = ("a view from above (the marks do not decide; a mirrored view would only "
               "swap the arms)")
    else:
        reading = readings[0]
        how = f"view {view}"
    scale = local_scale(reading.hom, geo.apex.mean(axis=0))
    dv = 0.5 / scale
    g32 = np.asarray(gray, dtype=np.float32)
    strips = _arm_strips(g32, fa.light, reading.hom, geo, step_mm, dv)
    bead = bead_contrast([s for pair in strips for s in pair])
    d0 = 0.5 * geo.band_mm + 0.5 * SHEET_SMOOTH_MM + 0.3
    lines = []
    arm_errors = []
    profiles = []
    for j, (su, sl) in enumerate(strips):
        ws = [window_widths(contrast_widths(s, bead), s.strip.per,
                            min_width_mm=0.5 * geo.layer_height_mm) for s in (su, sl)]
        nd = min(ws[0].size, ws[1].size)
        d = su.strip.positions_mm[:nd]
        reading_j, arms_j = _score(float(pattern.values[j]), d, ws[0][:nd], ws[1][:nd],
                                   d0, geo.arm_mm, geo.upper_first[j])
        lines.append(reading_j)
        arm_errors.append(arms_j)
        sel = d >= 0.55 * geo.arm_mm
        profiles.append(np.median(su.contrast[:, np.repeat(sel, su.strip.per)], axis=1))
    reason = blur_reason(np.median(np.vstack(profiles), axis=0), dv, scale)
    if reason is not None:
        raise VisionError(reason, source=name, field="image")
    usable = [i for i, r in enumerate(lines)
              if r.measured_fraction >= _MIN_MEASURED and math.isfinite(r.score)]
    if len(usable) < min(MIN_LINES, n):
        raise VisionError("too few chevrons could be measured along their arms", source=name,
                          value=f"{len(usable)} of {n}",
                          allowed=f"at least {MIN_LINES} chevrons with beads along the arms")
    ks = np.array([r.k_la_s for r in lines])
    choice = best_line(ks, [r.score for r in lines], [r.accel_error for r in lines],
                       [r.decel_error for r in lines], usable)
    notes = [f"{n} chevrons, K {ks[0]:g} to {ks[-1]:g} s; beads "
             f"{'lighter' if fa.light else 'darker'} than the sheet; arms assigned by {how}",
             f"widths from {d0:.2f} mm beyond each apex (nearer, the other arm is in the "
             "strip)"]
    if any(u == 0 for u in geo.upper_first):
        notes.append("an even number of walls: as many run into each apex along either arm, "
                     "so a chevron's error is the mean of its arms' (weak)")
    lag: LagFit | None = None
    problem: str | None = None
    if fit:
        from flowtwin.calibration.image.chevron_fit import fit_chevron_lag
        try:
            lag = fit_chevron_lag(full, geo, lines, d0=d0, step_mm=step_mm, source=name)
        except CalibrationError as exc:
            problem = exc.message
    check = answer_reason(ks, choice.index, usable, k_lag_s=None if lag is None else lag.k_s,
                          k_lag_err_s=None if lag is None else lag.k_err_s, item="chevron",
                          best_by=choice.by, lag_problem=problem)
    if check.reason is not None:
        raise VisionError(check.reason, source=name, field="k_best_line_s",
                          value=check.values)
    if shrunk < 1.0:
        notes.append(scale_note(shrunk, fa.pitch_px, "arm"))
    return ChevronResult(name, "chevron", tuple(lines), choice.index, choice.k_cross_s,
                         choice.by, lag, problem, fa.light,
                         f"{reading.name} (decided by {how})", scale / shrunk,
                         reading.across_rms_px / scale,
                         homography_to_photo(reading.hom, shrunk),
                         reading.paths / shrunk, tuple(notes),
                         np.asarray(arm_errors, dtype=np.float64),
                         disagreement=check.z)
