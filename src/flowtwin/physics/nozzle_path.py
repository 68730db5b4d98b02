"""Nozzle trajectory that lays a desired road, given the strand lag ``L`` [004].

The strand leaves the nozzle at height ``H`` and touches the road a distance ``L`` behind
it, along the road's tangent. So to lay the road point ``P_i`` with unit tangent ``t̂_i``
the nozzle must be at

``P_N = P_i + L·t̂_i + H·ẑ``  [004 Eqs. 9, 18–19]

(Eq. 19 writes ``t̂_i = (cos θ_i, sin θ_i)`` with ``cos θ = 1/sqrt(1 + K_i²)``,
``sin θ = K_i/sqrt(1 + K_i²)`` for a road ``y = F(x)`` of slope ``K_i`` [004 Eq. 17]).
Special cases: a straight road at angle ``θ`` gives the same line shifted by ``L``
[004 Eqs. 10–11]; a circle road of radius ``r`` needs a nozzle circle of radius
``sqrt(r² + L²)``, turned ahead by ``atan(L/r)`` [004 Eq. 15]. For a road through sampled
points [004] takes the slope from a clamped cubic spline [004 Eqs. 20–21]
(:mod:`flowtwin.physics.spline`); ``scipy.interpolate.CubicSpline`` with the same end slopes
is the maintained alternative (:class:`SplineMethod`). [004 Fig. 7] uses ``H = 0.012``,
``L = 0.06`` and the road ``y = x⁴ + x³ + x² + x``.

The inverse — the road a given nozzle path really lays — is in
:mod:`flowtwin.physics.pursuit`.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicSpline

from flowtwin.errors import DataError
from flowtwin.physics._checks import as_float_array, require_nonnegative, require_positive
from flowtwin.physics.spline import clamped_spline

__all__ = [
    "NozzleTrajectory",
    "SplineMethod",
    "circle_nozzle_phase_rad",
    "circle_nozzle_radius_mm",
    "nozzle_positions_mm",
    "nozzle_trajectory_for_graph_road",
    "unit_tangents_from_slope",
]

FloatArray = npt.NDArray[np.float64]


def nozzle_positions_mm(road_xy_mm: npt.ArrayLike, tangent_xy: npt.ArrayLike, *,
                        lag_mm: float, height_mm: float) -> FloatArray:
    """Nozzle positions ``P_N = P_i + L·t̂_i + H·ẑ`` [004 Eqs. 9, 19].

    Parameters
    ----------
    road_xy_mm
        Road points ``P_i`` in the layer plane, mm, shape (n, 2).
    tangent_xy
        Road tangents in the direction of travel, shape (n, 2); normalised here (must be
        non-zero).
    lag_mm
        Strand lag ``L``, mm (≥ 0).
    height_mm
        Nozzle height ``H`` above the layer below, mm (≥ 0).

    Returns
    -------
    ndarray
        Nozzle positions ``(x, y, z)``, mm, shape (n, 3).
    """
    road = as_float_array(road_xy_mm)
    tangent = as_float_array(tangent_xy)
    if road.ndim != 2 or road.shape[1] != 2 or tangent.shape != road.shape:
        raise DataError("road points and tangents must both have shape (n, 2)",
                        field="tangent_xy", value=(road.shape, tangent.shape),
                        allowed="(n, 2) and (n, 2)")
    norm = np.hypot(tangent[:, 0], tangent[:, 1])
    if np.any(~(norm > 0.0)):
        raise DataError("a road tangent is zero or not finite", field="tangent_xy",
                        value=int(np.argmin(norm)), allowed="non-zero tangents")
    lag = float(require_nonnegative("lag_mm", lag_mm))
    out = np.empty((road.shape[0], 3))
    out[:, :2] = road + lag * tangent / norm[:, None]
    out[:, 2] = float(require_nonnegative("height_mm", height_mm))
    return out


def unit_tangents_from_slope(slope: npt.ArrayLike) -> FloatArray:
    """Unit tangents ``(1, K)/sqrt(1 + K²)`` of a road ``y = F(x)`` with slope ``K`` [004 Eq. 19].

    Parameters
    ----------
    slope
        ``K_i = F'(x_i)`` [004 Eq. 17], shape (n,).

    Returns
    -------
    ndarray
        ``(cos θ_i, sin θ_i)``, shape (n, 2) — the road is travelled towards increasing x.
    """
    k = as_float_array(slope).reshape(-1)
    inv = 1.0 / np.sqrt(1.0 + k * k)
    return np.column_stack([inv, k * inv])


def circle_nozzle_radius_mm(road_radius_mm: npt.ArrayLike,
                            lag_mm: npt.ArrayLike) -> FloatArray:
    """Radius ``sqrt(r² + L²)`` of the nozzle circle that lays a circle road [004 Eq. 15].

    Parameters
    ----------
    road_radius_mm
        Road radius ``r``, mm (> 0), any shape.
    lag_mm
        Strand lag ``L``, mm (≥ 0).

    Returns
    -------
    ndarray
        Nozzle circle radius, mm, broadcast shape.
    """
    r = require_positive("road_radius_mm", road_radius_mm)
    lag = require_nonnegative("lag_mm", lag_mm)
    return np.sqrt(r * r + lag * lag)


def circle_nozzle_phase_rad(road_radius_mm: npt.ArrayLike,
                            lag_mm: npt.ArrayLike) -> FloatArray:
    """Angle ``γ = atan(L/r)`` by which the nozzle leads the road point on a circle [004 Eq. 15].

    The nozzle is at angle ``φ = α + γ`` when it lays the road point at angle ``α``
    (counter-clockwise travel).

    Parameters
    ----------
    road_radius_mm
        Road radius ``r``, mm (> 0).
    lag_mm
        Strand lag ``L``, mm (≥ 0).

    Returns
    -------
    ndarray
        ``γ``, radians, broadcast shape.
    """
    return np.arctan2(require_nonnegative("lag_mm", lag_mm),
                      require_positive("road_radius_mm", road_radius_mm))


class SplineMethod(Enum):
    """How the road slope between sample points is obtained."""

    #: The hand-written clamped spline of [004 Eqs. 20–21] (:mod:`flowtwin.physics.spline`).
    PAPER = "paper"
    #: ``scipy.interpolate.CubicSpline`` with ``bc_type=((1, S'(x_0)), (1, S'(x_m)))``.
    SCIPY = "scipy"


@dataclass(frozen=True)
class NozzleTrajectory:
    """A road and the nozzle path that lays it.

    Attributes
    ----------
    road_xy_mm
        Road points, mm, shape (n, 2).
    tangent_xy
        Unit road tangents, shape (n, 2).
    nozzle_xyz_mm
        Nozzle positions, mm, shape (n, 3).
    """

    road_xy_mm: FloatArray
    tangent_xy: FloatArray
    nozzle_xyz_mm: FloatArray


def nozzle_trajectory_for_graph_road(x_nodes: npt.ArrayLike, y_nodes: npt.ArrayLike, *,
                                     dy_start: float, dy_end: float, lag_mm: float,
                                     height_mm: float, x_samples: npt.ArrayLike,
                                     method: SplineMethod = SplineMethod.PAPER,
                                     ) -> NozzleTrajectory:
    """Nozzle trajectory for a road ``y = F(x)`` given at nodes [004 Eqs. 17–21].

    The road is interpolated by a clamped cubic spline with the road's end slopes, its slope
    ``K_i`` at each sample gives the tangent [004 Eqs. 17, 19], and the nozzle is placed at
    ``P_i + L·t̂_i + H·ẑ``.

    Parameters
    ----------
    x_nodes, y_nodes
        Road points, mm, strictly increasing ``x``, shape (m + 1,).
    dy_start, dy_end
        Road slopes ``F'(x_0)``, ``F'(x_m)``.
    lag_mm
        Strand lag ``L``, mm.
    height_mm
        Nozzle height ``H``, mm.
    x_samples
        Where to evaluate the road and the nozzle, mm, shape (n,).
    method
        :attr:`SplineMethod.PAPER` (default) or :attr:`SplineMethod.SCIPY`.

    Returns
    -------
    NozzleTrajectory
        Road samples, tangents and nozzle positions.
    """
    xs = as_float_array(x_samples).reshape(-1)
    if method is SplineMethod.PAPER:
        spline = clamped_spline(x_nodes, y_nodes, dy_start=dy_start, dy_end=dy_end)
        y, slope = spline(xs), spline.derivative(xs)
    else:
        cubic = CubicSpline(as_float_array(x_nodes), as_float_array(y_nodes),
                            bc_type=((1, float(dy_start)), (1, float(dy_end))))
        y, slope = cubic(xs), cubic(xs, 1)
    road = np.column_stack([xs, y])
    tangent = unit_tangents_from_slope(slope)
    return NozzleTrajectory(road, tangent,
                            nozzle_positions_mm(road, tangent, lag_mm=lag_mm,
                                                height_mm=height_mm))
