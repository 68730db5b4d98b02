"""When a photo cannot support an answer: blur, too few lines, lines cut by the frame.

Each check returns a reason (a sentence) or ``None``; the analysis refuses with the reason
(:class:`~flowtwin.errors.VisionError`) rather than report a K the photo does not show.

* **Too few lines.** The scores need neighbours to compare: fewer than
  :data:`MIN_LINES` lines found, or fewer than that measurable along their length.
* **Cut by the frame.** A line whose end reaches the edge of the photo has lost its end:
  its length no longer registers the pattern and its last segment is unmeasured.
* **Blur.** Across a bead, the mean contrast profile (over all lines, on the bed grid)
  is fitted with a box of the bead's width ``W`` blurred by a Gaussian of ``σ``
  (:func:`blur_fit`: ``A/2·[erf((v − c + W/2)/(√2σ)) − erf((v − c − W/2)/(√2σ))]`` plus a
  level): ``σ`` is the blur in millimetres on the bed, whatever the bead's width in
  pixels (a sharp 3-px bead and a sharp 30-px bead both give ``σ`` of about a pixel).
  A bead the blur swamps (``W < σ``) no longer fixes ``σ`` and ``W`` apart: its profile
  is a Gaussian of ``σ_eff = FWHM/2.355``, taken as ``σ`` (an upper bound). The photo
  is refused above :data:`MAX_BLUR_MM`, where the widths along the lines are no longer
  read well enough to rank the lines (measured on the independent renders:
  docs/calibration.md), and when a bead is under :data:`MIN_BEAD_PX` pixels wide.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares
from scipy.special import erf

__all__ = ["MAX_BLUR_MM", "MIN_BEAD_PX", "MIN_LINES", "BlurFit", "blur_fit", "blur_reason",
           "edge_ratio"]

FloatArray = npt.NDArray[np.float64]

#: Fewest lines for an answer.
MIN_LINES = 3
#: Largest blur (Gaussian sigma on the bed) a photo may have, mm.
MAX_BLUR_MM = 0.35
#: Narrowest resolvable bead, px.
MIN_BEAD_PX = 2.0


def edge_ratio(profile: FloatArray, dv: float) -> tuple[float, float]:
    """Half-maximum width and 10–90 % flank width of a bead profile.

    Parameters
    ----------
    profile
        Bead signal across the bead (positive on the bead, ~0 on the sheet), shape ``(n,)``.
    dv
        Sample spacing.

    Returns
    -------
    tuple
        ``(F, E)`` in the units of ``dv`` (NaN where the profile has no clear peak).
    """
    p = np.asarray(profile, dtype=np.float64)
    i = int(np.argmax(p))
    peak = p[i]
    if not peak > 0:
        return float("nan"), float("nan")

    def level(frac: float, step: int) -> float:
        j = i
        while 0 <= j + step < p.size and p[j + step] >= frac * peak:
            j += step
        k = j + step
        if not 0 <= k < p.size:
            return float("nan")
        t = (p[j] - frac * peak) / (p[j] - p[k]) if p[j] != p[k] else 0.0
        return (j + t * step) * dv

    lo50, hi50 = level(0.5, -1), level(0.5, 1)
    lo10, hi10 = level(0.1, -1), level(0.1, 1)
    lo90, hi90 = level(0.9, -1), level(0.9, 1)
    fwhm = hi50 - lo50
    edge = 0.5 * ((lo90 - lo10) + (hi10 - hi90))
    return float(fwhm), float(edge)


@dataclass(frozen=True)
class BlurFit:
    """Box-blurred-by-a-Gaussian fit of a bead's profile (units of the sample spacing).

    Attributes
    ----------
    sigma
        Blur (Gaussian sigma); ``σ_eff`` when the bead is swamped.
    width
        The bead's width ``W``.
    fwhm
        Half-maximum width of the profile.
    swamped
        ``W < σ``: the profile does not fix ``σ`` and ``W`` apart.
    """

    sigma: float
    width: float
    fwhm: float
    swamped: bool


def _box_blur(v: FloatArray, level: float, amp: float, c: float, w: float,
              sigma: float) -> FloatArray:
    s = math.sqrt(2.0) * max(sigma, 1e-9)
    return np.asarray(level + 0.5 * amp * (erf((v - c + 0.5 * w) / s)
                                           - erf((v - c - 0.5 * w) / s)), dtype=np.float64)


def blur_fit(profile: FloatArray, dv: float) -> BlurFit | None:
    """Fit a box of width ``W`` blurred by a Gaussian ``σ`` to a bead's profile.

    Parameters
    ----------
    profile
        Contrast across the bead (positive on it), shape ``(n,)``.
    dv
        Sample spacing (mm on the bed grid).

    Returns
    -------
    BlurFit or None
        ``None`` when the profile has no clear peak.
    """
    p = np.asarray(profile, dtype=np.float64)
    fwhm, _ = edge_ratio(p, 1.0)
    if not (np.isfinite(fwhm) and fwhm > 0):
        return None
    v = np.arange(p.size, dtype=np.float64)
    i = int(np.argmax(p))
    lo_lvl = float(np.median(np.concatenate([p[: p.size // 6 + 1], p[-(p.size // 6) - 1:]])))
    amp0 = float(p[i] - lo_lvl)
    x0 = np.array([lo_lvl, amp0, float(i), fwhm, max(0.3 * fwhm / 2.355, 0.3)])
    lower = [-np.inf, 0.0, 0.0, 0.0, 0.1]
    upper = [np.inf, np.inf, float(p.size - 1), float(p.size), float(p.size)]
    x0 = np.clip(x0, np.array(lower) + 1e-9, np.array(upper) - 1e-9)
    sol = least_squares(lambda x: _box_blur(v, *x) - p, x0, bounds=(lower, upper),
                        x_scale=np.array([max(amp0, 1e-3), max(amp0, 1e-3), 1.0, 1.0, 1.0]))
    _, _, _, w, sigma = (float(x) for x in sol.x)
    swamped = w < sigma
    if swamped:
        sigma = fwhm / 2.355
    return BlurFit(sigma * dv, w * dv, fwhm * dv, swamped)


def blur_reason(profile: FloatArray, dv_mm: float, px_per_mm: float, *,
                max_blur_mm: float = MAX_BLUR_MM) -> str | None:
    """Why the bead profile is too blurred to read, or ``None`` (module docstring)."""
    fit = blur_fit(profile, dv_mm)
    if fit is None:
        return "the beads show no clear profile across them (out of focus?)"
    if fit.fwhm * px_per_mm < MIN_BEAD_PX:
        return (f"the beads are {fit.fwhm * px_per_mm:.1f} px wide (need >= {MIN_BEAD_PX:g} "
                "px: take the photo closer or at a higher resolution)")
    if fit.sigma > max_blur_mm:
        return (f"the image is blurred: the bead edges are spread over sigma = "
                f"{fit.sigma:.2f} mm ({fit.sigma * px_per_mm:.1f} px) on the print, more "
                f"than {max_blur_mm:g} mm; refocus, hold still, use more light, or take "
                "the photo closer")
    return None
