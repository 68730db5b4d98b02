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

Two more checks look at the answer itself (:func:`answer_reason`), once the lines are read:

* **Best line at an end of the range.** When the most even line is the first or the last
  line measured, the advance factor may lie beyond it: the tuning guides read such a
  pattern as "print it again with a range that brackets the answer" (docs/calibration.md
  cites them). The photo gives a bound then, not a value, and the analysis refuses with it.
* **Best line and twin's lag disagree.** Both are answers from the same photo: the line
  whose K cancels the lag [001 Eq. 11] and the lag the twin fits to every line's widths.
  Their difference is compared with the best line's resolution (half a step: the lag lies
  anywhere between two lines) and the lag's standard error:
  ``z = |K_best − K_lag| / sqrt((step/2)² + σ²)``; above :data:`MAX_DISAGREEMENT` the
  photo does not support a confident answer. The threshold was set on the independent
  renderer's study alone (docs/calibration.md, "Session 10"), never on the real photos.
  The two are commensurable only where the lines' K is the firmware's advance factor in
  seconds (Klipper ``pressure_advance``, Marlin ``M900 K`` of linear advance 1.5, RRF
  ``M572 S``: every layout flowtwin writes) and the twin's lag is the ``τ`` that factor
  cancels — not when a dead time is fitted too (then the best K is not ``τ`` alone), nor
  when the lines' K do not step.
* **No witness beside the smallest score.** The best line is taken where the lines'
  signed errors cross zero [001 Fig. 2] (:mod:`flowtwin.calibration.image.bestline`);
  only when they do not cross within the printed range does the smallest score decide.
  When, on top of that, the twin's lag could not be fitted to the widths, nothing on
  the photo confirms the line the score picked: the scores of a photo whose widths do
  not read are flat and noisy, and their minimum is a guess (docs/calibration.md,
  "Session 17": a real photo read 2 steps off this way). The analysis refuses then,
  with both reasons. A caller that did not ask for the lag fit is not refused.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares
from scipy.special import erf

__all__ = ["MAX_BLUR_MM", "MAX_DISAGREEMENT", "MIN_BEAD_PX", "MIN_LINES", "AnswerCheck",
           "BlurFit", "answer_reason", "blur_fit", "blur_reason", "disagreement", "edge_ratio",
           "range_end_reason"]

FloatArray = npt.NDArray[np.float64]

#: Fewest lines for an answer.
MIN_LINES = 3
#: Largest blur (Gaussian sigma on the bed) a photo may have, mm.
MAX_BLUR_MM = 0.35
#: Narrowest resolvable bead, px.
MIN_BEAD_PX = 2.0
#: Largest disagreement ``z`` of the best line and the twin's lag (:func:`disagreement`).
MAX_DISAGREEMENT = 4.0


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


def range_end_reason(k_s: npt.ArrayLike, best_index: int, usable: Sequence[int], *,
                     item: str = "line") -> str | None:
    """Why the best line gives only a bound: it is the first or last line measured.

    Parameters
    ----------
    k_s
        Every line's advance factor, front to back (rising), s.
    best_index
        The best line.
    usable
        The lines measured well enough to be chosen.
    item
        ``"line"`` or ``"chevron"`` (for the message).

    Returns
    -------
    str or None
        The reason, or ``None`` when the best line has measured lines on both sides.
    """
    k = np.asarray(k_s, dtype=np.float64)
    use = sorted(int(i) for i in usable)
    if len(use) < 2 or best_index not in (use[0], use[-1]):
        return None
    which = "first" if best_index == use[0] else "last"
    side = "below" if which == "first" else "above"
    bound = "<=" if which == "first" else ">="
    return (f"the best {item} is the {which} of the range measured (K {k[use[0]]:g} to "
            f"{k[use[-1]]:g} s): the answer may lie {side} it (K {bound} {k[best_index]:g} s, "
            f"a bound, not a value); print the pattern again with a range that brackets it")


