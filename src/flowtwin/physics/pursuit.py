"""The road a given nozzle path really lays: the strand end pursues the nozzle (beyond [004]).

[004] places the nozzle at ``P_N = P + L·t̂`` ahead of the road point ``P`` along the
road's tangent. Read the other way, the road end ``R`` always moves straight towards the
nozzle ``N`` and stays at the distance ``L`` (a tractrix, the pursuit curve of a trailer):

``dR/dt = ê·(ê·dN/dt)``,  ``ê = (N − R)/L``  ⇒  ``|N − R| = L`` for all t.

On a straight nozzle segment with direction ``û`` and left normal ``n̂``, write
``N − R = L·(cos φ·û + sin φ·n̂)``; then ``dφ/ds = −sin φ/L`` over the nozzle arc length
``s`` and

``tan(φ/2) = tan(φ_0/2)·exp(−s/L)``,  ``R(s) = N(s) − L·(cos φ·û + sin φ·n̂)``,

so a polyline nozzle path is followed exactly, segment by segment, with no integration
error. At a corner the road cuts inside: for a 90° corner the laid road passes the corner
vertex at ``0.663·L`` and strays up to ``0.482·L`` from the commanded path (docs/physics.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.errors import DataError
from flowtwin.physics._checks import as_float_array, require_positive

__all__ = ["LaidRoad", "laid_road", "polyline_distance_mm"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class LaidRoad:
    """Samples of the road laid behind a nozzle path.

    Attributes
    ----------
    road_xy_mm
        Road end positions, mm, shape (k, 2).
    nozzle_xy_mm
        Nozzle positions at the same instants, mm, shape (k, 2); ``|nozzle − road| = L``.
    nozzle_s_mm
        Nozzle arc length from the path start, mm, shape (k,).
    """

    road_xy_mm: FloatArray
    nozzle_xy_mm: FloatArray
    nozzle_s_mm: FloatArray


def laid_road(nozzle_xy_mm: npt.ArrayLike, *, lag_mm: float,
              initial_direction: npt.ArrayLike | None = None,
              samples_per_segment: int = 16) -> LaidRoad:
    """Road laid by a strand end that pursues the nozzle at distance ``L`` (closed form).

    Parameters
    ----------
    nozzle_xy_mm
        Nozzle path as a polyline in the layer plane, mm, shape (M, 2), M ≥ 2 (repeated
        points are skipped).
    lag_mm
        Strand lag ``L``, mm (> 0).
    initial_direction
        Direction from the road end to the nozzle at the start, shape (2,); default the
        direction of the first segment (the strand lies straight behind the nozzle).
    samples_per_segment
        Road samples per nozzle segment (≥ 1); the samples are exact, this only sets the
        resolution.

    Returns
    -------
    LaidRoad
        Road and nozzle samples, starting with the initial position.
    """
    path = as_float_array(nozzle_xy_mm)
    if path.ndim != 2 or path.shape[1] != 2 or path.shape[0] < 2:
        raise DataError("the nozzle path must have shape (M, 2) with M >= 2",
                        field="nozzle_xy_mm", value=path.shape, allowed="(M, 2), M >= 2")
    if not np.all(np.isfinite(path)):
        raise DataError("the nozzle path contains non-finite values", field="nozzle_xy_mm")
    lag = float(require_positive("lag_mm", lag_mm))
    if samples_per_segment < 1:
        raise DataError("samples_per_segment must be at least 1", field="samples_per_segment",
                        value=samples_per_segment, allowed=">= 1")
    steps = np.diff(path, axis=0)
    lengths = np.hypot(steps[:, 0], steps[:, 1])
    keep = lengths > 0.0
    if not np.any(keep):
        raise DataError("the nozzle path does not move", field="nozzle_xy_mm")
    starts, steps, lengths = path[:-1][keep], steps[keep], lengths[keep]
    directions = steps / lengths[:, None]
    if initial_direction is None:
        e = directions[0].copy()
    else:
        e = as_float_array(initial_direction).reshape(-1)
        norm = float(np.hypot(e[0], e[1])) if e.shape == (2,) else 0.0
        if not norm > 0.0:
            raise DataError("initial_direction must be a non-zero 2-vector",
                            field="initial_direction", value=e.tolist())
        e = e / norm

    # Pass 1 (scalar recurrence, cheap): the angle φ_0 of N − R against each segment at its
    # start. Within a segment tan(φ/2) decays by exp(−ℓ/L); at a vertex the absolute
    # direction ψ of N − R is kept and only the reference direction θ changes.
    theta = np.arctan2(directions[:, 1], directions[:, 0])
    decay = np.exp(-lengths / lag)
    phi0 = np.empty(theta.size)
    psi = math.atan2(float(e[1]), float(e[0]))
    for j, (th, dk) in enumerate(zip(theta.tolist(), decay.tolist(), strict=True)):
        p0 = math.remainder(psi - th, math.tau)
        phi0[j] = p0
        psi = th + 2.0 * math.atan(math.tan(p0 / 2.0) * dk)
    # Pass 2 (vectorised): the exact samples on every segment.
    frac = np.arange(1, samples_per_segment + 1) / samples_per_segment
    s = lengths[:, None] * frac[None, :]
    phi = 2.0 * np.arctan(np.tan(phi0[:, None] / 2.0) * np.exp(-s / lag))
    ux, uy = directions[:, 0:1], directions[:, 1:2]
    nozzle_x = starts[:, 0:1] + s * ux
    nozzle_y = starts[:, 1:2] + s * uy
    road_x = nozzle_x - lag * (np.cos(phi) * ux - np.sin(phi) * uy)
    road_y = nozzle_y - lag * (np.cos(phi) * uy + np.sin(phi) * ux)
    arc = np.concatenate([[0.0], np.cumsum(lengths)[:-1]])[:, None] + s
    first_road = starts[0] - lag * e
    return LaidRoad(np.vstack([first_road, np.column_stack([road_x.ravel(), road_y.ravel()])]),
                    np.vstack([starts[0], np.column_stack([nozzle_x.ravel(),
                                                           nozzle_y.ravel()])]),
                    np.concatenate([[0.0], arc.ravel()]))


def polyline_distance_mm(points_xy_mm: npt.ArrayLike,
                         polyline_xy_mm: npt.ArrayLike) -> FloatArray:
    """Distance of each point to a polyline (nearest point on any segment), mm.

    Use it to measure how far a laid road strays from the commanded path.

    Parameters
    ----------
    points_xy_mm
        Points, mm, shape (k, 2).
    polyline_xy_mm
        Polyline vertices, mm, shape (M, 2), M ≥ 2.

    Returns
    -------
    ndarray
        Distances, mm, shape (k,).
    """
    pts = as_float_array(points_xy_mm)
    poly = as_float_array(polyline_xy_mm)
    if pts.ndim != 2 or pts.shape[1] != 2 or poly.ndim != 2 or poly.shape[1] != 2 \
            or poly.shape[0] < 2:
        raise DataError("points must be (k, 2) and the polyline (M, 2) with M >= 2",
                        field="polyline_xy_mm", value=(pts.shape, poly.shape))
    a = poly[:-1]
    ab = poly[1:] - a
    ab2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300)
    ap = pts[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("kij,ij->ki", ap, ab) / ab2, 0.0, 1.0)
    nearest = a[None, :, :] + t[:, :, None] * ab[None, :, :]
    d = np.hypot(pts[:, None, 0] - nearest[:, :, 0], pts[:, None, 1] - nearest[:, :, 1])
    return np.asarray(d.min(axis=1))
