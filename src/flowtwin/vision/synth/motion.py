"""Known motion for the synthetic camera: gear and filament speeds and width over time.

The camera can be driven by any time series ``(t, gear speed, filament speed, width)`` —
for example the output of the twin's drive simulation — so accuracy is measured against
a ground truth that the renderer integrates exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.errors import VisionError

__all__ = ["MotionSeries", "integrate_piecewise_linear"]

FloatArray = npt.NDArray[np.float64]


def integrate_piecewise_linear(t_knots: FloatArray, v_knots: FloatArray,
                               t_query: npt.ArrayLike) -> FloatArray:
    """Exact integral of a piecewise-linear signal from ``t_knots[0]`` to each query time.

    Between knots ``v`` is linear, so on ``[t_k, t_k+1)`` the integral is
    ``C_k + v_k·τ + ½·(v_k+1 − v_k)/(t_k+1 − t_k)·τ²`` with ``τ = t − t_k`` and ``C_k``
    the trapezoid sum up to ``t_k``. Outside the knots the end values are held.

    Parameters
    ----------
    t_knots
        Strictly increasing knot times, shape ``(K,)``, s.
    v_knots
        Signal at the knots, shape ``(K,)`` (e.g. mm/s).
    t_query
        Times to evaluate, any shape, s.

    Returns
    -------
    numpy.ndarray
        Integral at ``t_query`` (e.g. mm), same shape as ``t_query``.
    """
    t = np.asarray(t_knots, dtype=np.float64)
    v = np.asarray(v_knots, dtype=np.float64)
    q = np.asarray(t_query, dtype=np.float64)
    if t.size == 1:
        return v[0] * (q - t[0])
    seg = np.diff(t)
    cum = np.concatenate(([0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * seg)))
    k = np.clip(np.searchsorted(t, q, side="right") - 1, 0, t.size - 2)
    tau = q - t[k]
    slope = (v[k + 1] - v[k]) / seg[k]
    inside = cum[k] + v[k] * tau + 0.5 * slope * tau * tau
    before = v[0] * (q - t[0])
    after = cum[-1] + v[-1] * (q - t[-1])
    return np.where(q < t[0], before, np.where(q > t[-1], after, inside))


@dataclass(frozen=True, slots=True)
class MotionSeries:
    """Gear surface speed, filament speed and filament width over time (ground truth).

    Speeds are linear between samples; ``width_mm[k]`` is the width of the filament
    that passes the centre row of the ``before`` ROI at ``t_s[k]``.

    Attributes
    ----------
    t_s
        Strictly increasing times, shape ``(K,)``, s.
    gear_speed_mm_s
        Gear surface speed at the drive radius ``ω·R`` [003 Eq. 3], shape ``(K,)``, mm/s.
    filament_speed_mm_s
        Filament transport speed, shape ``(K,)``, mm/s.
    width_mm
        Filament width, shape ``(K,)``, mm (> 0).
    """

    t_s: FloatArray
    gear_speed_mm_s: FloatArray
    filament_speed_mm_s: FloatArray
    width_mm: FloatArray

    def __post_init__(self) -> None:
        arrays = {}
        for name in ("t_s", "gear_speed_mm_s", "filament_speed_mm_s", "width_mm"):
            arr = np.asarray(getattr(self, name), dtype=np.float64)
            if arr.ndim != 1 or arr.size < 1:
                raise VisionError("motion series must be 1-D and non-empty", field=name,
                                  value=arr.shape, allowed="shape (K,), K >= 1")
            if not np.all(np.isfinite(arr)):
                raise VisionError("motion series contains NaN or infinity", field=name,
                                  allowed="finite numbers")
            arrays[name] = arr
            object.__setattr__(self, name, arr)
        sizes = {a.size for a in arrays.values()}
        if len(sizes) != 1:
            raise VisionError("motion series columns differ in length",
                              value={k: a.size for k, a in arrays.items()},
                              allowed="equal lengths")
        if np.any(np.diff(arrays["t_s"]) <= 0):
            raise VisionError("motion series times must increase strictly", field="t_s",
                              allowed="t_s[k+1] > t_s[k]")
        if np.any(arrays["width_mm"] <= 0):
            raise VisionError("filament width must be positive", field="width_mm",
                              value=float(arrays["width_mm"].min()), allowed="> 0 mm")

    @classmethod
    def constant(cls, *, duration_s: float, gear_speed_mm_s: float, slip: float = 0.0,
                 width_mm: float = 1.75) -> MotionSeries:
        """Steady feed: constant gear speed and slip (fraction) [000 Eq. 1]."""
        t = np.array([0.0, float(duration_s)])
        g = np.full(2, float(gear_speed_mm_s))
        return cls(t, g, g * (1.0 - slip), np.full(2, float(width_mm)))

    @classmethod
    def from_slip(cls, t_s: npt.ArrayLike, gear_speed_mm_s: npt.ArrayLike,
                  slip: npt.ArrayLike, width_mm: npt.ArrayLike) -> MotionSeries:
        """Build from gear speed and slip fraction: ``v_fil = ω·R·(1 − s)`` [000 Eq. 1]."""
        g = np.asarray(gear_speed_mm_s, dtype=np.float64)
        return cls(np.asarray(t_s, dtype=np.float64), g,
                   g * (1.0 - np.asarray(slip, dtype=np.float64)),
                   np.asarray(width_mm, dtype=np.float64))

    def gear_distance_mm(self, t_s: npt.ArrayLike) -> FloatArray:
        """Arc length the gear surface has travelled since ``t_s[0]``, mm."""
        return integrate_piecewise_linear(self.t_s, self.gear_speed_mm_s, t_s)

    def filament_distance_mm(self, t_s: npt.ArrayLike) -> FloatArray:
        """Length of filament fed since ``t_s[0]``, mm."""
        return integrate_piecewise_linear(self.t_s, self.filament_speed_mm_s, t_s)

    def width_at(self, t_s: npt.ArrayLike) -> FloatArray:
        """Width passing the reference row at ``t_s`` (linear between samples), mm."""
        return np.interp(np.asarray(t_s, dtype=np.float64), self.t_s, self.width_mm)
