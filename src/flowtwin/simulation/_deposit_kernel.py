"""Compiled bead metrics per move (private; see :func:`.result.deposition_metrics`)."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit

__all__ = ["bead_metrics"]


@njit(cache=True, nogil=True)
def bead_metrics(x: npt.NDArray[np.float64], y: npt.NDArray[np.float64], x0: float,
                 y0: float, kind: npt.NDArray[np.uint8], extrude_bit: int,
                 cmd: npt.NDArray[np.float64], out: npt.NDArray[np.float64],
                 duration: npt.NDArray[np.float64], q_min: npt.NDArray[np.float64],
                 q_max: npt.NDArray[np.float64], peak: npt.NDArray[np.float64],
                 h: npt.NDArray[np.float64], max_force: npt.NDArray[np.float64], bead_c: float,
                 w_nom: npt.NDArray[np.float64], w_mean: npt.NDArray[np.float64],
                 w_min: npt.NDArray[np.float64], w_max: npt.NDArray[np.float64],
                 flow_err: npt.NDArray[np.float64], margin: npt.NDArray[np.float64],
                 narrow: npt.NDArray[np.bool_]) -> None:
    """One pass of the formulas of ``deposition_metrics`` (same operations, same order)."""
    px = x0
    py = y0
    for i in range(x.shape[0]):
        length = math.hypot(x[i] - px, y[i] - py)
        px = x[i]
        py = y[i]
        hh = h[i]
        bead = (kind[i] & extrude_bit) != 0 and length > 1e-9 and duration[i] > 0.0
        if bead:
            speed = length / duration[i]
            w_nom[i] = cmd[i] / length / hh + bead_c * hh
            wm = out[i] / length / hh + bead_c * hh
            w_mean[i] = wm
            w_min[i] = q_min[i] / (hh * speed) + bead_c * hh
            w_max[i] = q_max[i] / (hh * speed) + bead_c * hh
            flow_err[i] = out[i] / cmd[i] - 1.0 if cmd[i] > 0.0 else 0.0
            narrow[i] = wm < hh
        else:
            w_nom[i] = math.nan
            w_mean[i] = math.nan
            w_min[i] = math.nan
            w_max[i] = math.nan
            flow_err[i] = 0.0
            narrow[i] = False
        margin[i] = max_force[i] - peak[i]
