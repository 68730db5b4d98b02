"""When a photo cannot support an answer: blur, too few lines, lines cut by the frame.

Each check returns a reason (a sentence) or ``None``; the analysis refuses with the reason
(:class:`~flowtwin.errors.VisionError`) rather than report a K the photo does not show.

* **Too few lines.** The scores need neighbours to compare: fewer than
  :data:`MIN_LINES` lines found, or fewer than that measurable along their length.
* **Cut by the frame.** A line whose end reaches the edge of the photo has lost its end:
  its length no longer registers the pattern and its last segment is unmeasured.
* **Blur.** Across a bead, the mean profile (background removed, over the steady parts of
  all lines, on the bed grid) has a half-maximum width ``F`` and flanks that rise from 10 %
  to 90 % over ``E``. A sharp bead has ``E ≪ F``; blur widens the flanks until the profile
  is the blur's own (a Gaussian has ``E/F = 1.687σ/2.355σ = 0.72``). Above
  :data:`MAX_EDGE_RATIO` the width changes along the line are smeared beyond reading; a
  bead narrower than :data:`MIN_BEAD_PX` pixels is not resolved either.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = ["MAX_EDGE_RATIO", "MIN_BEAD_PX", "MIN_LINES", "blur_reason", "edge_ratio"]

FloatArray = npt.NDArray[np.float64]

#: Fewest lines for an answer.
MIN_LINES = 3
#: Largest 10–90 % flank width / half-maximum width of the bead profile.
MAX_EDGE_RATIO = 0.65
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


def blur_reason(profile: FloatArray, dv_mm: float, px_per_mm: float) -> str | None:
    """Why the bead profile is too blurred to read, or ``None`` (module docstring)."""
    fwhm, edge = edge_ratio(profile, dv_mm)
    if not (np.isfinite(fwhm) and np.isfinite(edge)):
        return "the beads show no clear profile across them (out of focus?)"
    if fwhm * px_per_mm < MIN_BEAD_PX:
        return (f"the beads are {fwhm * px_per_mm:.1f} px wide (need >= {MIN_BEAD_PX:g} px: "
                "take the photo closer or at a higher resolution)")
    if edge > MAX_EDGE_RATIO * fwhm:
        return (f"the image is blurred: the bead edges rise over {edge * px_per_mm:.1f} px, "
                f"{edge / fwhm:.2f} of the bead's {fwhm * px_per_mm:.1f} px width (at most "
                f"{MAX_EDGE_RATIO:g}); refocus, hold still, or use more light")
    return None
