"""Filament width from its two outer edges, with a plausibility model [003 §2.2].

[003 §2.2] finds the width from "the maximum and minimum of the first derivative across
the filament ROI, in the expected filament edge area". A real ROI also holds other edges
(the idler bearing's dark rim, the gear, teeth marks and specular highlights on the
filament), and the strongest rise and fall of the derivative need not be the filament's.
Here the two edges must form a *plausible filament*:

1. **Candidates.** Each row is smoothed across the filament (Gaussian, ``sigma_px``) and
   differentiated. The rows are grouped in horizontal bands (at most
   :data:`_MAX_BANDS`, at least :data:`_BAND_ROWS` rows each); in each band's mean
   derivative every local extremum stronger than ``min_edge_dn_px`` is a candidate edge.
2. **Pairs.** A rising edge followed by a falling one is a bright filament on a darker
   background, a falling then rising edge a dark one. A pair is plausible when
   (a) its separation lies in one of the ``expected_px`` ranges (the nominal diameter
   over the scale, when known), (b) the background outside each edge is resolved
   (:data:`_EDGE_CLEAR` · ``sigma`` px inside the ROI), and (c) nothing between the two
   edges comes back to the background level: the darkest interior point (bright
   filament) stays at least half the weaker edge's step above the brighter outside
   level. (c) separates one object from two (filament and bearing, gear and filament).
3. **Outer edges.** Highlights and teeth marks give pairs *inside* the filament; a pair
   nested in another plausible pair is dropped. One outer pair left: that band's
   filament. Several (not nested in each other): the band is **ambiguous** — unless no
   nominal width is known (the scale is being calibrated) and one pair is at least
   :data:`_DOMINANCE` times wider than all others.
4. **Consistency along the rows.** Bands must agree on polarity, width (within
   :data:`_BAND_TOL_PX` px or 3 %) and on a straight centre line; every row is then
   refined near its band's edges (parabola through the derivative extremum for sub-pixel
   position), a straight line is fitted to each edge along the rows, and rows off those
   lines (a tooth mark, a speck) are dropped.
5. **Refusal.** The measurement is refused — ``ok`` false, NaN width and a ``status`` —
   when no band has a plausible pair (``no_edges``), when ambiguous or disagreeing bands
   outnumber a quarter of the bands with edges or leave fewer agreeing bands than
   half of all bands (``ambiguous``), or when fewer than ``min_rows_frac`` of the rows keep
   both edges (``few_rows``). A refused frame is flagged, never given a number.

The width is the mean of the row widths times ``cos(tilt)`` (tilt of the centre line):
the perpendicular width. The image scale follows from a known width,
``k_cal = w_µ / w_detected`` [003 Eq. 4].
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.errors import VisionError
from flowtwin.vision.edge_model import EdgeProfile
from flowtwin.vision.edge_pairs import Pair, band_pairs, outer_pairs
from flowtwin.vision.silhouette import (
    NO_FIT,
    Silhouette,
    edge_profiles,
    fit_silhouette,
    fit_silhouettes,
)

__all__ = ["STANDARD_DIAMETERS_MM", "EdgeMeasurement", "calibration_factor",
           "expected_width_px", "measure_width_px", "refit_width", "refit_widths"]

F64 = npt.NDArray[np.float64]

#: Filament diameters on the market, mm (used when no nominal diameter is given).
STANDARD_DIAMETERS_MM = (1.75, 2.85)
#: Half-width of the plausible range around a given nominal diameter, fraction: the
#: filament's own tolerance (±0.05 mm on 1.75 mm is ±3 %) plus the scale's uncertainty.
DIAMETER_TOLERANCE = 0.05
#: Half-width around the standard diameters when none is given (2.85 mm filament is sold
#: as "3 mm"; 3.0 mm lies within 2.85 mm + 8 %).
STANDARD_TOLERANCE = 0.08
#: Largest number of row bands, and fewest rows in one band.
_MAX_BANDS = 6
_BAND_ROWS = 12
#: Background must be resolved this many smoothing sigmas (and at least 3 px) outside an
#: edge inside the ROI.
_EDGE_CLEAR = 3.0
#: Without a nominal width, a band's widest plausible pair is taken when it is at least
#: this many times wider than the next one (a glint or a gap beside the filament).
_DOMINANCE = 2.0
#: Bands agree when their widths, and their centres about a straight line, differ by at
#: most this many px or this fraction of the width, whichever is larger.
_BAND_TOL_PX = 3.0
_BAND_TOL_FRACTION = 0.03
#: Rows farther than this from an edge's straight line are dropped (or 3 robust sigma).
_ROW_LINE_TOL_PX = 1.0
#: The two edge lines may drift apart over the ROI's height by at most this many px plus
#: this fraction of the height (real edges wiggle by a px or so; a gear's round outline
#: taken for an edge drifts much more).
_PARALLEL_TOL_PX = 2.5
_PARALLEL_TOL_FRACTION = 0.02
#: A row's edge must be at least this fraction of its band's edge strength.
_ROW_STRENGTH_FRACTION = 0.3


@dataclass(frozen=True, slots=True, eq=False)
class EdgeMeasurement:
    """Result of one width measurement in one image crop.

    Attributes
    ----------
    width_px
        Perpendicular filament width, px (NaN if not ``ok``).
    left_px, right_px
        Mean edge columns in crop coordinates, px (NaN if not ``ok``).
    tilt_rad
        Angle of the filament axis from the image vertical, rad.
    edge_dn_px
        Median edge slope, DN/px.
    rows_used
        Rows that contributed.
    ok
        The measurement is usable.
    reason
        Why not, if not ``ok``.
    status
        ``"ok"``, ``"no_edges"`` (no plausible pair of edges), ``"ambiguous"``
        (competing plausible pairs, or rows that disagree), ``"few_rows"``, or
        ``"pending"`` (edges found, silhouettes not fitted yet: ``fit=False``).
    row_spread_px
        Standard deviation of the used rows' widths, px (NaN if not ``ok``).
    row_left_px, row_right_px
        Edge column of every row, crop coordinates (NaN where none), shape ``(H,)``.
    row_used
        Rows that contributed, shape ``(H,)``.
    rejected
        Plausible-looking pairs that were not taken, ``(y0, y1, left, right, why)`` in
        crop coordinates (for drawing).
    gradient_width_px
        The width between the derivative extrema (the method of [003 §2.2]), px; NaN when
        the edges were not found.
    blur_px
        Blur σ of the silhouette fit (optics and pixel), px.
    lines
        The derivative-extremum edge lines ``((slope, intercept), (slope, intercept))``,
        ``x = slope·y + intercept`` in crop coordinates (``None`` if not found).
    silhouette
        The silhouette fit of the two edges (:mod:`flowtwin.vision.silhouette`), or
        ``None``.
    edge_scatter_px
        Robust scatter (1.4826·MAD) of the rows' edge points about the left and the right
        edge line, px: a silhouette is straight, gear teeth over the edge or teeth marks
        in it are not.
    """

    width_px: float
    left_px: float
    right_px: float
    tilt_rad: float
    edge_dn_px: float
    rows_used: int
    ok: bool
    reason: str = ""
    status: str = "ok"
    row_spread_px: float = math.nan
    row_left_px: F64 = field(default_factory=lambda: np.zeros(0))
    row_right_px: F64 = field(default_factory=lambda: np.zeros(0))
    row_used: npt.NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, bool))
    rejected: tuple[tuple[int, int, float, float, str], ...] = ()
    gradient_width_px: float = math.nan
    blur_px: float = math.nan
    lines: tuple[tuple[float, float], tuple[float, float]] | None = None
    silhouette: Silhouette | None = None
    edge_scatter_px: tuple[float, float] = (math.nan, math.nan)


def expected_width_px(mm_per_px: float | None, diameter_mm: float | None = None, *,
                      tolerance: float | None = None
                      ) -> tuple[tuple[float, float], ...] | None:
    """Plausible filament widths in px from the nominal diameter and the scale.

    Parameters
    ----------
    mm_per_px
        Image scale, mm/px; ``None`` (scale still to be calibrated): no range.
    diameter_mm
        Nominal filament diameter, mm; ``None``: any of :data:`STANDARD_DIAMETERS_MM`.
    tolerance
        Half-width of each range as a fraction of the diameter (default
        :data:`DIAMETER_TOLERANCE` for a given diameter, :data:`STANDARD_TOLERANCE` for
        the standard ones).

    Returns
    -------
    tuple of (float, float) or None
        ``((lo_px, hi_px), ...)``, or ``None`` when the scale is unknown.
    """
    if mm_per_px is None:
        return None
    diameters = STANDARD_DIAMETERS_MM if diameter_mm is None else (diameter_mm,)
    if tolerance is None:
        tolerance = STANDARD_TOLERANCE if diameter_mm is None else DIAMETER_TOLERANCE
    return tuple(((1 - tolerance) * d / mm_per_px, (1 + tolerance) * d / mm_per_px)
                 for d in diameters)


def _refuse(status: str, reason: str, h: int, edge: float = math.nan, rows: int = 0,
            rejected: tuple[tuple[int, int, float, float, str], ...] = ()
            ) -> EdgeMeasurement:
    nan = np.full(h, math.nan)
    return EdgeMeasurement(math.nan, math.nan, math.nan, math.nan, edge, rows, False, reason,
                           status, math.nan, nan, nan.copy(), np.zeros(h, bool), rejected)


def _subpixel(d: npt.NDArray[np.float32], k: npt.NDArray[np.intp]) -> F64:
    """Sub-pixel extremum near index ``k`` of each row of ``d`` (parabola, ±0.5 px)."""
    rows = np.arange(d.shape[0])
    km = np.clip(k, 1, d.shape[1] - 2)
    a = d[rows, km - 1].astype(np.float64)
    b = d[rows, km].astype(np.float64)
    c = d[rows, km + 1].astype(np.float64)
    den = a - 2.0 * b + c
    with np.errstate(divide="ignore", invalid="ignore"):
        off = np.where(np.abs(den) > 1e-12, 0.5 * (a - c) / den, 0.0)
    return km + np.clip(off, -0.5, 0.5)


def measure_width_px(crop: npt.NDArray[np.uint8] | npt.NDArray[np.float32], *,
                     sigma_px: float = 0.7,
                     min_edge_dn_px: float = 3.0, min_rows_frac: float = 0.5,
                     expected_px: Sequence[tuple[float, float]] | None = None,
                     blur_px: float | None = None, mix: tuple[float, float] | None = None,
                     fit: bool = True) -> EdgeMeasurement:
    """Measure the filament width in a crop that spans both edges (see module docstring).

    Parameters
    ----------
    crop
        Grey image of the ``before`` ROI, shape ``(H, W)``, uint8 (or float32, e.g. a
        mean of several frames), filament roughly vertical with background on both
        sides.
    sigma_px
        Gaussian smoothing across the filament before differentiation, px.
    min_edge_dn_px
        Weakest accepted edge slope, DN/px.
    min_rows_frac
        Smallest fraction of the rows that must keep both edges.
    expected_px
        Plausible widths ``((lo, hi), ...)`` in px (:func:`expected_width_px`);
        ``None``: any width of at least ``4·sigma_px`` and 6 px.
    blur_px
        The camera's blur σ (optics and pixel), px, when known (e.g. from earlier frames
        of the same recording); ``None``: fitted in this crop.
    mix
        The two edges' limb shapes when known from earlier frames
        (:attr:`~flowtwin.vision.edge_model.EdgeFit.mix_rad`); ``None``: fitted.
    fit
        Fit the silhouettes now. ``False`` (with ``blur_px`` known): the edges are found
        and their profiles taken, but the fit is left for :func:`refit_widths`, which
        fits many frames in one vectorised pass; the result's ``status`` is
        ``"pending"`` (``ok`` false, width NaN) unless the edge search refused it.

    Returns
    -------
    EdgeMeasurement
        Width in px and diagnostics; ``ok`` is false (and the width NaN) when the edges
        are missing or ambiguous, never a guessed number.
    """
    h, w = crop.shape[:2]
    sm = np.asarray(cv2.GaussianBlur(crop.astype(np.float32), (0, 0), sigmaX=sigma_px,
                                     sigmaY=1e-3), dtype=np.float32)
    d = np.zeros_like(sm)
    d[:, 1:-1] = 0.5 * (sm[:, 2:] - sm[:, :-2])
    clear = max(3, math.ceil(_EDGE_CLEAR * sigma_px))
    min_sep = max(6.0, 4.0 * sigma_px, 2.0 * clear + 1)
    n_bands = max(1, min(_MAX_BANDS, h // _BAND_ROWS))
    bounds = np.linspace(0, h, n_bands + 1).round().astype(int)
    counts = np.diff(bounds).astype(np.float64)[:, None]
    band_d = np.add.reduceat(d, bounds[:-1], axis=0) / counts
    band_i = np.add.reduceat(sm, bounds[:-1], axis=0) / counts
    rejected: list[tuple[int, int, float, float, str]] = []
    chosen: list[tuple[int, Pair]] = []
    n_ambiguous = 0
    for b in range(n_bands):
        y0, y1 = int(bounds[b]), int(bounds[b + 1])
        outer = outer_pairs(band_pairs(band_d[b].astype(np.float64),
                                   band_i[b].astype(np.float64), min_edge_dn_px, clear,
                                   expected_px, min_sep))
        if expected_px is None and len(outer) > 1:
            # no nominal width: the filament is the one pair far wider than any other
            outer.sort(key=lambda q: q.right - q.left, reverse=True)
            if outer[0].right - outer[0].left >= _DOMINANCE * (outer[1].right - outer[1].left):
                outer = outer[:1]
        if len(outer) == 1:
            chosen.append((b, outer[0]))
        elif len(outer) > 1:
            n_ambiguous += 1
            rejected.extend((y0, y1, q.left, q.right, "competing pair") for q in outer)
    if not chosen:
        if n_ambiguous:
            return _refuse("ambiguous", f"several plausible edge pairs in {n_ambiguous} of "
                           f"{n_bands} row bands, none unique", h, rejected=tuple(rejected))
        return _refuse("no_edges", "no pair of filament edges in the ROI"
                       + ("" if expected_px is None else " at the expected width "
                          + ", ".join(f"{lo:.0f}–{hi:.0f} px" for lo, hi in expected_px)),
                       h)
    # consistency between bands: polarity, width, straight centre line
    sign = 1.0 if sum(q.sign for _, q in chosen) >= 0 else -1.0
    widths = np.array([q.right - q.left for _, q in chosen])
    w_med = float(np.median(widths))
    tol = max(_BAND_TOL_PX, _BAND_TOL_FRACTION * w_med)
    agree = [(b, q) for b, q in chosen
             if q.sign == sign and abs(q.right - q.left - w_med) <= tol]
    if len(agree) >= 2:
        yc = np.array([0.5 * (bounds[b] + bounds[b + 1]) for b, _ in agree])
        cc = np.array([0.5 * (q.left + q.right) for _, q in agree])
        off = np.abs(cc - _line_at(yc, cc, yc))
        agree = [bq for bq, o in zip(agree, off, strict=True) if o <= tol]
    agree_ids = {b for b, _ in agree}
    for b, q in chosen:
        if b not in agree_ids:
            rejected.append((int(bounds[b]), int(bounds[b + 1]), q.left, q.right,
                             "disagrees with the other rows"))
    n_disagree = len(chosen) - len(agree) + n_ambiguous
    n_found = len(chosen) + n_ambiguous
    if not agree or 4 * n_disagree > n_found or 2 * len(agree) < n_bands:
        return _refuse("ambiguous", f"filament edges agree in {len(agree)} of {n_bands} row "
                       f"bands ({n_disagree} ambiguous or disagreeing)", h,
                       rejected=tuple(rejected))
    # per row: the derivative extremum near the straight lines through the bands' edges
    yc = np.array([0.5 * (bounds[b] + bounds[b + 1] - 1) for b, _ in agree])
    bl = np.array([q.left for _, q in agree])
    br = np.array([q.right for _, q in agree])
    rows = np.concatenate([np.arange(bounds[b], bounds[b + 1]) for b, _ in agree])
    yf = rows.astype(np.float64)
    pred_l, pred_r = _line_at(yc, bl, yf), _line_at(yc, br, yf)
    scatter = max(float(np.max(np.abs(bl - _line_at(yc, bl, yc)))),
                  float(np.max(np.abs(br - _line_at(yc, br, yc)))))
    r = max(2, math.ceil(2.0 * sigma_px)) + 1 + min(math.ceil(scatter), 2)
    band_s = np.concatenate([np.full(bounds[b + 1] - bounds[b], q.strength)
                             for b, q in agree])
    offs = np.arange(-r, r + 1)
    il = np.clip(np.rint(pred_l).astype(np.intp)[:, None] + offs, 1, w - 2)
    ir = np.clip(np.rint(pred_r).astype(np.intp)[:, None] + offs, 1, w - 2)
    dl = sign * d[rows[:, None], il]
    dr = -sign * d[rows[:, None], ir]
    kl, kr = np.argmax(dl, axis=1), np.argmax(dr, axis=1)
    n = rows.size
    sl, sr = dl[np.arange(n), kl], dr[np.arange(n), kr]
    xl = _subpixel(sign * d[rows], il[np.arange(n), kl])
    xr = _subpixel(-sign * d[rows], ir[np.arange(n), kr])
    floor = np.maximum(min_edge_dn_px, _ROW_STRENGTH_FRACTION * band_s)
    good_l = (sl >= floor) & (kl > 0) & (kl < 2 * r)
    good_r = (sr >= floor) & (kr > 0) & (kr < 2 * r)
    fit_l, keep_l = _edge_line(yf, xl, good_l)
    fit_r, keep_r = _edge_line(yf, xr, good_r)
    both = keep_l & keep_r
    row_left = np.full(h, math.nan)
    row_right = np.full(h, math.nan)
    row_left[rows] = np.where(good_l, xl, math.nan)
    row_right[rows] = np.where(good_r, xr, math.nan)
    row_used = np.zeros(h, bool)
    row_used[rows[both]] = True
    used = int(min(keep_l.sum(), keep_r.sum()))
    strength = float(np.median(np.minimum(sl, sr)[both])) if both.any() else math.nan
    if fit_l is None or fit_r is None or used < max(3, min_rows_frac * h):
        return EdgeMeasurement(math.nan, math.nan, math.nan, math.nan, strength, used, False,
                               f"straight filament edges found in only {used} of {h} rows",
                               "few_rows", math.nan, row_left, row_right, row_used,
                               tuple(rejected))
    if abs(fit_r[0] - fit_l[0]) * h > _PARALLEL_TOL_PX + _PARALLEL_TOL_FRACTION * h:
        return EdgeMeasurement(math.nan, math.nan, math.nan, math.nan, strength, used, False,
                               "the two edges are not parallel "
                               f"({abs(fit_r[0] - fit_l[0]) * h:.1f} px over {h} rows)",
                               "ambiguous", math.nan, row_left, row_right, row_used,
                               tuple(rejected))
    lines = (fit_l, fit_r)
    y_mid = 0.5 * (h - 1)
    half = 0.5 * ((fit_r[0] - fit_l[0]) * y_mid + fit_r[1] - fit_l[1])
    profiles = edge_profiles(crop.astype(np.float32), (rows[keep_l], rows[keep_r]), lines,
                             sign, half)
    spread = float(np.std(xr[both] - xl[both])) if both.sum() > 1 else math.nan
    diag = _Diagnostics(strength, used, spread, row_left, row_right, row_used,
                        tuple(rejected), lines, sign,
                        (_scatter(yf, xl, good_l, fit_l), _scatter(yf, xr, good_r, fit_r)))
    if not fit and blur_px is not None:
        return _pending(diag, profiles, float(blur_px))
    return _silhouette_width(diag, profiles, h, expected_px, blur_px, mix)


@dataclass(frozen=True, slots=True)
class _Diagnostics:
    """What the edge search found, carried into the result."""

    strength: float
    used: int
    spread: float
    row_left: F64
    row_right: F64
    row_used: npt.NDArray[np.bool_]
    rejected: tuple[tuple[int, int, float, float, str], ...]
    lines: tuple[tuple[float, float], tuple[float, float]]
    polarity: float
    scatter: tuple[float, float]


def _scatter(y: F64, x: F64, good: npt.NDArray[np.bool_], line: tuple[float, float]) -> float:
    """Robust scatter (1.4826·MAD) of the rows' edge points about an edge line, px."""
    res = x[good] - (line[0] * y[good] + line[1])
    return float(1.4826 * np.median(np.abs(res - np.median(res)))) if res.size else math.nan


