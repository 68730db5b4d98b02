"""Bead width along a printed line, measured in an image straightened onto the bed.

:func:`sample_strip` resamples the image along one printed line on the bed's own grid
through the homography bed → image (``cv2.remap``): rows across the bead every ``dv`` mm,
columns along it. Rotation, scale and perspective are gone; a width in rows is a width in
mm. Two measurements of the width of each column:

* ``"area"`` (default): the bead's darkness integrated across it,
  ``w = Σ (B − I)/(B − D) · dv`` with ``B`` the bed's grey level beside the bead (per
  column: the median of the strip's outer fifths, so uneven lighting cancels) and ``D`` the
  bead's own level (one value for the whole pattern, :func:`dark_level`). Blur moves grey
  across the edges but keeps the integral, so the width is unbiased by blur and by the
  pixel grid. A wrong ``D`` scales every width by the same factor, which the lag fit's
  gain absorbs. Measured on images rendered from the twin (docs/calibration.md): exact
  to 1e-4 mm when sharp, at 12 px/mm and a 1.2 px blur the profile shape within 0.0012 mm
  RMS (plus a common 4 % scale).
* ``"edges"``: the two strongest slopes of the Gaussian-smoothed profile across the bead,
  to sub-sample precision (the derivative-extrema method of [003 §2.2], docs/spec.md §3.7,
  vectorised over the columns). It needs no dark level, but a sharp image locks the edges
  to the pixel grid (±0.25 px) and blur pulls the edges of a narrow bead together: on the
  same renders its profile errs by 0.003–0.005 mm RMS with a shape-dependent bias.

Widths of ``per`` neighbouring columns are averaged into one sample of ``step_mm``
(:func:`window_widths`); a window where part of the bead is missing (a gap: width below
half the layer height) has no width.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

__all__ = ["Strip", "area_widths", "dark_level", "edge_widths", "sample_strip",
           "window_widths"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Strip:
    """An image resampled along one printed line on the bed grid.

    Attributes
    ----------
    values
        Grey levels, shape ``(n_across, n_along)``; row ``i`` at ``v = −half + i·dv``.
    dv_mm
        Spacing of the rows and columns, mm.
    per
        Columns per width sample.
    positions_mm
        Centre of each sample window along the line, mm, shape ``(n_windows,)``.
    """

    values: npt.NDArray[np.float32]
    dv_mm: float
    per: int
    positions_mm: FloatArray


def sample_strip(gray32: npt.NDArray[np.float32], homography: FloatArray,
                 start_xy_mm: FloatArray, end_xy_mm: FloatArray, *, step_mm: float,
                 half_span_mm: float, dv_mm: float) -> Strip:
    """Resample the image along the bed segment ``start → end``.

    Parameters
    ----------
    gray32
        Grey image as float32, shape ``(H, W)``.
    homography
        Bed (mm) → image (px), 3 × 3.
    start_xy_mm, end_xy_mm
        The line's path on the bed, mm, shape ``(2,)``.
    step_mm
        Length of a width sample along the line, mm.
    half_span_mm
        The strip reaches this far to each side of the path, mm.
    dv_mm
        Sampling interval, mm (half an image pixel or less).

    Returns
    -------
    Strip
    """
    a = np.asarray(start_xy_mm, dtype=np.float64)
    b = np.asarray(end_xy_mm, dtype=np.float64)
    length = float(np.hypot(*(b - a)))
    d = (b - a) / length
    nrm = np.array([-d[1], d[0]])
    per = max(2, int(round(step_mm / dv_mm)))
    n_win = int(length // step_mm)
    s = (np.arange(n_win * per) + 0.5) * (step_mm / per)
    v = np.arange(-half_span_mm, half_span_mm + 0.5 * dv_mm, dv_mm)
    pts = (a[None, None, :] + s[None, :, None] * d[None, None, :]
           + v[:, None, None] * nrm[None, None, :])
    img_pts = cv2.perspectiveTransform(pts.reshape(-1, 1, 2), homography).reshape(
        v.size, s.size, 2).astype(np.float32)
    values = cv2.remap(gray32, img_pts[..., 0], img_pts[..., 1], cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_REPLICATE)
    return Strip(np.asarray(values, dtype=np.float32), dv_mm, per,
                 np.asarray((np.arange(n_win) + 0.5) * step_mm, dtype=np.float64))


def _background(values: npt.NDArray[np.float32]) -> FloatArray:
    q = max(2, values.shape[0] // 5)
    return np.asarray(np.median(np.vstack([values[:q], values[-q:]]), axis=0),
                      dtype=np.float64)


def dark_level(strips: list[Strip]) -> float:
    """Grey level of the bead itself, one value for all strips.

    The profile across each column is smoothed (sigma one sample) and its minimum taken;
    the bead's level is the median of the darker half of those minima over every column
    of every strip (the wide, steady parts of the beads, where the core is not blurred).
    """
    mins = np.concatenate([
        cv2.GaussianBlur(st.values, (0, 0), sigmaX=1.0, sigmaY=1.0).min(axis=0)
        for st in strips])
    dark = np.sort(mins)[: max(1, mins.size // 2)]
    return float(np.median(dark))


def area_widths(strip: Strip, dark_dn: float) -> FloatArray:
    """Width of every column from its integrated darkness, mm (module docstring).

    Parameters
    ----------
    strip
        The resampled line.
    dark_dn
        Grey level of the bead (:func:`dark_level`).

    Returns
    -------
    ndarray
        Width per column, mm, shape ``(n_along,)``; NaN where the bed is not lighter
        than the bead.
    """
    bg = _background(strip.values)
    contrast = bg - dark_dn
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = (bg[None, :] - strip.values) / contrast[None, :]
    w = np.sum(np.clip(frac, -0.5, 1.5), axis=0) * strip.dv_mm
    return np.asarray(np.where(contrast > 10.0, w, np.nan), dtype=np.float64)


def edge_widths(strip: Strip, *, smooth_px: float = 2.0,
                min_edge_fraction: float = 0.3) -> FloatArray:
    """Width of every column from the extrema of the derivative across it, mm.

    Each column is smoothed with a Gaussian (``smooth_px`` samples, also along the line),
    differentiated, and the bead's edges are the strongest falling and rising slopes (a
    dark bead: falling first), each located by a parabola through the extremum and its
    neighbours [003 §2.2].

    Parameters
    ----------
    strip
        The resampled line.
    smooth_px
        Gaussian sigma, samples.
    min_edge_fraction
        An edge weaker than this fraction of the strip's median edge strength is no edge
        (a gap in the bead).

    Returns
    -------
    ndarray
        Width per column, mm (NaN: no pair of edges).
    """
    img = cv2.GaussianBlur(strip.values, (0, 0), sigmaX=smooth_px, sigmaY=smooth_px)
    d = np.zeros_like(img)
    d[1:-1] = 0.5 * (img[2:] - img[:-2])
    cols = np.arange(d.shape[1])
    k_fall = np.argmin(d, axis=0)
    k_rise = np.argmax(d, axis=0)
    strength = np.minimum(-d[k_fall, cols], d[k_rise, cols])
    typical = float(np.median(strength))

    def peak(k: npt.NDArray[np.intp]) -> FloatArray:
        km = np.clip(k, 1, d.shape[0] - 2)
        a, b, c = (d[km - 1, cols].astype(np.float64), d[km, cols].astype(np.float64),
                   d[km + 1, cols].astype(np.float64))
        den = a - 2.0 * b + c
        with np.errstate(divide="ignore", invalid="ignore"):
            off = np.where(np.abs(den) > 1e-12, 0.5 * (a - c) / den, 0.0)
        return np.asarray(km + np.clip(off, -0.5, 0.5), dtype=np.float64)

    ok = (k_fall < k_rise) & (strength >= max(min_edge_fraction * typical, 1.0))
    ok &= (k_fall > 0) & (k_rise < d.shape[0] - 1)
    return np.asarray(np.where(ok, (peak(k_rise) - peak(k_fall)) * strip.dv_mm, np.nan),
                      dtype=np.float64)


def window_widths(column_widths: FloatArray, per: int, *, min_width_mm: float) -> FloatArray:
    """Mean width of each window of ``per`` columns; NaN if any column is a gap.

    Parameters
    ----------
    column_widths
        Width per column, mm, shape ``(n_windows·per,)``.
    per
        Columns per window.
    min_width_mm
        A column narrower than this (or without a width) is a gap.

    Returns
    -------
    ndarray
        Shape ``(n_windows,)``, mm.
    """
    win = column_widths.reshape(-1, per)
    ok = np.all(np.isfinite(win) & (win >= min_width_mm), axis=1)
    return np.asarray(np.where(ok, np.mean(np.where(ok[:, None], win, 0.0), axis=1), np.nan),
                      dtype=np.float64)
