"""Compiled per-tool and per-feature totals of a planned print (private; see
:meth:`flowtwin.planner.plan_file.PlanResult.summary`).

Two passes over the move and phase records instead of a dozen numpy passes over strided
record fields (0.24 s → ~0.04 s on a 2.1 M-move print). Sums are Neumaier-compensated,
as in :func:`flowtwin.gcode.groups.group_sums`, so the figures agree with it exactly.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit

from flowtwin.gcode.groups import compensated_add

__all__ = ["plan_totals"]


@njit(cache=True)
def plan_totals(kind: npt.NDArray[np.uint8], tool: npt.NDArray[np.int16],
                de: npt.NDArray[np.float64], flow: npt.NDArray[np.float32],
                feature: npt.NDArray[np.int16], layer: npt.NDArray[np.int32],
                accel_t: npt.NDArray[np.float64], cruise_t: npt.NDArray[np.float64],
                decel_t: npt.NDArray[np.float64], extrude_bit: int, fw_retract_bit: int
                ) -> tuple[int, npt.NDArray[np.int64], npt.NDArray[np.float64],
                           npt.NDArray[np.float64], int, npt.NDArray[np.int64],
                           npt.NDArray[np.float64], int, int]:
    """Totals of ``n >= 1`` moves.

    Returns ``(tool_lo, tool_count, written_de, extruded, feature_lo, feature_count,
    feature_time_s, extruding_written, max_layer)``: per tool ``tool_lo + b`` its moves,
    the E written in the G-code (firmware retractions left out, mm) and ``Σ de·flow``
    (mm); per feature ``feature_lo + b`` its moves and move time (s); the number of
    extruding moves that are not firmware retractions; the largest layer index.
    """
    n = kind.shape[0]
    t_lo = tool[0]
    t_hi = tool[0]
    f_lo = feature[0]
    f_hi = feature[0]
    for i in range(1, n):
        t_lo = min(t_lo, tool[i])
        t_hi = max(t_hi, tool[i])
        f_lo = min(f_lo, feature[i])
        f_hi = max(f_hi, feature[i])
    nt = int(t_hi) - int(t_lo) + 1
    nf = int(f_hi) - int(f_lo) + 1
    t_count = np.zeros(nt, np.int64)
    written = np.zeros(nt)
    w_c = np.zeros(nt)
    extruded = np.zeros(nt)
    x_c = np.zeros(nt)
    f_count = np.zeros(nf, np.int64)
    f_time = np.zeros(nf)
    f_c = np.zeros(nf)
    ext_written = 0
    max_layer = layer[0]
    for i in range(n):
        b = int(tool[i]) - int(t_lo)
        t_count[b] += 1
        k = kind[i]
        is_written = (k & fw_retract_bit) == 0
        if is_written:
            compensated_add(written, w_c, b, de[i])
            if (k & extrude_bit) != 0:
                ext_written += 1
        compensated_add(extruded, x_c, b, de[i] * flow[i])
        g = int(feature[i]) - int(f_lo)
        f_count[g] += 1
        compensated_add(f_time, f_c, g, accel_t[i] + cruise_t[i] + decel_t[i])
        max_layer = max(max_layer, layer[i])
    for b in range(nt):
        written[b] += w_c[b]
        extruded[b] += x_c[b]
    for g in range(nf):
        f_time[g] += f_c[g]
    return (int(t_lo), t_count, written, extruded, int(f_lo), f_count, f_time, ext_written,
            int(max_layer))