def _pending(d: _Diagnostics, profiles: tuple[EdgeProfile, EdgeProfile], blur_px: float
             ) -> EdgeMeasurement:
    """Edges found, silhouettes not fitted yet (:func:`refit_widths` fits them)."""
    (al, bl), (ar, br) = d.lines
    y_mid = 0.5 * (d.row_used.size - 1)
    cos_t = math.cos(math.atan(0.5 * (al + ar)))
    gradient = ((ar - al) * y_mid + br - bl) * cos_t
    sil = Silhouette(NO_FIT, NO_FIT, profiles, d.polarity, False, "not fitted yet")
    return EdgeMeasurement(math.nan, math.nan, math.nan, math.nan, d.strength, d.used, False,
                           "silhouettes not fitted yet", "pending", d.spread, d.row_left,
                           d.row_right, d.row_used, d.rejected, gradient, blur_px, d.lines,
                           sil, d.scatter)


def _silhouette_width(d: _Diagnostics, profiles: tuple[EdgeProfile, EdgeProfile], h: int,
                      expected_px: Sequence[tuple[float, float]] | None,
                      blur_px: float | None, mix: tuple[float, float] | None = None,
                      sil: Silhouette | None = None) -> EdgeMeasurement:
    """The width between the fitted silhouettes at the ROI's middle row, or a refusal
    (``sil``: the silhouettes when already fitted)."""
    (al, bl), (ar, br) = d.lines
    y_mid = 0.5 * (h - 1)
    tilt = math.atan(0.5 * (al + ar))
    cos_t = math.cos(tilt)
    grad_left, grad_right = al * y_mid + bl, ar * y_mid + br
    gradient = (grad_right - grad_left) * cos_t
    if sil is None:
        sil = fit_silhouette(profiles, d.polarity, blur_px=blur_px, mix=mix)

    def refuse(status: str, reason: str, width: float = math.nan) -> EdgeMeasurement:
        return EdgeMeasurement(math.nan, math.nan, math.nan, math.nan, d.strength, d.used,
                               False, reason, status, d.spread, d.row_left, d.row_right,
                               d.row_used, d.rejected, gradient, sil.left.blur_px, d.lines,
                               sil, d.scatter)

    if not sil.ok:
        return refuse("ambiguous", sil.reason)
    left = grad_left + sil.left.offset_px
    right = grad_right + sil.right.offset_px
    width = (right - left) * cos_t
    if expected_px is not None and not any(lo <= width <= hi for lo, hi in expected_px):
        return refuse("no_edges", f"the edges' width {width:.1f} px is outside the expected "
                      + ", ".join(f"{lo:.0f}–{hi:.0f} px" for lo, hi in expected_px))
    return EdgeMeasurement(width, left, right, tilt, d.strength, d.used, True, "", "ok",
                           d.spread, d.row_left, d.row_right, d.row_used, d.rejected,
                           gradient, sil.left.blur_px, d.lines, sil, d.scatter)


