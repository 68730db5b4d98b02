"""Bead widths along the lines of a photo, independent of the lighting and the sheet.

The image is resampled along each test line on the bed grid
(:func:`flowtwin.calibration.image.beadwidth.sample_strip`: rows across the bead every ``dv``
mm, columns along it). In a photo the light is not even — it falls off across the
print, a glossy sheet reflects a window — and the sheet is textured. Both matter to an
integrated-contrast width ``w = Σ (B − I)/(B − D)·dv`` with one bead level ``D`` for the
whole photo: a light level that changes along a line scales the widths along it, and
the changes a test line is scored on (a few per cent after each speed step) are of that
size. So:

* the sheet's level ``B`` beside the bead, per column, is the median of the strip
  outside the bead's band (between the band and half way to the neighbouring line),
  then a running median along the line over :data:`SHEET_SMOOTH_MM` (the texture of a
  PEI sheet averages out; the light changes over centimetres);
* the bead's contrast ``C = ±(I − B)`` (``+`` for beads lighter than the sheet);
* the width of a column is ``w = Σ C/C_bead · dv`` over the bead's band only
  (:func:`band_half_mm`: the bead and a margin for a bulge and for the registration;
  outside it the sheet's texture would only add noise), with ``C_bead`` the bead's own
  contrast followed along each line: the running median of the column peaks over
  :data:`BEAD_LOCAL_MM` (:func:`local_bead_contrast`, within 0.4–2.5 × the photo's
  value from the cores of the widest columns, as
  :func:`flowtwin.calibration.image.beadwidth.dark_level`). A light level ``L(x)`` multiplies
  ``C`` and ``C_bead`` alike and cancels; so does glare, which is not a multiplicative
  light (a reflection adds to a glossy bead more than to a matt sheet and lowers a dark
  bead's contrast where it falls: a fifth under a moderate highlight on the renders).
  The contrast is not divided by the sheet's level: on a black sheet (photos edited to
  a black background) that level is zero.

A bead narrower than about three blur widths does not reach its contrast in its core;
where a thin stretch is that narrow the local ``C_bead`` follows it partly and the width
change reads smaller, but a line that stays even (the best line) reads even either way.
Blur moves contrast across the bead's edges but keeps its integral, so the width is
unbiased by blur as long as the blurred bead stays inside its band.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt
from scipy.ndimage import median_filter

from flowtwin.calibration.image.beadwidth import Strip, sample_strip

__all__ = ["BEAD_LOCAL_MM", "SHEET_SMOOTH_MM", "ContrastStrip", "band_half_mm",
           "bead_contrast", "contrast_strip", "contrast_widths", "local_bead_contrast"]

FloatArray = npt.NDArray[np.float64]

#: Length along the line over which the sheet's level is smoothed (running median), mm.
SHEET_SMOOTH_MM = 1.5
#: Length along the line over which the bead's own contrast is followed (running median
#: of the column peaks), mm: longer than a width transient's thin or thick part.
BEAD_LOCAL_MM = 10.0


def band_half_mm(line_width_mm: float, pitch_mm: float) -> float:
    """Half-width of the band a bead's contrast is integrated over, mm.

    Wide enough for a bead three times its nominal width (the twin's cap where the
    nozzle nearly stops) and for a registration error of a few tenths of a millimetre,
    never more than 0.4 of the line pitch (the neighbouring line's band).
    """
    return float(min(0.4 * pitch_mm, max(1.5 * line_width_mm, 0.5 * line_width_mm + 0.5)))


@dataclass(frozen=True)
class ContrastStrip:
    """One line's strip as contrast relative to the local sheet.

    Attributes
    ----------
    strip
        The resampled grey levels (:class:`~flowtwin.calibration.image.beadwidth.Strip`).
    contrast
        ``±(I − B)``, grey levels, positive on the bead, shape as ``strip.values``.
    v_mm
        Position of each row across the line, mm, shape ``(n_across,)``.
    band_mm
        Half-width of the bead's band, mm.
    """

    strip: Strip
    contrast: npt.NDArray[np.float32]
    v_mm: FloatArray
    band_mm: float

    @property
    def in_band(self) -> npt.NDArray[np.bool_]:
        """Rows inside the bead's band."""
        return np.asarray(np.abs(self.v_mm) <= self.band_mm + 1e-9, dtype=np.bool_)


def contrast_strip(gray32: npt.NDArray[np.float32], homography: FloatArray,
                   start_xy_mm: FloatArray, end_xy_mm: FloatArray, *, light: bool,
                   step_mm: float, band_mm: float, half_span_mm: float,
                   dv_mm: float) -> ContrastStrip:
    """Resample one line and turn it into contrast against the local sheet.

    Parameters
    ----------
    gray32
        The photo's grey levels (not inverted), float32, shape ``(H, W)``.
    homography
        Bed (mm) → image (px).
    start_xy_mm, end_xy_mm
        The line's path, mm.
    light
        Beads lighter than the sheet.
    step_mm, dv_mm
        Width sample length along the line; sample spacing, mm.
    band_mm, half_span_mm
        Half-width of the bead's band and of the whole strip (the sheet between them).

    Returns
    -------
    ContrastStrip
    """
    half = max(half_span_mm, band_mm + 2.0 * dv_mm)
    st = sample_strip(gray32, homography, start_xy_mm, end_xy_mm, step_mm=step_mm,
                      half_span_mm=half, dv_mm=dv_mm)
    v = -half + np.arange(st.values.shape[0]) * dv_mm
    outside = np.abs(v) > band_mm
    sheet = np.median(st.values[outside], axis=0).astype(np.float64)
    k = max(3, int(round(SHEET_SMOOTH_MM / dv_mm)) | 1)
    sheet = median_filter(sheet, size=k, mode="nearest")
    c = st.values - sheet[None, :]
    if not light:
        c = -c
    return ContrastStrip(st, np.asarray(c, dtype=np.float32), np.asarray(v, dtype=np.float64),
                         float(band_mm))


def bead_contrast(strips: list[ContrastStrip]) -> float:
    """The bead's own contrast, one value for the photo.

    Each column's profile across the band is smoothed (sigma one sample) and its maximum
    taken; the bead's contrast is the median of the upper half of those maxima over
    every column of every strip (the wide, steady parts of the beads, whose cores blur
    does not reach).
    """
    peaks = np.concatenate([
        cv2.GaussianBlur(cs.contrast[cs.in_band], (0, 0), sigmaX=1.0, sigmaY=1.0).max(axis=0)
        for cs in strips])
    peaks = peaks[np.isfinite(peaks)]
    if peaks.size == 0:
        return float("nan")
    top = np.sort(peaks)[peaks.size // 2:]
    return float(np.median(top))


def local_bead_contrast(cs: ContrastStrip, bead: float) -> FloatArray:
    """The bead's contrast along one line (module docstring), shape ``(n_along,)``."""
    band = cs.contrast[cs.in_band]
    peaks = cv2.GaussianBlur(band, (0, 0), sigmaX=1.0, sigmaY=1.0).max(axis=0)
    k = max(3, int(round(BEAD_LOCAL_MM / cs.strip.dv_mm)) | 1)
    local = median_filter(peaks.astype(np.float64), size=k, mode="nearest")
    return np.asarray(np.clip(local, 0.4 * bead, 2.5 * bead), dtype=np.float64)


def contrast_widths(cs: ContrastStrip, bead: float, *, local: bool = True) -> FloatArray:
    """Width of every column, ``Σ C/C_bead · dv`` over the band, mm; NaN without contrast.

    Parameters
    ----------
    cs
        The line's contrast strip.
    bead
        The photo's bead contrast (:func:`bead_contrast`).
    local
        Follow the bead's contrast along the line (:func:`local_bead_contrast`).

    Returns
    -------
    ndarray
        Shape ``(n_along,)``, mm.
    """
    if not bead > 2.0:
        return np.full(cs.contrast.shape[1], np.nan)
    ref = local_bead_contrast(cs, bead) if local else np.full(cs.contrast.shape[1], bead)
    frac = np.clip(cs.contrast[cs.in_band] / ref[None, :], -0.5, 1.5)
    return np.asarray(np.sum(frac, axis=0) * cs.strip.dv_mm, dtype=np.float64)
