"""Compiled assembly of the nominal feed segments (private; see :mod:`.feed`).

One pass over the moves writes, in time order, the accelerate / cruise / decelerate
phases of each move and the stop before the next one, skipping empty ones — the same
arrays the vectorised form would give, without its (n, 4) temporaries.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = ["BAD_NONE", "BAD_NO_MOTION", "BAD_OVERLAP", "BAD_PHASE_TIME", "build_segments",
           "count_segments", "prepare_moves"]


@njit(cache=True, inline="always")
def _phase_speeds(ph: npt.NDArray[np.void], i: int, a: float, c: float, d: float,
                  d_e: float) -> tuple[float, float, float, float]:
    """Path length of move ``i`` from its phases and the E speeds at the phase ends
    (``v · d_e / length``; zero without motion)."""
    v0 = np.float64(ph[i].start_v)  # float32 fields: compute in float64
    vc = np.float64(ph[i].cruise_v)
    v1 = np.float64(ph[i].end_v)
    length = 0.5 * (v0 + vc) * a + vc * c + 0.5 * (vc + v1) * d
    r = d_e / length if length > 0.0 else 0.0
    return length, v0 * r, vc * r, v1 * r


@njit(cache=True, nogil=True)
def count_segments(ph: npt.NDArray[np.void], ts: npt.NDArray[np.float64],
                   te: npt.NDArray[np.float64], residue: float, lead_s: float,
                   tail_s: float) -> int:
    """Number of segments :func:`build_segments` writes (non-empty phases, stops, lead)."""
    n = ts.shape[0]
    cap = 1 if lead_s > 0.0 else 0
    for i in range(n):
        cap += ((_clamp(ph[i].accel_t, residue) > 0.0) + (_clamp(ph[i].cruise_t, residue) > 0.0)
                + (_clamp(ph[i].decel_t, residue) > 0.0))
        if ((ts[i + 1] - te[i]) if i + 1 < n else tail_s) > 0.0:
            cap += 1
    return cap


@njit(cache=True, nogil=True)
def build_segments(ph: npt.NDArray[np.void], ts: npt.NDArray[np.float64],
                   te: npt.NDArray[np.float64], de: npt.NDArray[np.float64], residue: float,
                   e_start: float, lead_s: float, tail_s: float, t0: npt.NDArray[np.float64],
                   dt: npt.NDArray[np.float64], coef: npt.NDArray[np.float64],
                   e0: npt.NDArray[np.float64], move: npt.NDArray[np.int64],
                   phase: npt.NDArray[np.int8], gaps: npt.NDArray[np.bool_]) -> int:
    """Fill the segments ``(t0, dt, coef (m, 4), e0, move, phase, gap)`` of the nominal
    feed (``m`` from :func:`count_segments`; allocated by the caller, so that numpy's large
    allocations back them, not numba's: 4 KiB pages, ~72 k page faults on the 2.1 M-line
    print, against a few hundred). Returns the number written.

    ``ph``: the checked phases (:func:`prepare_moves`; their times are clamped again here
    with the same ``residue``, and the E speeds at the phase ends recomputed, rather than
    kept in six move-sized arrays); ``ts``, ``te``, ``de``: move start and end times and
    ``de · flow`` from :func:`prepare_moves` (the stop after move ``i`` is
    ``[te[i], ts[i + 1])``). The stop after the last move lasts ``tail_s``, a rest of
    ``lead_s`` comes first (move index -1). Phase codes: 0 accel, 1 cruise, 2 decel,
    3 stop (``gap``).
    """
    n = ts.shape[0]
    k = 0
    if lead_s > 0.0:
        t0[k] = (ts[0] if n > 0 else 0.0) - lead_s
        dt[k] = lead_s
        coef[k, 0] = coef[k, 1] = coef[k, 2] = coef[k, 3] = 0.0
        e0[k] = e_start
        move[k] = -1
        phase[k] = 3
        gaps[k] = True
        k += 1
    e = e_start
    for i in range(n):
        t = ts[i]
        ta = _clamp(ph[i].accel_t, residue)
        tc = _clamp(ph[i].cruise_t, residue)
        td = _clamp(ph[i].decel_t, residue)
        _, sv, cv, ev = _phase_speeds(ph, i, ta, tc, td, de[i])
        ea = 0.5 * (sv + cv) * ta
        if ta > 0.0:
            t0[k] = t
            dt[k] = ta
            coef[k, 0] = sv
            coef[k, 1] = (cv - sv) / ta
            coef[k, 2] = coef[k, 3] = 0.0
            e0[k] = e
            move[k] = i
            phase[k] = 0
            gaps[k] = False
            k += 1
        if tc > 0.0:
            t0[k] = t + ta
            dt[k] = tc
            coef[k, 0] = cv
            coef[k, 1] = coef[k, 2] = coef[k, 3] = 0.0
            e0[k] = e + ea
            move[k] = i
            phase[k] = 1
            gaps[k] = False
            k += 1
        if td > 0.0:
            t0[k] = t + ta + tc
            dt[k] = td
            coef[k, 0] = cv
            coef[k, 1] = (ev - cv) / td
            coef[k, 2] = coef[k, 3] = 0.0
            e0[k] = e + ea + cv * tc
            move[k] = i
            phase[k] = 2
            gaps[k] = False
            k += 1
        e += de[i]
        gap = (ts[i + 1] - te[i]) if i + 1 < n else tail_s
        if gap > 0.0:
            t0[k] = te[i]
            dt[k] = gap
            coef[k, 0] = coef[k, 1] = coef[k, 2] = coef[k, 3] = 0.0
            e0[k] = e
            move[k] = i
            phase[k] = 3
            gaps[k] = True
            k += 1
    return k


#: Failure codes of :func:`prepare_moves` (checked in this order, first move reported).
BAD_NONE = 0
BAD_PHASE_TIME = 1   # non-finite or negative phase time
BAD_OVERLAP = 2      # a move starts before the previous one ends
BAD_NO_MOTION = 3    # de != 0 but no path length / duration


@njit(cache=True, nogil=True)
def _clamp(t: float, residue: float) -> float:
    return 0.0 if (t < 0.0 and t >= -residue) else t


@njit(cache=True, nogil=True)
def prepare_moves(ph: npt.NDArray[np.void], mv: npt.NDArray[np.void], tool: int,
                  all_tools: bool, residue: float, overlap_tol: float,
                  ts: npt.NDArray[np.float64], te: npt.NDArray[np.float64],
                  de: npt.NDArray[np.float64], err: npt.NDArray[np.float64]) -> int:
    """Move start and end times (planner residue ``>= -residue`` in phase times taken as
    0) and ``de · flow`` of every move, straight from the structured arrays, and the
    checks of the phases, in one pass.

    ``ph``: :data:`~flowtwin.planner.timeline.PHASE_DTYPE` rows; ``mv``:
    :data:`~flowtwin.gcode.moves.MOVE_DTYPE` rows; ``tool``/``all_tools``: which moves drive
    this extruder. Returns a ``BAD_*`` code: the first code in their order that any move
    fails, reported for the first move failing it; ``err`` gets its index and values
    (phase times: ``accel, cruise, decel, start``; overlap: the previous move's end;
    no motion: ``de · flow``).
    """
    n = ph.shape[0]
    first = np.full(4, n)  # first failing move per code
    for i in range(n):
        a = _clamp(ph[i].accel_t, residue)
        c = _clamp(ph[i].cruise_t, residue)
        d = _clamp(ph[i].decel_t, residue)
        t = ph[i].t_start
        ts[i] = t
        te[i] = t + (a + c + d)
        if (not math.isfinite(a + c + d + t)) or a < 0.0 or c < 0.0 or d < 0.0:
            if first[BAD_PHASE_TIME] == n:
                first[BAD_PHASE_TIME] = i
                err[1] = a
                err[2] = c
                err[3] = d
                err[4] = t
        elif i > 0 and te[i - 1] - t > overlap_tol * max(1.0, abs(t)) \
                and first[BAD_OVERLAP] == n:
            first[BAD_OVERLAP] = i
            err[5] = te[i - 1]
        d_e = mv[i].de * np.float64(mv[i].flow)
        if not all_tools and mv[i].tool != tool:
            d_e = 0.0
        de[i] = d_e
        length = _phase_speeds(ph, i, a, c, d, d_e)[0]
        if d_e != 0.0 and not length > 0.0 and first[BAD_NO_MOTION] == n:
            first[BAD_NO_MOTION] = i
            err[6] = d_e
    for code in (BAD_PHASE_TIME, BAD_OVERLAP, BAD_NO_MOTION):
        if first[code] < n:
            err[0] = first[code]
            if code == BAD_OVERLAP:
                err[1] = err[5]
            elif code == BAD_NO_MOTION:
                err[1] = err[6]
            return code
    return BAD_NONE