def refit_widths(ems: Sequence[EdgeMeasurement], blur_px: float, h: int,
                 expected_px: Sequence[tuple[float, float]] | None = None,
                 mix: tuple[float, float] | None = None) -> list[EdgeMeasurement]:
    """The same measurements with the silhouettes refitted at a known blur (all frames
    in one pass, :func:`~flowtwin.vision.silhouette.fit_silhouettes`).

    Parameters
    ----------
    ems
        Measurements; those whose edges were not found (``silhouette`` ``None``) are
        returned unchanged.
    blur_px
        The blur σ (optics and pixel), px.
    h
        Height of the crop, rows.
    expected_px
        Plausible widths, as for :func:`measure_width_px`.
    mix
        Known limb shapes, as for :func:`measure_width_px`.

    Returns
    -------
    list of EdgeMeasurement
        The refitted measurements, in the order given.
    """
    todo = [(i, em.silhouette, em.lines) for i, em in enumerate(ems)
            if em.silhouette is not None and em.lines is not None]
    sils = fit_silhouettes([(sl.profiles, sl.polarity) for _, sl, _ in todo if sl is not None],
                           blur_px, mix)
    out = list(ems)
    for (i, _, lines), sil in zip(todo, sils, strict=True):
        em = ems[i]
        if lines is None:
            continue
        d = _Diagnostics(em.edge_dn_px, em.rows_used, em.row_spread_px, em.row_left_px,
                         em.row_right_px, em.row_used, em.rejected, lines, sil.polarity,
                         em.edge_scatter_px)
        out[i] = _silhouette_width(d, sil.profiles, h, expected_px, blur_px, mix, sil)
    return out


