"""Compiled per-tool, per-feature and per-layer sums of planned moves (private; see
:class:`flowtwin.planner.totals.PlanTotals`).

One pass over the move and phase records of a chunk adds every move to its tool, feature
and layer; the accumulators live in the caller and carry from chunk to chunk, so a print
read in pieces sums exactly as in one piece (the same additions in the same order). Tool
and feature sums are Neumaier-compensated, as in :func:`flowtwin.gcode.groups.group_sums`;
layer sums are plain running sums in move order, as ``np.bincount`` forms them.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit
from flowtwin.gcode.groups import compensated_add

__all__ = ["accumulate", "key_ranges"]


@njit(cache=True, nogil=True)
def key_ranges(tool: npt.NDArray[np.int16], feature: npt.NDArray[np.int16],
               layer: npt.NDArray[np.int32]) -> tuple[int, int, int, int, int, int]:
    """``(tool_lo, tool_hi, feature_lo, feature_hi, layer_lo, layer_hi)`` of ``n >= 1``
    moves."""
    t_lo = t_hi = int(tool[0])
    f_lo = f_hi = int(feature[0])
    l_lo = l_hi = int(layer[0])
    for i in range(1, tool.shape[0]):
        t = int(tool[i])
        f = int(feature[i])
        g = int(layer[i])
        t_lo = min(t_lo, t)
        t_hi = max(t_hi, t)
        f_lo = min(f_lo, f)
        f_hi = max(f_hi, f)
        l_lo = min(l_lo, g)
        l_hi = max(l_hi, g)
    return t_lo, t_hi, f_lo, f_hi, l_lo, l_hi


@njit(cache=True, nogil=True)
def accumulate(kind: npt.NDArray[np.uint8], tool: npt.NDArray[np.int16],
               de: npt.NDArray[np.float64], flow: npt.NDArray[np.float32],
               feature: npt.NDArray[np.int16], layer: npt.NDArray[np.int32],
               z: npt.NDArray[np.floating], accel_t: npt.NDArray[np.float64],
               cruise_t: npt.NDArray[np.float64], decel_t: npt.NDArray[np.float64],
               extrude_bit: int, fw_retract_bit: int,
               t_lo: int, t_count: npt.NDArray[np.int64], written: npt.NDArray[np.float64],
               w_c: npt.NDArray[np.float64], extruded: npt.NDArray[np.float64],
               x_c: npt.NDArray[np.float64],
               f_lo: int, f_count: npt.NDArray[np.int64], f_time: npt.NDArray[np.float64],
               f_c: npt.NDArray[np.float64],
               l_lo: int, l_count: npt.NDArray[np.int64], l_fil: npt.NDArray[np.float64],
               l_time: npt.NDArray[np.float64], l_first_z: npt.NDArray[np.float64]) -> int:
    """Add every move to the accumulators (arrays cover the moves' key ranges from
    ``t_lo``, ``f_lo``, ``l_lo``); return how many are extruding moves written in the G-code.

    Per tool: moves, E written (firmware retractions left out, mm) and ``Σ de·flow`` (mm),
    each with its compensation term. Per feature: moves and move time (s) with its
    compensation term. Per layer: moves, E written (mm), move time (s) and the Z of the
    layer's first extruding move (NaN until there is one).
    """
    ext_written = 0
    for i in range(kind.shape[0]):
        k = kind[i]
        is_written = (k & fw_retract_bit) == 0
        b = int(tool[i]) - t_lo
        t_count[b] += 1
        if is_written:
            compensated_add(written, w_c, b, de[i])
            if (k & extrude_bit) != 0:
                ext_written += 1
        compensated_add(extruded, x_c, b, de[i] * flow[i])
        dur = accel_t[i] + cruise_t[i] + decel_t[i]
        g = int(feature[i]) - f_lo
        f_count[g] += 1
        compensated_add(f_time, f_c, g, dur)
        j = int(layer[i]) - l_lo
        l_count[j] += 1
        if is_written:
            l_fil[j] += de[i]
        l_time[j] += dur
        if (k & extrude_bit) != 0 and math.isnan(l_first_z[j]):
            l_first_z[j] = z[i]
    return ext_written
