"""Filament width from the extrema of the first derivative across it [003 §2.2].

Each row of the ``before`` ROI is smoothed across the filament with a Gaussian and
differentiated; the filament's two edges are the largest rising and falling slopes (which
is which depends on whether the filament is brighter or darker than the background),
located to sub-pixel precision by a parabola through the extremum and its neighbours.
Rows whose edge slope is weak or whose width disagrees with the others are dropped; a
straight line through the centre points gives the tilt of the filament, and the width
is corrected to the perpendicular width ``w·cos(tilt)``. The image scale follows from a
known width, ``k_cal = w_µ / w_detected`` [003 Eq. 4].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.errors import VisionError

__all__ = ["EdgeMeasurement", "calibration_factor", "measure_width_px"]

#: A row's width is an outlier (a texture blotch taken for an edge) only if it is this
#: far from the median row, px; real width changes within a ROI are smaller.
_ROW_OUTLIER_PX = 2.0


@dataclass(frozen=True, slots=True)
class EdgeMeasurement:
    """Result of one width measurement in one image crop.

    Attributes
    ----------
    width_px
        Perpendicular filament width, px (NaN if not ``ok``).
    left_px, right_px
        Mean edge columns in crop coordinates, px.
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
    """

    width_px: float
    left_px: float
    right_px: float
    tilt_rad: float
    edge_dn_px: float
    rows_used: int
    ok: bool
    reason: str = ""


def _parabola_peak(d: npt.NDArray[np.float32], k: npt.NDArray[np.intp]) -> npt.NDArray[np.float64]:
    """Sub-pixel position of the extremum at index ``k`` of each row of ``d``."""
    rows = np.arange(d.shape[0])
    km = np.clip(k, 1, d.shape[1] - 2)
    a, b, c = (d[rows, km - 1].astype(np.float64), d[rows, km].astype(np.float64),
               d[rows, km + 1].astype(np.float64))
    den = a - 2.0 * b + c
    with np.errstate(divide="ignore", invalid="ignore"):
        off = np.where(np.abs(den) > 1e-12, 0.5 * (a - c) / den, 0.0)
    return km + np.clip(off, -0.5, 0.5)


def measure_width_px(crop: npt.NDArray[np.uint8], *, sigma_px: float = 0.7,
                     min_edge_dn_px: float = 3.0, min_rows_frac: float = 0.5
                     ) -> EdgeMeasurement:
    """Measure the filament width in a crop that spans both edges [003 §2.2].

    Parameters
    ----------
    crop
        Grey image of the ``before`` ROI, shape ``(H, W)``, uint8, filament roughly
        vertical with background on both sides.
    sigma_px
        Gaussian smoothing across the filament before differentiation, px.
    min_edge_dn_px
        Weakest accepted edge slope, DN/px.
    min_rows_frac
        Smallest fraction of rows with two good edges for a valid result.

    Returns
    -------
    EdgeMeasurement
        Width in px and diagnostics; ``ok`` is false (and the width NaN) when the edges
        cannot be found, never a guessed number.
    """
    h, w = crop.shape[:2]
    img = np.asarray(cv2.GaussianBlur(crop.astype(np.float32), (0, 0), sigmaX=sigma_px,
                                      sigmaY=1e-3), dtype=np.float32)
    d = np.zeros_like(img)
    d[:, 1:-1] = 0.5 * (img[:, 2:] - img[:, :-2])
    d[:, :2] = 0.0
    d[:, -2:] = 0.0
    # polarity from the mean profile: bright filament rises on the left
    mean_d = d.mean(axis=0)
    k_max, k_min = int(np.argmax(mean_d)), int(np.argmin(mean_d))
    bright = k_max < k_min
    lo_edge, hi_edge = (k_max, k_min) if bright else (k_min, k_max)
    sep = hi_edge - lo_edge
    if sep < 3 or min(abs(mean_d[k_max]), abs(mean_d[k_min])) < 0.5 * min_edge_dn_px:
        return EdgeMeasurement(math.nan, math.nan, math.nan, math.nan,
                               float(max(abs(mean_d[k_max]), abs(mean_d[k_min]))), 0, False,
                               "no pair of filament edges in the ROI")
    # per row: search each edge near the mean-profile edge
    band = max(4, sep // 4)
    sign = 1.0 if bright else -1.0
    left_win = slice(max(1, lo_edge - band), min(w - 1, lo_edge + band + 1))
    right_win = slice(max(1, hi_edge - band), min(w - 1, hi_edge + band + 1))
    dl = sign * d[:, left_win]
    dr = -sign * d[:, right_win]
    kl, kr = np.argmax(dl, axis=1), np.argmax(dr, axis=1)
    rows = np.arange(h)
    strength = np.minimum(dl[rows, kl], dr[rows, kr])
    xl = _parabola_peak(dl, kl) + left_win.start
    xr = _parabola_peak(dr, kr) + right_win.start
    good = strength >= min_edge_dn_px
    widths = xr - xl
    if good.sum() >= 3:
        med = float(np.median(widths[good]))
        mad = float(np.median(np.abs(widths[good] - med)))
        good &= np.abs(widths - med) <= max(3 * 1.4826 * mad, _ROW_OUTLIER_PX)
    n = int(good.sum())
    if n < max(3, min_rows_frac * h):
        return EdgeMeasurement(math.nan, math.nan, math.nan, math.nan,
                               float(np.median(strength)), n, False,
                               f"filament edges found in only {n} of {h} rows")
    y = rows[good].astype(np.float64)
    centre = 0.5 * (xl[good] + xr[good])
    slope = float(np.polyfit(y, centre, 1)[0]) if np.ptp(y) > 0 else 0.0
    tilt = math.atan(slope)
    width = float(np.mean(widths[good])) * math.cos(tilt)
    return EdgeMeasurement(width, float(np.mean(xl[good])), float(np.mean(xr[good])), tilt,
                           float(np.median(strength[good])), n, True)


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
