"""The bead signal of a photo of a line pattern: direction, deskew, pitch, polarity.

A line pattern is many long, thin, parallel beads. Everything here uses that, and nothing
about the colours:

* **Direction.** The structure tensor of the image (products of the Sobel gradients,
  averaged over the image): a bead's two edges both have gradients across the lines, a
  textured sheet's speckle has gradients in all directions, so the dominant gradient
  direction is across the lines whatever their polarity. The image is turned so that the
  lines run along its rows (``cv2.warpAffine``; the affine map is kept).
* **Pitch.** The autocorrelation across the lines of the high-passed, deskewed image,
  averaged over columns: its first strong peak is the line pitch (px).
* **Bead signal.** A top-hat across the lines with a vertical structuring element of
  0.6 pitch: a light bead is ``I − open(I)``, a dark one ``close(I) − I``. It keeps bright
  (dark) structures *thinner* than 0.6 pitch across the lines — the beads — and removes
  the sheet's large-scale shading, glare patches and filled areas (taller than that), and
  the gaps between lines (wider than 0.6 pitch as long as the bead is narrower than 0.4
  pitch: 0.17 pitch on OrcaSlicer's pattern, 0.1 on Marlin's). Divided by the local
  brightness, so uneven lighting does not change it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.calibration.image.smooth import wide_gaussian

__all__ = ["Deskewed", "bead_signal", "deskew", "line_direction_deg", "pitch_px"]

FloatArray = npt.NDArray[np.float64]
F32 = npt.NDArray[np.float32]


def line_direction_deg(gray: npt.NDArray[np.uint8]) -> tuple[float, float]:
    """Direction of the lines in the image and how dominant it is.

    Returns
    -------
    angle_deg : float
        Angle of the lines from the image's +x axis (rows grow downwards), degrees in
        ``(−90, 90]``.
    coherence : float
        ``(λ1 − λ2)/(λ1 + λ2)`` of the mean structure tensor (0: no direction, 1: all
        gradients parallel).
    """
    g = cv2.GaussianBlur(gray.astype(np.float32), (0, 0), 1.0)
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3)
    jxx, jyy, jxy = float(np.mean(gx * gx)), float(np.mean(gy * gy)), float(np.mean(gx * gy))
    # gradient direction (across the lines) from the double-angle mean
    across = 0.5 * math.atan2(2.0 * jxy, jxx - jyy)
    tr = jxx + jyy
    coherence = math.hypot(jxx - jyy, 2.0 * jxy) / tr if tr > 0 else 0.0
    angle = math.degrees(across) + 90.0
    while angle > 90.0:
        angle -= 180.0
    while angle <= -90.0:
        angle += 180.0
    return angle, coherence


@dataclass(frozen=True)
class Deskewed:
    """The image turned so the lines run along the rows.

    Attributes
    ----------
    image
        Turned grey image (float32; outside the photo: NaN-free replicate border).
    valid
        1 where the turned image has photo pixels, shape as ``image``.
    forward
        2 × 3 affine map, original px → turned px.
    angle_deg
        Direction of the lines in the original image.
    """

    image: F32
    valid: npt.NDArray[np.uint8]
    forward: FloatArray

    angle_deg: float

    def to_original(self, pts: FloatArray) -> FloatArray:
        """Turned-image points ``(n, 2)`` → original image points."""
        inv = cv2.invertAffineTransform(self.forward)
        return np.asarray(pts @ inv[:, :2].T + inv[:, 2], dtype=np.float64)


def deskew(gray: npt.NDArray[np.uint8], angle_deg: float) -> Deskewed:
    """Turn ``gray`` by ``angle_deg`` so that lines at that angle run along the rows."""
    h, w = gray.shape
    c = (w / 2.0, h / 2.0)
    rot = cv2.getRotationMatrix2D(c, angle_deg, 1.0)
    cos, sin = abs(rot[0, 0]), abs(rot[0, 1])
    nw, nh = int(math.ceil(w * cos + h * sin)), int(math.ceil(w * sin + h * cos))
    rot[0, 2] += nw / 2.0 - c[0]
    rot[1, 2] += nh / 2.0 - c[1]
    img = cv2.warpAffine(gray.astype(np.float32), rot, (nw, nh), flags=cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REPLICATE)
    valid = cv2.warpAffine(np.full((h, w), 255, np.uint8), rot, (nw, nh),
                           flags=cv2.INTER_NEAREST, borderValue=0)
    return Deskewed(np.asarray(img, dtype=np.float32), (valid > 0).astype(np.uint8),
                    np.asarray(rot, dtype=np.float64), angle_deg)


def pitch_px(turned: F32, valid: npt.NDArray[np.uint8]) -> float:
    """Line pitch of the deskewed image, px (first strong autocorrelation peak across rows).

    Returns NaN when the rows show no periodic structure.
    """
    h, _ = turned.shape
    hp = turned - wide_gaussian(turned, max(4.0, h / 40.0))
    hp = np.where(valid > 0, hp, 0.0).astype(np.float32)
    # column strips: average a few columns so each strip's profile is less noisy
    cols = np.flatnonzero(valid.sum(axis=0) > 0.8 * valid.sum(axis=0).max())
    if cols.size < 8:
        return math.nan
    prof = hp[:, cols]
    n = int(2 ** math.ceil(math.log2(2 * h)))
    spec = np.fft.rfft(prof - prof.mean(axis=0), n=n, axis=0)
    ac = np.fft.irfft(np.mean(np.abs(spec) ** 2, axis=1), n=n)[: h // 2]
    if ac[0] <= 0:
        return math.nan
    ac = ac / ac[0]
    # the first local maximum after the first minimum, if strong enough
    d = np.diff(ac)
    minima = np.flatnonzero((d[:-1] < 0) & (d[1:] >= 0)) + 1
    if minima.size == 0:
        return math.nan
    start = int(minima[0])
    peak = start + int(np.argmax(ac[start:]))
    maxima = np.flatnonzero((d[start:-1] > 0) & (d[start + 1:] <= 0)) + start + 1
    strong = [int(m) for m in maxima if ac[m] > 0.5 * ac[peak]]
    if not strong or ac[strong[0]] < 0.05:
        return math.nan
    m = strong[0]
    if 0 < m < ac.size - 1:
        a, b, cc = ac[m - 1], ac[m], ac[m + 1]
        den = a - 2 * b + cc
        return float(m + (0.5 * (a - cc) / den if abs(den) > 1e-12 else 0.0))
    return float(m)


def bead_signal(turned: F32, valid: npt.NDArray[np.uint8], pitch: float, *,
                light: bool, isotropic: bool = False, element_pitches: float = 0.6) -> F32:
    """Top-hat across the lines (module docstring), divided by the local brightness.

    Parameters
    ----------
    turned, valid
        Deskewed image and its valid mask (:func:`deskew`).
    pitch
        Line pitch, px.
    light
        Beads lighter than the sheet (``False``: darker).
    isotropic
        A disc instead of the vertical element: keeps thin beads in every direction (the
        pattern's marks: prime lines, reference marks, digits).
    element_pitches
        Length of the element, pitches: between the bead's width and the gap's (0.6 for
        line patterns, whose beads are a fifth of the pitch or less; half a pitch for
        chevrons, whose bands of touching walls are 0.4 of it).

    Returns
    -------
    ndarray
        float32, ≥ 0, about the bead/sheet contrast as a fraction of the brightness on
        the beads, 0 on the sheet.
    """
    length = max(3, int(round(element_pitches * pitch)) | 1)
    se = (cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (length, length)) if isotropic
          else cv2.getStructuringElement(cv2.MORPH_RECT, (1, length)))
    if light:
        th = turned - cv2.morphologyEx(turned, cv2.MORPH_OPEN, se)
    else:
        th = cv2.morphologyEx(turned, cv2.MORPH_CLOSE, se) - turned
    bright = wide_gaussian(turned, max(2.0, 2.0 * pitch))
    floor = max(8.0, float(np.percentile(turned[valid > 0], 99.0)) * 0.05)
    out = th / np.maximum(bright, floor)
    out[valid == 0] = 0.0
    return np.asarray(np.clip(out, 0.0, None), dtype=np.float32)
