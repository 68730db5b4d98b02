"""Which printed line (or chevron) is the best, from every line's signed errors.

Each test line has a *signed error*: how far it is from even after its speed changes, and
which way ([001 Table II] made quantitative, :func:`flowtwin.calibration.image.kimage.score_line`:
negative when the line's K is too low — thin after a step up, thick after a step down —
positive when too high). In the twin, and in every render of the independent model, the
errors grow linearly with the line's K near the best line and cross zero at the lag
([001 Fig. 2]: the advance term ``K·dQ/dt`` cancels the lag ``τ·dQ/dt`` when ``K = τ``).

A photo adds noise to every line's error (a textured sheet under the bead, JPEG, glare:
several hundredths on the renders, comparable to the change from one line to the next).
Taking the line with the smallest score, line by line, then often picks a neighbour of the
best line. :func:`error_crossing` uses the lines around the crossing at once instead: the
mean of each line's acceleration and deceleration errors, a Theil–Sen line through them
against K (the median of all pairwise slopes: robust to a few lines whose errors
saturate, e.g. gaps at the ends of the range), and its zero crossing. The errors are not
straight over a wide range (the deceleration error grows faster above the lag than it
falls below it: a line through all of them crosses a sixth of a step low on a clean
render), so the line is fitted again to the :data:`LOCAL_LINES` lines nearest the first
crossing, twice. The best line is the printed line nearest
that crossing (:func:`best_line`); when the errors do not rise with K or cross outside the
printed range, the smallest score decides.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["LOCAL_LINES", "BestLine", "best_line", "error_crossing", "trend", "zero_crossing"]

FloatArray = npt.NDArray[np.float64]

#: Lines nearest the first crossing that the crossing is refitted to.
LOCAL_LINES = 5


def _mean_error(acc: FloatArray, dec: FloatArray) -> FloatArray:
    both = np.vstack([acc, dec])
    n = np.sum(np.isfinite(both), axis=0)
    with np.errstate(invalid="ignore"):
        return np.asarray(np.where(n > 0, np.nansum(both, axis=0) / np.maximum(n, 1), np.nan),
                          dtype=np.float64)


def error_crossing(k_s: npt.ArrayLike, accel_error: npt.ArrayLike,
                   decel_error: npt.ArrayLike) -> tuple[float, float] | None:
    """Zero crossing of the Theil–Sen line through the lines' mean signed errors.

    Parameters
    ----------
    k_s
        Each line's advance factor, s.
    accel_error, decel_error
        Each line's signed errors (NaN: none).

    Returns
    -------
    tuple or None
        ``(K where the line crosses zero (s), slope per s)``; ``None`` with fewer than
        three lines with an error, or a slope that is not positive.
    """
    k = np.asarray(k_s, dtype=np.float64)
    e = _mean_error(np.asarray(accel_error, dtype=np.float64),
                    np.asarray(decel_error, dtype=np.float64))
    ok = np.isfinite(e)
    k, e = k[ok], e[ok]
    first = _theil_sen_crossing(k, e)
    if first is None:
        return None
    out = first
    for _ in range(2):
        near = np.argsort(np.abs(k - out[0]), kind="stable")[:max(LOCAL_LINES, 3)]
        again = _theil_sen_crossing(k[near], e[near])
        if again is None:
            break
        out = again
    return out


def _theil_sen_crossing(k: FloatArray, e: FloatArray) -> tuple[float, float] | None:
    if k.size < 3:
        return None
    slopes = [(e[j] - e[i]) / (k[j] - k[i]) for i, j in itertools.combinations(range(k.size), 2)
              if k[j] != k[i]]
    if not slopes:
        return None
    slope = float(np.median(slopes))
    if not slope > 0:
        return None
    intercept = float(np.median(e - slope * k))
    return -intercept / slope, slope


def zero_crossing(k: FloatArray, e: FloatArray, near: float) -> float | None:
    """K where ``e`` rises through zero between neighbouring lines, nearest to ``near``."""
    ok = np.isfinite(e)
    k, e = k[ok], e[ok]
    found = [float(k[i] + (k[i + 1] - k[i]) * (-e[i]) / (e[i + 1] - e[i]))
             for i in range(k.size - 1) if e[i] <= 0.0 < e[i + 1]]
    return min(found, key=lambda kk: abs(kk - near)) if found else None


def trend(k_s: npt.ArrayLike, accel_error: npt.ArrayLike, decel_error: npt.ArrayLike
          ) -> float:
    """Mean rank correlation of the acceleration and deceleration errors with K."""
    k = np.asarray(k_s, dtype=np.float64)
    out = []
    for e in (np.asarray(accel_error, dtype=np.float64),
              np.asarray(decel_error, dtype=np.float64)):
        ok = np.isfinite(e)
        if np.count_nonzero(ok) >= 3:
            rk = np.argsort(np.argsort(k[ok])).astype(float)
            re = np.argsort(np.argsort(e[ok])).astype(float)
            out.append(float(np.corrcoef(rk, re)[0, 1]))
    return float(np.mean(out)) if out else math.nan


@dataclass(frozen=True)
class BestLine:
    """The best line and how it was chosen.

    Attributes
    ----------
    index
        Index of the best line among all lines.
    k_cross_s
        Zero crossing of the errors' Theil–Sen line, s (``None``: no crossing).
    by
        ``"errors"`` (the line nearest the crossing) or ``"score"`` (the smallest score).
    """

    index: int
    k_cross_s: float | None
    by: str


def best_line(k_s: npt.ArrayLike, scores: Sequence[float], accel_error: npt.ArrayLike,
              decel_error: npt.ArrayLike, usable: Sequence[int]) -> BestLine:
    """The best of the ``usable`` lines (module docstring).

    Parameters
    ----------
    k_s, scores, accel_error, decel_error
        Per line (all lines, front to back).
    usable
        Indices of the lines measured well enough to be chosen.

    Returns
    -------
    BestLine
    """
    k = np.asarray(k_s, dtype=np.float64)
    use = list(usable)
    by_score = min(use, key=lambda i: float(scores[i]))
    cross = error_crossing(k[use], np.asarray(accel_error, dtype=np.float64)[use],
                           np.asarray(decel_error, dtype=np.float64)[use])
    if cross is None:
        return BestLine(by_score, None, "score")
    kc = cross[0]
    lo, hi = float(k[use].min()), float(k[use].max())
    if not lo <= kc <= hi:
        return BestLine(by_score, kc, "score")
    return BestLine(min(use, key=lambda i: abs(float(k[i]) - kc)), kc, "errors")
