"""Per-move accumulators of the lag integrator and their bookkeeping (compiled, private).

:func:`flowtwin.dynamics._lag_kernel.integrate_kernel` adds, segment by segment, the
filament commanded, fed, delivered and lost, the time and the extremes of force and flow
of the current move (or of the stop after it, or of the rest before the first move) in
registers (``A_*`` columns). A feed is in *move order* (the kernel checks it): the
segments of a move are contiguous, its stop follows them, moves come in index order.
So each accumulator row is complete when the next one starts: the kernel adds it to a
buffer of :data:`CHUNK` moves (rows ``2 j`` and ``2 j + 1``: move ``base + j`` and
the stop after it; row :data:`PRE_ROW`: the rest before the first move) and, once the
feed has moved past the chunk, writes its moves' results (:func:`finish_chunk`) straight
into the columns of the result table. No accumulator table of all moves is built: on a
print of 2 M moves that is 185 MB less fresh memory to zero, fill and read back; and the
hot loop calls out once per chunk, not once per move (a call per move, even inlined, cost
the kernel ~40 % on a 2.1 M-line print).

The totals are compensated (Neumaier) sums over the rows in the order moves, rest before
the first move, stops (:func:`add_row`, :func:`finish_totals`). ``S_*`` are the columns
of the optional time series.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = [
    "A_CMD", "A_FED", "A_FMAX", "A_FWD", "A_GRIND", "A_GTIME", "A_OUT", "A_QMAX", "A_QMIN",
    "A_SEEN", "A_SLIP", "A_TIME", "BAD_FEED", "BAD_ORDER", "BUF_ROWS", "BUF_WIDTH", "CHUNK",
    "N_ACC", "N_COLS", "N_SER", "PRE_ROW", "S_E", "S_F", "S_Q", "S_SLIP", "S_T", "S_VCMD",
    "S_VFIL", "S_X", "T_COMP", "T_SUM", "add_row", "clear_row", "finish_chunk", "finish_move",
    "finish_totals",
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

# The kernel's accumulator buffer ``(BUF_ROWS, BUF_WIDTH)``: ``CHUNK`` moves and their
# stops, then the rest before the first move; column ``A_SEEN`` marks rows with segments.
CHUNK = 256
PRE_ROW = 2 * CHUNK
BUF_ROWS = 2 * CHUNK + 1
A_SEEN = N_ACC
BUF_WIDTH = N_ACC + 1

# Rows of the totals ``(2, N_ACC)``: running sum and its compensation.
T_SUM = 0
T_COMP = 1

#: Float columns of the per-move results, in the order of ``result.MOVE_RESULT_DTYPE``
#: without ``grinding`` (passed separately, boolean).
N_COLS = 14

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

#: Failure codes of the kernel's check of a feed (``_lag_kernel.integrate_kernel``).
BAD_FEED = 1   # move index out of range, move segment without a move, dt, coefficients
BAD_ORDER = 2  # segments not in move order (``2 · move + gap`` decreasing)


@njit(cache=True, inline="always")
def clear_row(buf: npt.NDArray[np.float64], row: int) -> None:
    """Zero one accumulator row (``A_QMIN`` = inf: no sample yet; not seen)."""
    for q in range(BUF_WIDTH):
        buf[row, q] = 0.0
    buf[row, A_QMIN] = math.inf


@njit(cache=True, inline="always")
def finish_move(i: int, buf: npt.NDArray[np.float64], mrow: int, srow: int, has_stop: bool,
                area: float, move_de: npt.NDArray[np.float64],
                move_t0: npt.NDArray[np.float64], move_t1: npt.NDArray[np.float64],
                cols: tuple[npt.NDArray[np.float64], ...], grinding: npt.NDArray[np.bool_]
                ) -> None:
    """Results of move ``i`` (the columns of ``result.MOVE_RESULT_DTYPE``, strided views
    of one record array; ``cols`` in its order without ``grinding``) from its row
    ``buf[mrow]`` and, if ``has_stop``, its stop's row ``buf[srow]``.

    Element by element (no record objects: numba would reference-count each).
    """
    d = move_t1[i] - move_t0[i]
    o = area * buf[mrow, A_OUT]
    so = area * buf[srow, A_OUT] if has_stop else 0.0
    cols[0][i] = area * move_de[i]
    cols[1][i] = area * buf[mrow, A_CMD]
    cols[2][i] = area * buf[mrow, A_FED]
    cols[3][i] = o
    cols[4][i] = so
    cols[5][i] = so if move_de[i] > 0.0 else o + so
    cols[6][i] = o / d if d > 0.0 else 0.0
    cols[7][i] = area * buf[mrow, A_QMIN] if buf[mrow, A_TIME] > 0.0 else 0.0
    cols[8][i] = area * buf[mrow, A_QMAX]
    cols[9][i] = buf[mrow, A_FMAX]
    fwd = buf[mrow, A_FWD]
    cols[10][i] = buf[mrow, A_SLIP] / fwd if fwd > 0.0 else 0.0
    cols[11][i] = area * buf[mrow, A_SLIP]
    cols[12][i] = area * buf[mrow, A_GRIND]
    cols[13][i] = d
    grinding[i] = buf[mrow, A_GTIME] > 0.0 or (has_stop and buf[srow, A_GTIME] > 0.0)


@njit(cache=True, inline="always")
def add_row(tot: npt.NDArray[np.float64], buf: npt.NDArray[np.float64], row: int) -> None:
    """Add one accumulator row to the compensated totals ``tot`` (``T_SUM``, ``T_COMP``).

    Neumaier's summation per column, so that the mass balance of millions of moves stays
    at rounding; ``A_FMAX``: the maximum instead. Only the columns the summary reads
    (commanded, fed, out, slip, grind) are summed.
    """
    for q in (A_CMD, A_FED, A_OUT, A_SLIP, A_GRIND):
        v = buf[row, q]
        s = tot[T_SUM, q]
        t = s + v
        if abs(s) >= abs(v):
            tot[T_COMP, q] += (s - t) + v
        else:
            tot[T_COMP, q] += (v - t) + s
        tot[T_SUM, q] = t
    if buf[row, A_FMAX] > tot[T_SUM, A_FMAX]:
        tot[T_SUM, A_FMAX] = buf[row, A_FMAX]


@njit(cache=True, nogil=True)
def finish_totals(tot: npt.NDArray[np.float64]) -> None:
    """Fold the compensation into the sums (``tot[T_SUM]`` becomes the totals)."""
    for q in (A_CMD, A_FED, A_OUT, A_SLIP, A_GRIND):
        tot[T_SUM, q] += tot[T_COMP, q]
        tot[T_COMP, q] = 0.0


@njit(cache=True, nogil=True)
def finish_chunk(buf: npt.NDArray[np.float64], base: int, count: int, area: float,
                 move_de: npt.NDArray[np.float64], move_t0: npt.NDArray[np.float64],
                 move_t1: npt.NDArray[np.float64], cols: tuple[npt.NDArray[np.float64], ...],
                 grinding: npt.NDArray[np.bool_], stops: npt.NDArray[np.float64],
                 n_stops: int, tot: npt.NDArray[np.float64]) -> int:
    """Results of moves ``base .. base + count - 1`` from the buffer rows ``0 .. 2 count``
    (:func:`finish_move`), their rows added to the totals in move order and the rows of
    their stops copied to ``stops[n_stops:]``; the rows cleared. Returns the new number
    of stops."""
    for j in range(count):
        mrow = 2 * j
        srow = mrow + 1
        has_stop = buf[srow, A_SEEN] != 0.0
        finish_move(base + j, buf, mrow, srow, has_stop, area, move_de, move_t0, move_t1,
                    cols, grinding)
        add_row(tot, buf, mrow)
        if has_stop:
            for q in range(N_ACC):
                stops[n_stops, q] = buf[srow, q]
            n_stops += 1
        clear_row(buf, mrow)
        clear_row(buf, srow)
    return n_stops
