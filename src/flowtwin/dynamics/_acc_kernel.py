"""Per-move accumulators of the lag integrator and their bookkeeping (compiled, private).

:func:`flowtwin.dynamics._lag_kernel.integrate_kernel` adds, segment by segment, the
filament commanded, fed, delivered and lost, the time and the extremes of force and flow
into one row per move (and one per stop between moves: ``A_*`` columns). The functions
here set those rows up (:func:`stop_rows`, :func:`prepare_segments`), turn them into the
per-move results (:func:`fill_move_results`) and sum them (:func:`acc_totals`,
compensated). ``S_*`` are the columns of the optional time series.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

__all__ = [
    "A_CMD", "A_FED", "A_FMAX", "A_FWD", "A_GRIND", "A_GTIME", "A_OUT", "A_QMAX", "A_QMIN",
    "A_SLIP", "A_TIME", "N_ACC", "N_SER", "S_E", "S_F", "S_Q", "S_SLIP", "S_T", "S_VCMD",
    "S_VFIL", "S_X", "acc_totals", "fill_move_results", "prepare_segments", "stop_rows",
]

# Accumulator columns (per move, per stop): filament lengths in mm, times in s.
A_CMD = 0     # ∫ v_cmd dt, the firmware's commanded filament (pressure advance included)
A_FWD = 1     # ∫ max(v_cmd, 0) dt, forward command (denominator of the mean slip)
A_FED = 2     # ∫ v_in dt, filament that entered the column (after slip and grinding)
A_OUT = 3     # ∫ v*_out dt = ∫ max(Δl, 0)/K dt, melt out in filament mm [001 Eq. 5]
A_SLIP = 4    # filament lost to slip
A_GRIND = 5   # filament lost while grinding
A_GTIME = 6   # time spent grinding
A_FMAX = 7    # peak feed force, N
A_QMAX = 8    # max v*_out, mm/s
A_QMIN = 9    # min v*_out, mm/s
A_TIME = 10   # time covered
N_ACC = 11

# Series columns.
S_T = 0
S_E = 1       # commanded extruder position (pressure advance included), mm
S_VCMD = 2    # commanded filament speed, mm/s
S_VFIL = 3    # filament speed into the column (after slip/grinding), mm/s
S_Q = 4       # v*_out, mm/s (times A_fil gives mm³/s)
S_F = 5       # feed force, N
S_SLIP = 6    # slip fraction
S_X = 7       # Δl, mm
N_SER = 8


@njit(cache=True)
def fill_move_results(acc: npt.NDArray[np.float64], area: float,
                      move_de: npt.NDArray[np.float64], move_t0: npt.NDArray[np.float64],
                      move_t1: npt.NDArray[np.float64], cmd: npt.NDArray[np.float64],
                      fed_cmd: npt.NDArray[np.float64], fed: npt.NDArray[np.float64],
                      out: npt.NDArray[np.float64], stop_out: npt.NDArray[np.float64],
                      ooze: npt.NDArray[np.float64], q_mean: npt.NDArray[np.float64],
                      q_min: npt.NDArray[np.float64], q_max: npt.NDArray[np.float64],
                      peak: npt.NDArray[np.float64], slip: npt.NDArray[np.float64],
                      slip_loss: npt.NDArray[np.float64], grind_loss: npt.NDArray[np.float64],
                      grinding: npt.NDArray[np.bool_], duration: npt.NDArray[np.float64],
                      stop_row: npt.NDArray[np.int64]) -> None:
    """Per-move results (the columns of ``result.MOVE_RESULT_DTYPE``, as strided views of
    one record array) from the accumulators.

    Row ``i`` of ``acc`` is move ``i``; row ``stop_row[i]`` the stop after it (``-1``: no
    stop). One pass,
    element by element (no record objects: numba would reference-count each).
    """
    n = move_de.shape[0]
    for i in range(n):
        d = move_t1[i] - move_t0[i]
        o = area * acc[i, A_OUT]
        r = stop_row[i]
        so = area * acc[r, A_OUT] if r >= 0 else 0.0
        cmd[i] = area * move_de[i]
        fed_cmd[i] = area * acc[i, A_CMD]
        fed[i] = area * acc[i, A_FED]
        out[i] = o
        stop_out[i] = so
        ooze[i] = so if move_de[i] > 0.0 else o + so
        q_mean[i] = o / d if d > 0.0 else 0.0
        q_min[i] = area * acc[i, A_QMIN] if acc[i, A_TIME] > 0.0 else 0.0
        q_max[i] = area * acc[i, A_QMAX]
        peak[i] = acc[i, A_FMAX]
        slip[i] = acc[i, A_SLIP] / acc[i, A_FWD] if acc[i, A_FWD] > 0.0 else 0.0
        slip_loss[i] = area * acc[i, A_SLIP]
        grind_loss[i] = area * acc[i, A_GRIND]
        grinding[i] = acc[i, A_GTIME] > 0.0 or (r >= 0 and acc[r, A_GTIME] > 0.0)
        duration[i] = d


@njit(cache=True)
def stop_rows(move: npt.NDArray[np.int64], gap: npt.NDArray[np.bool_], n: int,
              stop_row: npt.NDArray[np.int64]) -> int:
    """Accumulator rows of the stops: ``stop_row[i]`` for the stop after move ``i``
    (``n + 1``, ``n + 2``, ... in order of appearance; ``-1``: none). Returns the number of
    rows needed (moves, the stop before the first move at row ``n``, the stops)."""
    for i in range(n):
        stop_row[i] = -1
    rows = n + 1
    for j in range(move.shape[0]):
        m = move[j]
        if gap[j] and 0 <= m < n and stop_row[m] < 0:
            stop_row[m] = rows
            rows += 1
    return rows


@njit(cache=True)
def prepare_segments(move: npt.NDArray[np.int64], gap: npt.NDArray[np.bool_],
                     dt: npt.NDArray[np.float64], coef: npt.NDArray[np.float64], n: int,
                     stop_row: npt.NDArray[np.int64], acc: npt.NDArray[np.float64]) -> bool:
    """Check a feed and zero the accumulators in one pass.

    The kernel gives segment ``i`` the parameters of move ``clip(move[i], 0, n - 1)`` and
    accumulates it into row ``move[i]`` (a move), ``n`` (the stop before the first move) or
    ``stop_row[move[i]]`` (the stop after it, :func:`stop_rows`). ``acc`` (rows × N_ACC) is
    zeroed (``A_QMIN`` = inf). Returns False when a move index is out of ``[-1, n)``, a move
    segment has none, a duration is not > 0 or a coefficient is not finite.
    """
    for i in range(move.shape[0]):
        m = move[i]
        if m >= n or m < -1 or (m < 0 and not gap[i]) or not dt[i] > 0.0:
            return False
        if not (math.isfinite(coef[i, 0]) and math.isfinite(coef[i, 1])
                and math.isfinite(coef[i, 2]) and math.isfinite(coef[i, 3])):
            return False
    for r in range(acc.shape[0]):
        for q in range(N_ACC):
            acc[r, q] = 0.0
        acc[r, A_QMIN] = math.inf
    return True


@njit(cache=True)
def acc_totals(acc: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Column sums of the accumulators, compensated (Neumaier) so that the mass balance of
    millions of moves stays at rounding; ``A_FMAX``: the maximum instead."""
    out = np.zeros(N_ACC)
    comp = np.zeros(N_ACC)
    for r in range(acc.shape[0]):
        for q in range(N_ACC):
            v = acc[r, q]
            t = out[q] + v
            if abs(out[q]) >= abs(v):
                comp[q] += (out[q] - t) + v
            else:
                comp[q] += (v - t) + out[q]
            out[q] = t
    mx = 0.0
    for r in range(acc.shape[0]):
        if acc[r, A_FMAX] > mx:
            mx = acc[r, A_FMAX]
    for q in range(N_ACC):
        out[q] += comp[q]
    out[A_FMAX] = mx
    return out