def refit_width(em: EdgeMeasurement, blur_px: float, h: int,
                expected_px: Sequence[tuple[float, float]] | None = None,
                mix: tuple[float, float] | None = None) -> EdgeMeasurement:
    """One measurement refitted at a known blur (:func:`refit_widths`)."""
    return refit_widths([em], blur_px, h, expected_px, mix)[0]


def _fit_line(y: F64, x: F64) -> tuple[float, float]:
    """Least-squares ``x = a·y + b`` (``a = 0`` for a single ``y``)."""
    ym = float(y.mean())
    dy = y - ym
    den = float(dy @ dy)
    a = float(dy @ x) / den if den > 0 else 0.0
    return a, float(x.mean()) - a * ym


def _line_at(y: F64, x: F64, at: F64) -> F64:
    """The least-squares line through ``(y, x)`` evaluated at ``at``."""
    a, b = _fit_line(y, x)
    return a * at + b


def _edge_line(y: F64, x: F64, good: npt.NDArray[np.bool_]
               ) -> tuple[tuple[float, float] | None, npt.NDArray[np.bool_]]:
    """Robust straight line along one edge, and the rows on it.

    Least squares, then twice: keep the rows within :data:`_ROW_LINE_TOL_PX` of the line
    (or 3 robust sigma, if wider) and refit. A tooth mark or speck that moves a few rows'
    edge drops out.
    """
    keep = good.copy()
    for _ in range(3):
        if keep.sum() < 3:
            return None, keep
        a, b = _fit_line(y[keep], x[keep])
        res = x - (a * y + b)
        mad = float(np.median(np.abs(res[keep])))
        keep = good & (np.abs(res) <= max(_ROW_LINE_TOL_PX, 3 * 1.4826 * mad))
    if keep.sum() < 3:
        return None, keep
    return _fit_line(y[keep], x[keep]), keep


def calibration_factor(known_width_mm: float, detected_width_px: float) -> float:
    """Image scale from a filament of known width: ``k_cal = w_µ / w_detected`` [003 Eq. 4].

    Parameters
    ----------
    known_width_mm
        Width measured with a micrometer, mm.
    detected_width_px
        Width detected in the image, px.

    Returns
    -------
    float
        ``k_cal``, mm/px.

    Raises
    ------
    VisionError
        If either width is not a positive finite number.
    """
    if not (math.isfinite(known_width_mm) and known_width_mm > 0):
        raise VisionError("calibration width must be positive", field="calib_width_mm",
                          value=known_width_mm, allowed="> 0 mm")
    if not (math.isfinite(detected_width_px) and detected_width_px > 0):
        raise VisionError("no filament width was detected to calibrate against",
                          field="calib_width_mm", value=detected_width_px,
                          allowed="a before ROI spanning both filament edges")
    return known_width_mm / detected_width_px
