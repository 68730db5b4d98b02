"""The scale a photo is read at: a phone's 12 MP photo is shrunk to the pitch the reader
needs.

The reader's filters are sized in line pitches (the top-hat's element, the local level's
disc, the blurs), so a photo taken closer costs more than its pixels: the widest of them
are made on a coarser grid (:mod:`.smooth`), but the top-hats' openings keep the full
resolution (a disc of 0.6 pitch for the marks costs the pixels times the pitch squared).
Measured on a 2-core AMD EPYC VM: the Marlin pattern at 1 MP 1.9 s, at 4.8 MP 5.0 s, at
14.7 MP (shrunk) 2.5 s. The widths need the
bead across a few pixels, no more: the project's synthetic photos, on which the reading
is validated, have a pitch of ~44 px (a 0.48 mm bead over ~4 px at 5 mm pitch). A photo
of more than :data:`SMALL_PIXELS` whose pitch is more than a quarter above
:data:`READ_PITCH_PX` is shrunk (area
averaging, which keeps each bead's integrated contrast) to that pitch; the result's
pixel figures are given back in the photo's own pixels.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.calibration.image.signal import deskew, line_direction_deg, pitch_px

__all__ = ["READ_PITCH_PX", "SMALL_PIXELS", "homography_to_photo", "scale_note", "shrink",
           "working_copy", "working_scale"]

#: Line pitch the reader works at, at most, px.
READ_PITCH_PX = 48.0
#: Photos of at most this many pixels are read as they are (no pitch is measured first);
#: a phone's 12 MP photo is above it. Shrinking costs width accuracy on real photos: at
#: 2 MP, PressureAdvanceCamera's black frame (2.07 MP, read right at its own size) was
#: refused, its lag 5.5σ from its best line (docs/calibration.md, "Wide filters").
SMALL_PIXELS = 8.0e6
#: The pitch of a larger photo is measured on a copy of about this many pixels.
_PROXY_PIXELS = 1.0e6


def shrink(gray: npt.NDArray[np.uint8], scale: float) -> npt.NDArray[np.uint8]:
    """``gray`` resized by ``scale`` (< 1) with area averaging, shape about
    ``(H·scale, W·scale)``."""
    return np.asarray(cv2.resize(gray, None, fx=scale, fy=scale,
                                 interpolation=cv2.INTER_AREA), dtype=np.uint8)


def scale_note(scale: float, pitch_px: float, what: str = "line") -> str:
    """The result's note for a photo read at ``scale`` (``pitch_px``: the pitch in the
    shrunk photo)."""
    return (f"read at {scale:.2f}× the photo's size (its {what} pitch {pitch_px / scale:.0f} "
            f"px; the widths need about {READ_PITCH_PX:.0f})")


def working_scale(gray: npt.NDArray[np.uint8]) -> float:
    """Factor (≤ 1) by which to shrink ``gray`` so that its line pitch is at most
    :data:`READ_PITCH_PX`.

    Parameters
    ----------
    gray
        Grey photo, uint8, shape ``(H, W)``.

    Returns
    -------
    float
        1 for a photo of at most :data:`SMALL_PIXELS`, one without a measurable pitch,
        or one whose pitch is within a quarter of :data:`READ_PITCH_PX`; else
        ``READ_PITCH_PX/pitch``.
    """
    pixels = float(gray.size)
    if gray.ndim != 2 or pixels <= SMALL_PIXELS:
        return 1.0
    s0 = math.sqrt(_PROXY_PIXELS / pixels)
    proxy = shrink(gray, s0)
    angle, _coherence = line_direction_deg(proxy)
    desk = deskew(proxy, angle)
    pitch = pitch_px(desk.image, desk.valid) / s0
    if not math.isfinite(pitch) or pitch <= 1.25 * READ_PITCH_PX:
        return 1.0
    return READ_PITCH_PX / pitch


def working_copy(gray: npt.NDArray[np.uint8]) -> tuple[npt.NDArray[np.uint8], float]:
    """The photo as the reader reads it, and the factor it was shrunk by (1: as it is;
    :func:`working_scale`)."""
    scale = working_scale(gray)
    return (shrink(gray, scale) if scale < 1.0 else gray), scale


def homography_to_photo(hom: npt.NDArray[np.float64], scale: float) -> npt.NDArray[np.float64]:
    """A homography bed (mm) → the working copy (px) as bed → the photo's own pixels."""
    return np.asarray(np.diag([1.0 / scale, 1.0 / scale, 1.0]) @ hom, dtype=np.float64)
