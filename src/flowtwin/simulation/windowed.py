"""Flow error over one nozzle diameter of printed path: the figure a user can act on.

The per-move flow error ``delivered / commanded − 1`` is the ratio of two numbers that
can both be tiny (slicers write moves of a few micrometres with 10⁻⁴ mm of E); a move of
0.03 mm at +600 % is not a bulge of the part. The melt leaves the orifice as a strand of
the nozzle's diameter ``d`` and is pressed into the bead under the nozzle [001 bead
cross-section, 004 strand model], so an excess of volume shows on the part spread along the
path over at least ``d``. The *windowed* flow error is therefore taken over windows of
``W = d`` of continuously printed path:

* consecutive printed moves form a *stretch* of continuous path; within a move the
  commanded and delivered volumes are spread evenly along its path (the twin resolves a
  move as a whole);
* a window ``[s, s + W]`` inside a stretch has the flow error
  ``delivered(window) / commanded(window) − 1``; a stretch shorter than ``W`` is one
  window;
* both volumes are piecewise linear in ``s``, so the ratio (linear-fractional between two
  positions where a window edge meets a move end) is monotonic there, and its largest and
  smallest values over all windows are at exactly those positions: every move's start as
  the window's left edge and every move's end as its right edge (clipped into the
  stretch). These *candidate* windows give the exact extremes.

:func:`windowed_flow` computes the extremes, the worst separate spots (non-overlapping
candidate windows, worst first) and, per move, the error of the window centred on it (a
smooth per-move figure for colouring a toolpath). The compensation's
:func:`flowtwin.compensation.metrics.window_peak` is its largest over-extrusion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.errors import DataError

__all__ = ["Window", "WindowedFlow", "path_lengths_mm", "windowed_flow"]

#: Candidate windows sorted first per spot asked for (the rest only when these overlap).
_HEAD_PER_SPOT = 64

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class Window:
    """One window of printed path.

    Attributes
    ----------
    error
        ``delivered / commanded − 1`` over the window (fraction).
    first_move, last_move
        First and last move (row of the move table) the window covers.
    centre_move
        The move at the window's middle.
    length_mm
        Path length of the window, mm (``W``, or the whole stretch where it is shorter).
    commanded_mm3, delivered_mm3
        Volumes over the window, mm³.
    """

    error: float
    first_move: int
    last_move: int
    centre_move: int
    length_mm: float
    commanded_mm3: float
    delivered_mm3: float


@dataclass(frozen=True, slots=True)
class WindowedFlow:
    """Flow error over windows of ``window_mm`` of printed path.

    Attributes
    ----------
    window_mm
        Window length ``W``, mm.
    peak_over
        Largest windowed flow error (fraction; 0 when nothing prints).
    peak_under
        Largest windowed shortfall, ``−min(error)`` (fraction; 0 when nothing prints or
        every window over-extrudes).
    worst_over, worst_under
        The worst separate windows (no two overlap), worst first.
    centred_error
        Per move: error of the window centred on the move's middle (clipped into its
        stretch), fraction; ``nan`` for moves that do not print. Shape ``(n_moves,)``.
    move_max_error, move_min_error
        Per move: largest and smallest error of the two candidate windows the move defines
        (starting at its start, ending at its end); ``nan`` for moves that do not print.
        Their maximum and minimum over any group of moves (a layer, a feature) are that
        group's windowed extremes. Shape ``(n_moves,)``.
    """

    window_mm: float
    peak_over: float
    peak_under: float
    worst_over: tuple[Window, ...]
    worst_under: tuple[Window, ...]
    centred_error: FloatArray
    move_max_error: FloatArray
    move_min_error: FloatArray


def path_lengths_mm(xyz_mm: FloatArray, start_xyz_mm: FloatArray) -> FloatArray:
    """Path length of every move, mm.

    Parameters
    ----------
    xyz_mm
        End position of every move, shape ``(n, 3)``.
    start_xyz_mm
        Position before the first move, shape ``(3,)``.

    Returns
    -------
    ndarray
        Shape ``(n,)``.
    """
    xyz = np.asarray(xyz_mm, dtype=np.float64)
    if xyz.shape[0] == 0:
        return np.zeros(0)
    start = np.vstack([np.asarray(start_xyz_mm, dtype=np.float64)[None, :3], xyz[:-1]])
    return np.asarray(np.sqrt(np.sum((xyz - start) ** 2, axis=1)), dtype=np.float64)


def windowed_flow(path_mm: npt.ArrayLike, commanded_mm3: npt.ArrayLike,
                  delivered_mm3: npt.ArrayLike, printed: npt.ArrayLike, *, window_mm: float,
                  spots: int = 10) -> WindowedFlow:
    """Flow error over every ``window_mm`` of continuously printed path (module docstring).

    Parameters
    ----------
    path_mm
        Path length of every move, mm, shape ``(n,)``.
    commanded_mm3, delivered_mm3
        Commanded (intended) and delivered melt volume of every move, mm³, ``(n,)``.
    printed
        Moves that print a bead (path > 0, commanded > 0), shape ``(n,)``.
    window_mm
        Window length ``W``, mm (> 0): the nozzle diameter.
    spots
        How many separate worst windows to list each way.

    Returns
    -------
    WindowedFlow

    Raises
    ------
    DataError
        ``window_mm`` not positive, or arrays of different shapes.
    """
    w = float(window_mm)
    if not (np.isfinite(w) and w > 0.0):
        raise DataError("window length must be positive", field="window_mm", value=window_mm,
                        allowed="> 0 mm")
    length_all = np.asarray(path_mm, dtype=np.float64)
    cmd_all = np.asarray(commanded_mm3, dtype=np.float64)
    dlv_all = np.asarray(delivered_mm3, dtype=np.float64)
    mask = np.asarray(printed, dtype=np.bool_)
    n = length_all.shape[0]
    if not (cmd_all.shape == dlv_all.shape == mask.shape == (n,)):
        raise DataError("per-move arrays of different shapes", field="printed",
                        value=(length_all.shape, cmd_all.shape, dlv_all.shape, mask.shape),
                        allowed="one value per move")
    centred = np.full(n, np.nan)
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return WindowedFlow(w, 0.0, 0.0, (), (), centred, centred.copy(), centred.copy())
    length = length_all[idx]
    # stretches: runs of consecutive printed rows
    new = np.concatenate(([True], np.diff(idx) != 1))
    stretch = np.cumsum(new) - 1
    first = np.flatnonzero(new)
    last = np.append(first[1:], idx.size) - 1
    g = np.concatenate(([0.0], np.cumsum(length)))       # position of every move end
    c_cum = np.concatenate(([0.0], np.cumsum(cmd_all[idx])))
    d_cum = np.concatenate(([0.0], np.cumsum(dlv_all[idx])))
    lo = g[first][stretch]                                # stretch of every move: [lo, hi]
    hi = g[last + 1][stretch]

    def windows(starts: FloatArray, lo_: FloatArray, hi_: FloatArray
                ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        # positions stay within their own stretch, whose nodes are consecutive in g
        s0 = np.clip(starts, lo_, np.maximum(hi_ - w, lo_))
        s1 = np.minimum(s0 + w, hi_)
        den = np.interp(s1, g, c_cum) - np.interp(s0, g, c_cum)
        num = np.interp(s1, g, d_cum) - np.interp(s0, g, d_cum)
        return s0, s1, den, num

    # candidates: a move's start at the left edge, or its end at the right edge
    s0, s1, den, num = windows(np.concatenate((g[:-1], g[1:] - w)),
                               np.concatenate((lo, lo)), np.concatenate((hi, hi)))
    ok = den > 0.0
    err = np.full(den.shape, np.nan)
    err[ok] = num[ok] / den[ok] - 1.0
    # centred windows, one per printed move
    _, _, cden, cnum = windows(0.5 * (g[:-1] + g[1:]) - 0.5 * w, lo, hi)
    cok = cden > 0.0
    centred[idx[cok]] = cnum[cok] / cden[cok] - 1.0
    # per move: the extremes of the two candidates it defines
    m = idx.size
    move_max = np.full(n, np.nan)
    move_min = np.full(n, np.nan)
    move_max[idx] = np.fmax(err[:m], err[m:])
    move_min[idx] = np.fmin(err[:m], err[m:])
    if not np.any(ok):
        return WindowedFlow(w, 0.0, 0.0, (), (), centred, move_max, move_min)
    peak_over = float(np.nanmax(err))
    peak_under = max(0.0, -float(np.nanmin(err)))

    top = idx.size - 1

    def pick(order: npt.NDArray[np.int64]) -> tuple[Window, ...]:
        # separate spots: no two windows share a move
        chosen: list[Window] = []
        taken: list[tuple[int, int]] = []
        for j in order.tolist():
            if len(chosen) >= spots:
                break
            a, b = float(s0[j]), float(s1[j])
            k0 = min(max(int(np.searchsorted(g, a, side="right")) - 1, 0), top)
            k1 = min(max(int(np.searchsorted(g, b, side="left")) - 1, k0), top)
            if any(k0 <= tb and ta <= k1 for ta, tb in taken):
                continue
            taken.append((k0, k1))
            kc = min(max(int(np.searchsorted(g, 0.5 * (a + b), side="right")) - 1, k0), k1)
            chosen.append(Window(float(err[j]), int(idx[k0]), int(idx[k1]), int(idx[kc]),
                                 b - a, float(den[j]), float(num[j])))
        return tuple(chosen)

    if spots <= 0:
        return WindowedFlow(w, peak_over, peak_under, (), (), centred, move_max, move_min)
    valid = np.flatnonzero(ok)

    def worst(key: FloatArray) -> tuple[Window, ...]:
        # candidates with key < 0, by key then position (a stable sort's order); the
        # few hundred smallest keys are sorted first, which finds the separate spots
        # unless those candidates overlap too much (then all of them are sorted)
        cand = valid[key[valid] < 0.0]
        k = _HEAD_PER_SPOT * spots
        if cand.size > 4 * k:
            thr = np.partition(key[cand], k)[k]
            head = cand[key[cand] <= thr]
            found = pick(head[np.argsort(key[head], kind="stable")])
            if len(found) >= spots:
                return found
        return pick(cand[np.argsort(key[cand], kind="stable")])

    return WindowedFlow(w, peak_over, peak_under, worst(-err), worst(err), centred, move_max,
                        move_min)
