"""Which way a photo reads when the pattern's marks do not say: the twin decides.

A stack of equal lines reads the same turned by 180° or mirrored; when its marks are
symmetric too (OrcaSlicer's PA line seen from above or scanned face down; a pattern in a
frame) the registration (:mod:`.register`) returns several readings. Each reading puts the
measured widths at other positions and K on other lines. Only in the right one do the
widths look like printed lines: the twin (:class:`~flowtwin.calibration.fits.lagmodel.
LagModel`, [001 Eqs. 7, 15]) then explains them with one lag for all lines.

For every reading the lag is scanned on a grid (:data:`K_GRID`; the flow gain solved in
closed form for each trial lag) and the best relative RMS of the width residuals kept.
The reading the twin explains best wins when its RMS is below :data:`RMS_RATIO` of every
other reading's and the lines' signed errors grow with K in it (rank correlation above
zero, :func:`.bestline.trend`); otherwise the photo is refused. The rank correlation alone
does not decide: reading a line backwards moves the windows after the speed steps onto
other transients of the same line, whose errors still grow with K.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.calibration.fits.lagmodel import LagModel, LagParams
from flowtwin.calibration.image.bestline import trend
from flowtwin.calibration.image.kimage import LineReading

__all__ = ["K_GRID", "RMS_RATIO", "DirectionChoice", "choose_by_twin", "twin_rms"]

FloatArray = npt.NDArray[np.float64]

#: Trial lags of the scan, s.
K_GRID = np.geomspace(0.004, 1.0, 16)
#: The winner's RMS must be below this fraction of every other reading's.
RMS_RATIO = 0.8
#: Samples this close to a line's ends are not compared (end caps, start blob), mm.
_END_MARGIN_MM = 1.0


def twin_rms(model: LagModel, lines: Sequence[LineReading]) -> float:
    """Best relative RMS of the twin's widths against ``lines`` over :data:`K_GRID`.

    Parameters
    ----------
    model
        The test lines (same order as ``lines``).
    lines
        Measured widths of each line in one reading.

    Returns
    -------
    float
        ``min over K of sqrt(mean((g·w_twin − w)²)) / mean(w)`` with the gain ``g`` fitted
        for each ``K``; NaN without usable samples.
    """
    xs, ws = [], []
    for i, r in enumerate(lines):
        x = np.asarray(r.positions_mm, dtype=np.float64)
        ok = np.isfinite(r.widths_mm) & model.usable(i, np.clip(x, 0.0, None),
                                                     end_margin_mm=_END_MARGIN_MM)
        ok &= x <= model.lines[i].length_mm
        xs.append(x[ok])
        ws.append(np.asarray(r.widths_mm, dtype=np.float64)[ok])
    measured = np.concatenate(ws)
    if measured.size < 10:
        return math.nan
    best = math.inf
    for k in K_GRID:
        pred = np.concatenate(model.widths(LagParams(k_s=float(k)), xs))
        good = np.isfinite(pred)
        if np.count_nonzero(good) < 10:
            continue
        p, m = pred[good], measured[good]
        g = float(p @ m) / float(p @ p)
        rms = float(np.sqrt(np.mean((g * p - m) ** 2))) / float(np.mean(m))
        best = min(best, rms)
    return best if math.isfinite(best) else math.nan


@dataclass(frozen=True)
class DirectionChoice:
    """The reading the twin chose, or why none.

    Attributes
    ----------
    index
        Index of the chosen reading (``None``: undecided).
    rms
        Relative RMS of each reading's best twin fit.
    trends
        Rank correlation of each reading's signed errors with K.
    """

    index: int | None
    rms: tuple[float, ...]
    trends: tuple[float, ...]


def choose_by_twin(model: LagModel, readings: Sequence[Sequence[LineReading]]
                   ) -> DirectionChoice:
    """The reading whose widths the twin explains best (module docstring)."""
    rms = tuple(twin_rms(model, r) for r in readings)
    trends = tuple(trend([x.k_la_s for x in r], [x.accel_error for x in r],
                         [x.decel_error for x in r]) for r in readings)
    finite = [i for i, v in enumerate(rms) if math.isfinite(v)]
    if not finite:
        return DirectionChoice(None, rms, trends)
    win = min(finite, key=lambda i: rms[i])
    others = [rms[i] for i in finite if i != win]
    if others and not rms[win] < RMS_RATIO * min(others):
        return DirectionChoice(None, rms, trends)
    if not trends[win] > 0.0:
        return DirectionChoice(None, rms, trends)
    return DirectionChoice(win, rms, trends)
