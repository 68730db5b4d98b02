"""Wide smoothing filters of a photo, made on a coarser grid.

The line reader's local levels (the brightness a bead is divided by, the strongest beads
around a point) are filters two pitches wide: a Gaussian of σ = 2 pitches and a disc of
radius 2 pitches. OpenCV applies them at full resolution with a kernel of ~8σ taps per
pass (the Gaussian) or every pixel of the disc (a non-rectangular dilation), so at a
pitch of 50 px they take seconds per call, and most of the reading's time (measured on a
2 MP render of the Prusa pattern: 8.5 of 15 s). What they give is smooth on the scale of
a pitch, so they are computed on a grid ``f`` times coarser (``f`` chosen so the filter
still spans :data:`COARSE_SIGMA_PX` or :data:`COARSE_RADIUS_PX` coarse pixels) and brought
back by linear interpolation:

* :func:`wide_gaussian`: area averaging down (a box of ``f``, variance ``f²/12``), a
  Gaussian of ``σ_c`` there, linear interpolation up (a triangle of ``f``, variance
  ``f²/6``): ``σ² = f²·σ_c² + f²/4``, solved for ``σ_c``, so the full-resolution σ is the one
  asked for.
* :func:`local_max`: the maximum over blocks of ``f × f`` pixels, a disc dilation of radius
  ``radius/f`` on the blocks, then the same Gaussian as above and linear interpolation up.
  The disc is exact to about a block (``f`` ≤ radius/40: 2.5 % of the radius).

Below the sizes where the coarse grid helps, both are OpenCV's own filters unchanged.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import numpy.typing as npt

__all__ = ["COARSE_RADIUS_PX", "COARSE_SIGMA_PX", "local_max", "wide_gaussian"]

F32 = npt.NDArray[np.float32]

#: A Gaussian of σ at least three times this is made on a grid ``f = ⌊σ/this⌋`` times
#: coarser, where its σ is still at least this many pixels.
COARSE_SIGMA_PX = 4.0
#: A disc of radius at least twice this is dilated on a grid ``f = ⌊radius/this⌋`` times
#: coarser, where its radius is still at least this many pixels (at f = 3 on a real photo
#: of ~57 px pitch the dark-bead evidence was 12 % off; docs/calibration.md).
COARSE_RADIUS_PX = 40.0


def _blocks(img: F32, f: int, pad: str) -> npt.NDArray[np.float32]:
    """The image cut in ``f × f`` blocks, ``(h/f, f, w/f, f)``, its last rows and columns
    padded to whole blocks (``"edge"``: repeated; ``"low"``: −∞)."""
    h, w = img.shape
    hc, wc = math.ceil(h / f), math.ceil(w / f)
    if pad == "edge":
        padded = np.pad(img, ((0, hc * f - h), (0, wc * f - w)), mode="edge")
    else:
        padded = np.full((hc * f, wc * f), -np.inf, dtype=np.float32)
        padded[:h, :w] = img
    return padded.reshape(hc, f, wc, f)


def _up(coarse: F32, f: int, shape: tuple[int, ...]) -> F32:
    """Linear interpolation of a block grid back to full resolution: each block's value
    stands at its centre."""
    hc, wc = coarse.shape
    full = cv2.resize(coarse, (wc * f, hc * f), interpolation=cv2.INTER_LINEAR)
    return np.ascontiguousarray(full[: shape[0], : shape[1]], dtype=np.float32)


def _coarse_gaussian(coarse: F32, sigma_px: float, f: int) -> F32:
    """Gaussian on the coarse grid such that, with the box down and the linear
    interpolation up, the full-resolution filter has σ = ``sigma_px``."""
    sigma_c = math.sqrt(max((sigma_px / f) ** 2 - 0.25, 0.25))
    return np.asarray(cv2.GaussianBlur(coarse, (0, 0), sigma_c), dtype=np.float32)


def wide_gaussian(img: F32, sigma_px: float) -> F32:
    """Gaussian blur of a 2-D float32 image, σ = ``sigma_px``.

    Parameters
    ----------
    img
        ``(h, w)`` float32 image.
    sigma_px
        Standard deviation, px (> 0).

    Returns
    -------
    ndarray
        ``(h, w)`` float32; ``cv2.GaussianBlur(img, (0, 0), sigma_px)`` itself when σ is at
        under ``3·COARSE_SIGMA_PX`` px, otherwise made on a grid ``f = ⌊σ/COARSE_SIGMA_PX⌋``
        times coarser (within ~1 % of the image's range of it, away from the borders).
    """
    f = int(sigma_px // COARSE_SIGMA_PX)
    if f < 3:
        return np.asarray(cv2.GaussianBlur(img, (0, 0), sigma_px), dtype=np.float32)
    # OpenCV reflects the image at its borders (BORDER_REFLECT_101): so does the margin
    # laid around it here, whole blocks wide and reaching 4σ, before the blocks are cut
    m = f * math.ceil(4.0 * sigma_px / f)
    padded = np.asarray(cv2.copyMakeBorder(img, m, m, m, m, cv2.BORDER_REFLECT_101),
                        dtype=np.float32)
    coarse = _blocks(padded, f, "edge").mean(axis=(1, 3), dtype=np.float32)
    out = _up(_coarse_gaussian(coarse, sigma_px, f), f, padded.shape)
    return np.ascontiguousarray(out[m: m + img.shape[0], m: m + img.shape[1]])


def local_max(img: F32, radius_px: int, sigma_px: float) -> F32:
    """The largest value within ``radius_px`` of each pixel, Gaussian-smoothed.

    ``GaussianBlur(dilate(img, disc(radius_px)), sigma_px)``.

    Parameters
    ----------
    img
        ``(h, w)`` float32 image.
    radius_px
        Radius of the disc, px (≥ 1).
    sigma_px
        σ of the Gaussian that follows, px (> 0).

    Returns
    -------
    ndarray
        ``(h, w)`` float32; OpenCV's filters themselves when the radius is under
        ``2·COARSE_RADIUS_PX`` px, otherwise made on a grid
        ``f = ⌊radius/COARSE_RADIUS_PX⌋`` times coarser (the disc's reach exact to about
        ``f`` px).
    """
    f = int(radius_px // COARSE_RADIUS_PX)
    if f < 2:
        se = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius_px + 1, 2 * radius_px + 1))
        return np.asarray(cv2.GaussianBlur(cv2.dilate(img, se), (0, 0), sigma_px),
                          dtype=np.float32)
    blocks = _blocks(img, f, "low").max(axis=(1, 3))
    # a block's maximum reaches half a block beyond its centre: the disc of blocks is that
    # much smaller, so the pixels' reach is the radius on average
    rc = max(1, round((radius_px - 0.5 * f) / f))
    se = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * rc + 1, 2 * rc + 1))
    grown = np.asarray(cv2.dilate(blocks, se), dtype=np.float32)
    # the blocks' values stand at their centres, as the area-averaged grid's do: the same
    # Gaussian and interpolation as :func:`wide_gaussian`
    return _up(_coarse_gaussian(grown, sigma_px, f), f, img.shape)
