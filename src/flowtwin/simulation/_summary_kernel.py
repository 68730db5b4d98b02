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

from flowtwin._jit import njit
from flowtwin.gcode.groups import compensated_add

__all__ = [
    "G_CMD",
    "G_DELIV",
    "G_FMAX",
    "G_GRIND",
    "G_OOZE",
    "G_TIME",
    "G_W",
    "G_WEE",
    "G_WORST",
    "N_GROUP",
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
    "add_groups",
    "add_totals",
    "extruding_mask",
    "fold_groups",
    "fold_totals",
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


@njit(cache=True, nogil=True)
def extruding_mask(kind: npt.NDArray[np.uint8], cmd: npt.NDArray[np.float64], bits: int,
                   out: npt.NDArray[np.bool_]) -> None:
    """``out[i]`` = move ``i`` lays a bead: all of ``bits`` set in ``kind`` and ``cmd > 0``."""
    for i in range(kind.shape[0]):
        out[i] = (kind[i] & bits) == bits and cmd[i] > 0.0


@njit(cache=True, nogil=True)
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
    add_totals(s, c, False, kind, bits, cmd, out, stop_out, fed_cmd, slip_loss, ooze,
               peak_force, grinding, flow_error, width_mean, width_nominal, margin, narrow)
    return fold_totals(s, c)


@njit(cache=True, nogil=True)
def fold_totals(s: npt.NDArray[np.float64], c: npt.NDArray[np.float64]
                ) -> npt.NDArray[np.float64]:
    """The totals from running sums ``s`` and their compensation terms ``c``."""
    t = s.copy()
    for q in _SUMS:
        t[q] += c[q]
    return t


@njit(cache=True, nogil=True)
def add_totals(s: npt.NDArray[np.float64], c: npt.NDArray[np.float64], was_grinding: bool,
               kind: npt.NDArray[np.uint8], bits: int, cmd: npt.NDArray[np.float64],
               out: npt.NDArray[np.float64], stop_out: npt.NDArray[np.float64],
               fed_cmd: npt.NDArray[np.float64], slip_loss: npt.NDArray[np.float64],
               ooze: npt.NDArray[np.float64], peak_force: npt.NDArray[np.float64],
               grinding: npt.NDArray[np.bool_], flow_error: npt.NDArray[np.float64],
               width_mean: npt.NDArray[np.float64], width_nominal: npt.NDArray[np.float64],
               margin: npt.NDArray[np.float64], narrow: npt.NDArray[np.bool_]) -> bool:
    """Add moves to the running totals ``s`` (compensation terms in ``c``; start with zeros
    and ``s[T_MARGIN_MIN] = inf``); ``was_grinding``: the move before them was grinding.
    Returns whether the last move grinds. Consecutive calls on consecutive moves give the
    totals of one call on all of them, to the bit (:func:`fold_totals` at the end)."""
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
    return was_grinding


# per-group columns of add_groups (sums carry a compensation column each)
G_TIME = 0     # Σ duration_s
G_CMD = 1      # Σ cmd_mm3
G_DELIV = 2    # Σ out_mm3 + stop_out_mm3
G_WEE = 3      # Σ cmd·flow_error² over printing moves
G_W = 4        # Σ cmd over printing moves
G_OOZE = 5     # Σ ooze_mm3
G_GRIND = 6    # grinding moves
G_WORST = 7    # max |width_mean − width_nominal| over printing moves (initial 0)
G_FMAX = 8     # max peak_force_n (initial 0)
N_GROUP = 9
_G_SUMS = (G_TIME, G_CMD, G_DELIV, G_WEE, G_W, G_OOZE)


@njit(cache=True, nogil=True)
def add_groups(key: npt.NDArray[np.integer], lo: int, acc: npt.NDArray[np.float64],
               comp: npt.NDArray[np.float64], count: npt.NDArray[np.int64],
               kind: npt.NDArray[np.uint8], bits: int, duration: npt.NDArray[np.float64],
               cmd: npt.NDArray[np.float64], out: npt.NDArray[np.float64],
               stop_out: npt.NDArray[np.float64], ooze: npt.NDArray[np.float64],
               peak_force: npt.NDArray[np.float64], grinding: npt.NDArray[np.bool_],
               flow_error: npt.NDArray[np.float64], width_mean: npt.NDArray[np.float64],
               width_nominal: npt.NDArray[np.float64]) -> None:
    """Add every move to the row ``key − lo`` of ``acc`` (``(groups, N_GROUP)``; sums with
    their compensation terms in ``comp``, moves in ``count``): the per-layer and
    per-feature columns ``G_*`` in one pass."""
    for i in range(key.shape[0]):
        g = int(key[i]) - lo
        count[g] += 1
        compensated_add(acc[g], comp[g], G_TIME, duration[i])
        compensated_add(acc[g], comp[g], G_CMD, cmd[i])
        compensated_add(acc[g], comp[g], G_DELIV, out[i] + stop_out[i])
        compensated_add(acc[g], comp[g], G_OOZE, ooze[i])
        acc[g, G_FMAX] = max(acc[g, G_FMAX], peak_force[i])
        if grinding[i]:
            acc[g, G_GRIND] += 1.0
        if (kind[i] & bits) == bits and cmd[i] > 0.0:
            e = flow_error[i]
            compensated_add(acc[g], comp[g], G_WEE, cmd[i] * e * e)
            compensated_add(acc[g], comp[g], G_W, cmd[i])
            acc[g, G_WORST] = max(acc[g, G_WORST], abs(width_mean[i] - width_nominal[i]))


@njit(cache=True, nogil=True)
def fold_groups(acc: npt.NDArray[np.float64], comp: npt.NDArray[np.float64]
                ) -> npt.NDArray[np.float64]:
    """The group columns from running sums and their compensation terms."""
    out = acc.copy()
    for g in range(acc.shape[0]):
        for q in _G_SUMS:
            out[g, q] += comp[g, q]
    return out
