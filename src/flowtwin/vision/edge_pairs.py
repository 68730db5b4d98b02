"""Candidate edge pairs of one row band: the plausibility rules of a filament's two edges.

A rising edge followed by a falling one is a bright filament on a darker background, a
falling then rising edge a dark one. A pair is plausible when (a) its separation lies in
one of the expected ranges, (b) the background outside each edge is resolved inside the
ROI, (c) the weaker edge has at least :data:`_STRENGTH_RATIO` of the stronger one's
slope, and (d) nothing between the two edges comes back to the background level (one
object, not the filament and the bearing). Pairs nested inside another are highlights or
teeth marks (:func:`outer_pairs`). See :mod:`flowtwin.vision.width` for the whole model.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["Pair", "band_pairs", "outer_pairs"]

F64 = npt.NDArray[np.float64]

#: Strongest candidates kept per sign and band.
_CANDIDATES = 5
#: Interior test: the interior's extreme must stay this fraction of the weaker step
#: away from the outside level.
_INTERIOR_FRACTION = 0.5
#: The weaker edge of a pair must have at least this fraction of the stronger one's slope
#: (a shading gradient is no match for a silhouette edge).
_STRENGTH_RATIO = 0.25


@dataclass(frozen=True, slots=True)
class Pair:
    """Two edges of one candidate filament in a band."""

    left: float          # sub-pixel columns of the two edges
    right: float
    sign: float          # +1 bright filament (rising then falling), -1 dark
    strength: float      # weaker edge slope, DN/px


def _candidates(p: F64, thr: float) -> tuple[list[int], list[int]]:
    """Indices of the strongest local maxima above ``thr`` and minima below ``-thr``."""
    inner = p[1:-1]
    rise = np.flatnonzero((inner >= p[:-2]) & (inner > p[2:]) & (inner >= thr)) + 1
    fall = np.flatnonzero((inner <= p[:-2]) & (inner < p[2:]) & (inner <= -thr)) + 1
    if rise.size > _CANDIDATES:
        rise = rise[np.argsort(-p[rise])[:_CANDIDATES]]
    if fall.size > _CANDIDATES:
        fall = fall[np.argsort(p[fall])[:_CANDIDATES]]
    return sorted(rise.tolist()), sorted(fall.tolist())


def band_pairs(p: F64, level: F64, thr: float, clear: int,
                expected: Sequence[tuple[float, float]] | None, min_sep: float
                ) -> list[Pair]:
    """Plausible edge pairs of one band (step 2 of the module docstring)."""
    w = p.size
    rise, fall = _candidates(p, thr)
    out: list[Pair] = []
    for a_list, b_list, sign in ((rise, fall, 1.0), (fall, rise, -1.0)):
        for i in a_list:
            if i - clear < 0:
                continue
            for j in b_list:
                sep = j - i
                if sep < min_sep:
                    continue
                if j + clear >= w:
                    break
                if expected is not None and not any(lo - 1 <= sep <= hi + 1
                                                    for lo, hi in expected):
                    continue
                out_l = float(level[i - clear])
                out_r = float(level[j + clear])
                in_l = float(level[i + clear])
                in_r = float(level[j - clear])
                step = min(sign * (in_l - out_l), sign * (in_r - out_r))
                if step <= 0:
                    continue
                if min(abs(p[i]), abs(p[j])) < _STRENGTH_RATIO * max(abs(p[i]), abs(p[j])):
                    continue
                inner = level[i + clear:j - clear + 1]
                if sign > 0:
                    margin = float(inner.min()) - max(out_l, out_r)
                else:
                    margin = min(out_l, out_r) - float(inner.max())
                if margin < _INTERIOR_FRACTION * step:
                    continue
                out.append(Pair(float(i), float(j), sign,
                                 float(min(abs(p[i]), abs(p[j])))))
    return out


def outer_pairs(pairs: list[Pair]) -> list[Pair]:
    """Pairs not nested inside another pair (one px of slack)."""
    keep = []
    for a in pairs:
        nested = any(b is not a and b.left <= a.left + 1 and a.right <= b.right + 1
                     and (b.right - b.left) > (a.right - a.left) for b in pairs)
        if not nested:
            keep.append(a)
    # identical pairs found twice (e.g. both polarities never, same edges) collapse
    unique: list[Pair] = []
    for a in keep:
        if not any(abs(a.left - b.left) <= 1 and abs(a.right - b.right) <= 1 for b in unique):
            unique.append(a)
    return unique
