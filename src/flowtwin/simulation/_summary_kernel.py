"""Compiled whole-print totals of a simulation (private; see
:meth:`.result.SimulationResult.summary`).

One pass over the per-move columns instead of some forty numpy operations on strided
record fields (each a full pass with a temporary): 0.74 s → ~0.05 s on a 2.1 M-move print.
Sums are compensated (Neumaier), so they agree with numpy's pairwise sums to rounding.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

from flowtwin.gcode.groups import compensated_add

__all__ = [
    "N_TOTALS",
    "T_CMD",
    "T_DELIVERED",
    "T_EXT_OUT",
    "T_FED_FWD",
    "T_FORCE_MAX",
    "T_GRIND_EVENTS",
    "T_GRIND_MOVES",
    "T_MARGIN_MIN",
    "T_MARGIN_N",
    "T_NARROW",
    "T_OOZE",
    "T_OVER",
    "T_RMS_W",
    "T_RMS_WEE",
    "T_SLIP_LOSS",
    "T_UNDER",
    "T_WIDTH_DEV",
    "extruding_mask",
    "print_totals",
]

T_CMD = 0          # Σ cmd_mm3
T_DELIVERED = 1    # Σ out_mm3 + stop_out_mm3
T_EXT_OUT = 2      # Σ out_mm3 over printing moves
T_RMS_W = 3        # Σ cmd_mm3 over printing moves (RMS weight)
T_RMS_WEE = 4      # Σ cmd_mm3 · flow_error² over printing moves
T_OVER = 5         # max flow_error over printing moves (initial 0)
T_UNDER = 6        # max −flow_error over printing moves (initial 0)
T_WIDTH_DEV = 7    # max |width_mean − width_nominal| over printing moves (initial 0)
T_SLIP_LOSS = 8    # Σ slip_loss_mm3
T_FED_FWD = 9      # Σ max(fed_cmd_mm3, 0)
T_FORCE_MAX = 10   # max peak_force_n (initial 0)
T_MARGIN_MIN = 11  # min finite force_margin_n
T_MARGIN_N = 12    # count of finite force_margin_n
T_GRIND_EVENTS = 13  # starts of grinding runs
T_GRIND_MOVES = 14   # grinding moves
T_OOZE = 15        # Σ ooze_mm3
T_NARROW = 16      # narrow printing moves
N_TOTALS = 17

_SUMS = (T_CMD, T_DELIVERED, T_EXT_OUT, T_RMS_W, T_RMS_WEE, T_SLIP_LOSS, T_FED_FWD, T_OOZE)


@njit(cache=True)
def extruding_mask(kind: npt.NDArray[np.uint8], cmd: npt.NDArray[np.float64], bits: int,
                   out: npt.NDArray[np.bool_]) -> None:
    """``out[i]`` = move ``i`` lays a bead: all of ``bits`` set in ``kind`` and ``cmd > 0``."""
    for i in range(kind.shape[0]):
        out[i] = (kind[i] & bits) == bits and cmd[i] > 0.0


@njit(cache=True)
def print_totals(kind: npt.NDArray[np.uint8], bits: int, cmd: npt.NDArray[np.float64],
                 out: npt.NDArray[np.float64], stop_out: npt.NDArray[np.float64],
                 fed_cmd: npt.NDArray[np.float64], slip_loss: npt.NDArray[np.float64],
                 ooze: npt.NDArray[np.float64], peak_force: npt.NDArray[np.float64],
                 grinding: npt.NDArray[np.bool_], flow_error: npt.NDArray[np.float64],
                 width_mean: npt.NDArray[np.float64], width_nominal: npt.NDArray[np.float64],
                 margin: npt.NDArray[np.float64], narrow: npt.NDArray[np.bool_]
                 ) -> npt.NDArray[np.float64]:
    """The totals ``T_*`` of one print, in one pass (arrays: one entry per move, any
    stride; a printing move has all of ``bits`` in ``kind`` and ``cmd > 0``)."""
    s = np.zeros(N_TOTALS)
    c = np.zeros(N_TOTALS)
    s[T_MARGIN_MIN] = math.inf
    was_grinding = False
    for i in range(kind.shape[0]):
        ext = (kind[i] & bits) == bits and cmd[i] > 0.0
        compensated_add(s, c, T_CMD, cmd[i])
        compensated_add(s, c, T_DELIVERED, out[i] + stop_out[i])
        compensated_add(s, c, T_SLIP_LOSS, slip_loss[i])
        compensated_add(s, c, T_FED_FWD, max(fed_cmd[i], 0.0))
        compensated_add(s, c, T_OOZE, ooze[i])
        s[T_FORCE_MAX] = max(s[T_FORCE_MAX], peak_force[i])
        m = margin[i]
        if math.isfinite(m):
            s[T_MARGIN_MIN] = min(s[T_MARGIN_MIN], m)
            s[T_MARGIN_N] += 1.0
        g = grinding[i]
        if g:
            s[T_GRIND_MOVES] += 1.0
            if not was_grinding:
                s[T_GRIND_EVENTS] += 1.0
        was_grinding = g
        if ext:
            e = flow_error[i]
            compensated_add(s, c, T_EXT_OUT, out[i])
            compensated_add(s, c, T_RMS_W, cmd[i])
            compensated_add(s, c, T_RMS_WEE, cmd[i] * e * e)
            s[T_OVER] = max(s[T_OVER], e)
            s[T_UNDER] = max(s[T_UNDER], -e)
            s[T_WIDTH_DEV] = max(s[T_WIDTH_DEV], abs(width_mean[i] - width_nominal[i]))
            if narrow[i]:
                s[T_NARROW] += 1.0
    for q in _SUMS:
        s[q] += c[q]
    return s
