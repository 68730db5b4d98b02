"""Compiled assembly of the nominal feed segments (private; see :mod:`.feed`).

One pass over the moves writes, in time order, the accelerate / cruise / decelerate
phases of each move and the stop before the next one, skipping empty ones — the same
arrays the vectorised form would give, without its (n, 4) temporaries.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit

__all__ = ["build_segments"]


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
    cap = 4 * n + 1
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
