"""The melt zone's bulk temperature fraction compiled (numba), for the kernels and arrays.

:func:`flowtwin.physics.melt.theta_scalar` is the one source: compiled here as
:data:`theta_scalar` (called inside other kernels) and looped over an array by
:func:`theta_kernel`; plain Python callers (the flow limits) use it uncompiled and need no
numba.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin._jit import njit
from flowtwin.physics.melt import theta_scalar as _theta_python

__all__ = ["theta_kernel", "theta_scalar"]

#: ``θ_b(Fo)`` of one Fourier number, compiled (Carslaw & Jaeger §7.4, see the source).
theta_scalar = njit(cache=True, nogil=True)(_theta_python)


@njit(cache=True, nogil=True)
def theta_kernel(fo: npt.NDArray[np.float64], out: npt.NDArray[np.float64]) -> None:
    """``out[i] = θ_b(fo[i])`` for 1-D arrays of the same length."""
    for i in range(fo.shape[0]):
        out[i] = theta_scalar(fo[i])
