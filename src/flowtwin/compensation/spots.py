"""Where the pacing is needed: the spots the advance alone leaves wrong.

The flow pacing (:mod:`flowtwin.compensation.pace`) slows the path wherever the intended
flow changes faster than the melt's lag follows. Most of those changes the baked advance
already meets: it pushes ahead of a rise and pulls back in a deceleration. Slowing them all
costs print time for nothing. So the pacing may be placed only near the *spots*: the
original moves whose flow error, after an advance computed without pacing and simulated by
the twin, is still beyond a tolerance (``Σ delivered / commanded − 1``,
:func:`flowtwin.compensation.metrics.flow_figures`). A junction, a run end or a start is
paced when a spot lies within ``reach_mm`` of printed path of it, before or after: the
melt's stored volume lands on the stretch after a falling junction and the shortfall of a
start follows it, each over ``K·v`` of path (0.5–10 mm at ``K`` 0.05–0.1 s and 10–100 mm/s).

A *spot* is a stretch of consecutive scored moves all beyond the tolerance
(:func:`rank_spots`); under a print-time budget only the worst spots are paced, ranked by
the share of the squared flow error they hold, ``Σ V·e²`` (``V`` the move's commanded
volume, ``e`` its flow error): the spot's part of the volume-weighted RMS flow error
(:func:`flowtwin.compensation.metrics.flow_figures`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from flowtwin.errors import DataError

__all__ = ["SpotRanking", "count_spots", "rank_spots", "spot_pieces"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]


def spot_pieces(flow_error: FloatArray, piece_row: IntArray, length_mm: FloatArray,
                printing: BoolArray, *, tolerance: float, reach_mm: float) -> BoolArray:
    """Pieces within ``reach_mm`` of printed path of a move whose flow error exceeds
    ``tolerance``.

    Parameters
    ----------
    flow_error
        Flow error of every original move (fraction; 0 where a move does not print),
        shape ``(n_moves,)``.
    piece_row
        Original move of every piece of the draft to pace, shape ``(n,)``.
    length_mm
        Path length of every piece, mm, shape ``(n,)``.
    printing
        Pieces that print, shape ``(n,)``; the path is measured along them only, so a
        travel between two runs adds none (a run end and the next start are neighbours).
    tolerance
        Largest flow error left alone (fraction, > 0).
    reach_mm
        Printed path within which a spot makes a piece pace-able, mm (≥ 0).

    Returns
    -------
    ndarray of bool
        Shape ``(n,)``.

    Raises
    ------
    DataError
        Arrays of different lengths, a row outside ``flow_error``, or a bad tolerance or
        reach.
    """
    err = np.asarray(flow_error, dtype=np.float64)
    row = np.asarray(piece_row, dtype=np.int64)
    length = np.asarray(length_mm, dtype=np.float64)
    pr = np.asarray(printing, dtype=bool)
    _same_length("piece", "piece_row", "one per piece", row, length, pr)
    if row.size and (row.min() < 0 or row.max() >= err.size):
        raise DataError("piece maps to no original move", field="piece_row",
                        value=int(row.max()), allowed=f"0 .. {err.size - 1}")
    _check_tolerance(tolerance)
    if not (np.isfinite(reach_mm) and reach_mm >= 0.0):
        raise DataError("spot reach must not be negative", field="reach_mm",
                        value=reach_mm, allowed=">= 0 mm")
    bad = pr & (np.abs(err[row]) > tolerance)
    if not bad.any():
        return np.zeros(row.size, dtype=bool)
    end = np.cumsum(np.where(pr, length, 0.0))  # printed path at the end of every piece
    begin = end - np.where(pr, length, 0.0)
    spot_begin, spot_end = begin[bad], end[bad]  # both non-decreasing
    # nearest spot ending at or after the piece's start, and starting at or before its end
    after = np.searchsorted(spot_end, begin, side="left")
    before = np.searchsorted(spot_begin, end, side="right") - 1
    gap_after = np.where(after < spot_begin.size,
                         spot_begin[np.minimum(after, spot_begin.size - 1)] - end, np.inf)
    gap_before = np.where(before >= 0, begin - spot_end[np.maximum(before, 0)], np.inf)
    return np.asarray(np.minimum(np.maximum(gap_after, 0.0), np.maximum(gap_before, 0.0))
                      <= reach_mm)


def _spot_labels(bad: BoolArray, scored: BoolArray) -> tuple[IntArray, int]:
    """Spot of every row (``-1``: none), spots numbered in row order, and their count: a
    spot is a stretch of ``bad`` rows consecutive among the ``scored`` ones."""
    idx = np.flatnonzero(scored)
    b = bad[idx]
    first = b & ~np.concatenate(([False], b[:-1]))
    label = np.full(bad.size, -1, dtype=np.int64)
    label[idx[b]] = (np.cumsum(first) - 1)[b]
    return label, int(np.count_nonzero(first))


@dataclass(frozen=True, slots=True)
class SpotRanking:
    """The spots of a print, worst first.

    Attributes
    ----------
    rank
        Rank of the spot every original move belongs to (0 the worst; ``-1``: none),
        shape ``(n_moves,)``.
    weight
        ``Σ V·e²`` of every spot in rank order, mm³ (non-increasing).
    """

    rank: IntArray
    weight: FloatArray

    @property
    def count(self) -> int:
        """Number of spots."""
        return int(self.weight.size)

    def worst(self, count: int) -> BoolArray:
        """Moves of the ``count`` worst spots, shape ``(n_moves,)``."""
        return (self.rank >= 0) & (self.rank < count)


def rank_spots(flow_error: FloatArray, volume_mm3: FloatArray, scored: BoolArray, *,
               tolerance: float) -> SpotRanking:
    """The spots (stretches of consecutive scored moves whose flow error exceeds
    ``tolerance``), ranked by ``Σ V·e²``, the spot's share of the squared RMS flow error.

    Parameters
    ----------
    flow_error
        Flow error of every original move (fraction), shape ``(n_moves,)``.
    volume_mm3
        Commanded volume of every original move, mm³, shape ``(n_moves,)``.
    scored
        Moves the flow error is scored on (:func:`~flowtwin.compensation.metrics.
        extruding_moves`), shape ``(n_moves,)``.
    tolerance
        Largest flow error left alone (fraction, > 0).

    Returns
    -------
    SpotRanking
        Ties keep the order of the print.

    Raises
    ------
    DataError
        Arrays of different lengths or a bad tolerance.
    """
    err = np.asarray(flow_error, dtype=np.float64)
    vol = np.asarray(volume_mm3, dtype=np.float64)
    sc = np.asarray(scored, dtype=bool)
    _same_length("move", "volume_mm3", "one per move", err, vol, sc)
    _check_tolerance(tolerance)
    label, n = _spot_labels(sc & (np.abs(err) > tolerance), sc)
    inside = label >= 0
    weight = np.bincount(label[inside], weights=np.abs(vol[inside]) * err[inside] ** 2,
                         minlength=n).astype(np.float64)
    order = np.argsort(-weight, kind="stable")
    rank_of = np.empty(n, dtype=np.int64)
    rank_of[order] = np.arange(n, dtype=np.int64)
    rank = np.where(inside, rank_of[np.maximum(label, 0)] if n else -1, -1)
    return SpotRanking(rank=np.asarray(rank, dtype=np.int64), weight=weight[order])


def count_spots(bad: BoolArray, scored: BoolArray, chosen: BoolArray) -> tuple[int, int]:
    """Spots of the ``bad`` moves (stretches consecutive among the ``scored`` ones), and
    how many of them hold a ``chosen`` move.

    Parameters
    ----------
    bad, scored, chosen
        Masks over the original moves, shape ``(n_moves,)``.

    Returns
    -------
    tuple of int
        ``(spots, chosen spots)``.
    """
    b = np.asarray(bad, dtype=bool)
    label, n = _spot_labels(b, np.asarray(scored, dtype=bool) | b)
    hit = label[np.asarray(chosen, dtype=bool) & (label >= 0)]
    return n, int(np.unique(hit).size)


def _check_tolerance(tolerance: float) -> None:
    """Refuse a spot tolerance that is not a positive number."""
    if not (np.isfinite(tolerance) and tolerance > 0.0):
        raise DataError("spot tolerance must be positive", field="tolerance",
                        value=tolerance, allowed="> 0")


def _same_length(kind: str, field: str, allowed: str, *arrays: npt.NDArray[Any]) -> None:
    """Refuse arrays of different shapes (``kind``: what they hold, for the message)."""
    if len({a.shape for a in arrays}) > 1:
        raise DataError(f"{kind} arrays differ in length", field=field,
                        value=tuple(a.shape for a in arrays), allowed=allowed)
