"""Compiled assembly of the nominal feed segments (private; see :mod:`.feed`).

One pass over the moves writes, in time order, the accelerate / cruise / decelerate
phases of each move and the stop before the next one, skipping empty ones — the same
arrays the vectorised form would give, without its (n, 4) temporaries.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

__all__ = ["BAD_NONE", "BAD_NO_MOTION", "BAD_OVERLAP", "BAD_PHASE_TIME", "build_segments",
           "prepare_moves"]


@njit(cache=True)
def build_segments(ts: npt.NDArray[np.float64], te: npt.NDArray[np.float64],
                   ta: npt.NDArray[np.float64],
                   tc: npt.NDArray[np.float64], td: npt.NDArray[np.float64],
                   sv: npt.NDArray[np.float64], cv: npt.NDArray[np.float64],
                   ev: npt.NDArray[np.float64], de: npt.NDArray[np.float64],
                   e_start: float, lead_s: float, tail_s: float
                   ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64],
                              npt.NDArray[np.float64], npt.NDArray[np.float64],
                              npt.NDArray[np.int64], npt.NDArray[np.int8]]:
    """Segments ``(t0, dt, coef (m, 4), e0, move, phase)`` of the nominal feed.

    ``ts``, ``te`` are the move start and end times (the stop after move ``i`` is
    ``[te[i], ts[i + 1])``).
    ``sv``, ``cv``, ``ev`` are the E speeds at the phase ends (path speed times the E
    ratio); the stop after the last move lasts ``tail_s``, a rest of ``lead_s`` comes
    first (move index -1). Phase codes: 0 accel, 1 cruise, 2 decel, 3 stop.
    """
    n = ts.shape[0]
    cap = 1 if lead_s > 0.0 else 0  # count first: the arrays are allocated at their size
    for i in range(n):
        cap += (ta[i] > 0.0) + (tc[i] > 0.0) + (td[i] > 0.0)
        if ((ts[i + 1] - te[i]) if i + 1 < n else tail_s) > 0.0:
            cap += 1
    t0 = np.empty(cap)
    dt = np.empty(cap)
    coef = np.zeros((cap, 4))
    e0 = np.empty(cap)
    move = np.empty(cap, dtype=np.int64)
    phase = np.empty(cap, dtype=np.int8)
    k = 0
    if lead_s > 0.0:
        t0[k] = (ts[0] if n > 0 else 0.0) - lead_s
        dt[k] = lead_s
        e0[k] = e_start
        move[k] = -1
        phase[k] = 3
        k += 1
    e = e_start
    for i in range(n):
        t = ts[i]
        ea = 0.5 * (sv[i] + cv[i]) * ta[i]
        if ta[i] > 0.0:
            t0[k] = t
            dt[k] = ta[i]
            coef[k, 0] = sv[i]
            coef[k, 1] = (cv[i] - sv[i]) / ta[i]
            e0[k] = e
            move[k] = i
            phase[k] = 0
            k += 1
        if tc[i] > 0.0:
            t0[k] = t + ta[i]
            dt[k] = tc[i]
            coef[k, 0] = cv[i]
            e0[k] = e + ea
            move[k] = i
            phase[k] = 1
            k += 1
        if td[i] > 0.0:
            t0[k] = t + ta[i] + tc[i]
            dt[k] = td[i]
            coef[k, 0] = cv[i]
            coef[k, 1] = (ev[i] - cv[i]) / td[i]
            e0[k] = e + ea + cv[i] * tc[i]
            move[k] = i
            phase[k] = 2
            k += 1
        e += de[i]
        gap = (ts[i + 1] - te[i]) if i + 1 < n else tail_s
        if gap > 0.0:
            t0[k] = te[i]
            dt[k] = gap
            e0[k] = e
            move[k] = i
            phase[k] = 3
            k += 1
    return t0[:k], dt[:k], coef[:k], e0[:k], move[:k], phase[:k]


#: Failure codes of :func:`prepare_moves` (checked in this order, first move reported).
BAD_NONE = 0
BAD_PHASE_TIME = 1   # non-finite or negative phase time
BAD_OVERLAP = 2      # a move starts before the previous one ends
BAD_NO_MOTION = 3    # de != 0 but no path length / duration


@njit(cache=True)
def _clamp(t: float, residue: float) -> float:
    return 0.0 if (t < 0.0 and t >= -residue) else t


@njit(cache=True)
def prepare_moves(ph: npt.NDArray[np.void], mv: npt.NDArray[np.void], tool: int,
                  all_tools: bool, residue: float, overlap_tol: float,
                  ts: npt.NDArray[np.float64], te: npt.NDArray[np.float64],
                  ta: npt.NDArray[np.float64], tc: npt.NDArray[np.float64],
                  td: npt.NDArray[np.float64], sv: npt.NDArray[np.float64],
                  cv: npt.NDArray[np.float64], ev: npt.NDArray[np.float64],
                  de: npt.NDArray[np.float64], err: npt.NDArray[np.float64]) -> int:
    """Phase times (planner residue ``>= -residue`` taken as 0), move ends, E speeds at the
    phase ends and ``de · flow`` of every move, straight from the structured arrays.

    ``ph``: :data:`~flowtwin.planner.timeline.PHASE_DTYPE` rows; ``mv``:
    :data:`~flowtwin.gcode.moves.MOVE_DTYPE` rows; ``tool``/``all_tools``: which moves drive
    this extruder. Returns a ``BAD_*`` code; ``err`` gets ``(index, value[, extra])`` of
    the first failing move. One pass per check, in the order of the codes.
    """
    n = ph.shape[0]
    for i in range(n):
        a = _clamp(ph[i].accel_t, residue)
        c = _clamp(ph[i].cruise_t, residue)
        d = _clamp(ph[i].decel_t, residue)
        t = ph[i].t_start
        ta[i] = a
        tc[i] = c
        td[i] = d
        ts[i] = t
        te[i] = t + (a + c + d)
    for i in range(n):
        if (not math.isfinite(ta[i] + tc[i] + td[i] + ts[i])) or ta[i] < 0.0 \
                or tc[i] < 0.0 or td[i] < 0.0:
            err[0] = i
            return BAD_PHASE_TIME
    for i in range(1, n):
        if te[i - 1] - ts[i] > overlap_tol * max(1.0, abs(ts[i])):
            err[0] = i
            err[1] = te[i - 1]
            return BAD_OVERLAP
    for i in range(n):
        d_e = mv[i].de * np.float64(mv[i].flow)
        if not all_tools and mv[i].tool != tool:
            d_e = 0.0
        de[i] = d_e
        v0 = np.float64(ph[i].start_v)  # float32 fields: compute in float64
        vc = np.float64(ph[i].cruise_v)
        v1 = np.float64(ph[i].end_v)
        length = 0.5 * (v0 + vc) * ta[i] + vc * tc[i] + 0.5 * (vc + v1) * td[i]
        if d_e != 0.0 and not length > 0.0:
            err[0] = i
            err[1] = d_e
            return BAD_NO_MOTION
        r = d_e / length if length > 0.0 else 0.0
        sv[i] = v0 * r
        cv[i] = vc * r
        ev[i] = v1 * r
    return BAD_NONE