def disagreement(k_best_s: float, step_s: float, k_lag_s: float, k_lag_err_s: float) -> float:
    """``|K_best − K_lag| / sqrt((step/2)² + σ²)``: the two answers' distance in units of
    their combined uncertainty (module docstring)."""
    u = math.hypot(0.5 * step_s, k_lag_err_s)
    return abs(k_best_s - k_lag_s) / u if u > 0 else math.inf


@dataclass(frozen=True)
class AnswerCheck:
    """The answer checks of one read photo (:func:`answer_reason`).

    Attributes
    ----------
    reason
        Why the photo cannot give a confident K, or ``None``.
    check
        ``"range-end"``, ``"disagreement"``, ``"unsupported"`` or ``None``.
    z
        Disagreement of the best line and the lag (NaN when not commensurable or no lag).
    values
        The two answers (a refusal's ``value``): ``best_k_s``, ``lag_k_s``, ``lag_err_s``
        (s; ``None`` without a lag) and ``z`` (``None`` when not compared).
    """

    reason: str | None
    check: str | None
    z: float
    values: dict[str, float | None]


def answer_reason(k_s: npt.ArrayLike, best_index: int, usable: Sequence[int], *,
                  k_lag_s: float | None, k_lag_err_s: float | None, dead_time: bool = False,
                  item: str = "line", max_z: float = MAX_DISAGREEMENT,
                  best_by: str = "errors", lag_problem: str | None = None) -> AnswerCheck:
    """The answer checks (module docstring): the best line at an end of the range first,
    then its disagreement with the twin's lag where the two are commensurable, then a best
    line that only the smallest score supports.

    Parameters
    ----------
    k_s, best_index, usable, item
        As for :func:`range_end_reason`.
    k_lag_s, k_lag_err_s
        The twin's fitted lag and its standard error, s (``None``: no lag fit).
    dead_time
        A dead time was fitted with the lag (then the two are not compared).
    max_z
        Largest disagreement accepted.
    best_by
        How the best line was chosen: ``"errors"`` (nearest the errors' zero crossing)
        or ``"score"`` (the smallest score; :class:`~flowtwin.calibration.image.bestline.
        BestLine`).
    lag_problem
        Why the lag fit failed (``None``: it was not asked for, or it succeeded).

    Returns
    -------
    AnswerCheck
    """
    k = np.asarray(k_s, dtype=np.float64)
    steps = np.diff(k)
    step = float(np.median(np.abs(steps))) if steps.size else 0.0
    z = math.nan
    if k_lag_s is not None and k_lag_err_s is not None and not dead_time and step > 0:
        z = disagreement(float(k[best_index]), step, k_lag_s, k_lag_err_s)
    values = {"best_k_s": round(float(k[best_index]), 6),
              "lag_k_s": None if k_lag_s is None else round(k_lag_s, 5),
              "lag_err_s": None if k_lag_err_s is None else round(k_lag_err_s, 5),
              "z": round(z, 1) if math.isfinite(z) else None}
    end = range_end_reason(k, best_index, usable, item=item)
    if end is not None:
        return AnswerCheck(end, "range-end", z, values)
    if math.isfinite(z) and z > max_z:
        assert k_lag_s is not None and k_lag_err_s is not None
        return AnswerCheck(
            f"the best {item} (K {k[best_index]:g} s) and the twin's lag fitted to the same "
            f"photo ({k_lag_s:.4g} ± {k_lag_err_s:.2g} s) disagree by {z:.1f} times their "
            f"combined uncertainty (more than {max_z:g}): the photo does not support a "
            "confident K; check the pattern's parameters as printed, or photograph it again "
            "square on, evenly lit", "disagreement", z, values)
    if best_by == "score" and k_lag_s is None and lag_problem is not None:
        return AnswerCheck(
            f"only the smallest score picks the best {item} (K {k[best_index]:g} s): the "
            f"{item}s' errors do not cross zero within the printed range, and the twin's "
            f"lag could not be fitted to the widths ({lag_problem}); the photo does not "
            "support a confident K: photograph the pattern closer, square on and evenly "
            "lit, without marks drawn over the lines", "unsupported", z, values)
    return AnswerCheck(None, None, z, values)
