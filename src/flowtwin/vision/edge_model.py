"""Where a filament's silhouette edge really is: a blurred, shaded-cylinder edge model.

The derivative extremum of [003 §2.2] is the edge only for a blurred *step*. A filament
is a cylinder lit from the camera (ring light or coaxial lamp of a microscope). Seen
along the view direction (orthographic; the camera's working distance is many radii),
a surface point at ``x`` from the axis has its normal at ``u = (x − x_c)/R`` across, so
the cosine between normal and view (= light) direction is ``√(1 − u²)``. Any reflectance
that is a smooth function ``f(cos θ)`` of that cosine — Lambertian, a diffuse plus a
specular lobe, ambient light — expands about the limb (``cos θ = 0``) as
``f(0) + f′(0)·√(1 − u²) + O(1 − u²)``. With ``d`` the distance inward from the
silhouette (``1 − u² = 2d/R − d²/R²``) the radiance just inside the edge is

    L(d) = A + B·√d + C·d + O(d^1.5),         d ≥ 0,

a step ``A`` (the limb's own radiance over the background's), a square-root rise with an
infinite slope at the silhouette, and a smooth part. The silhouette — the true edge, the
tangent of the grazing rays — is at ``d = 0``. The camera sees ``L`` (and the background
``b₀ + b₁·x``) through the optics' point spread (Gaussian, σ) and its pixels (a 1-px box;
its variance 1/12 px² adds to σ² here, ``blur_px`` is the total). The square-root term's
infinite slope pulls the blurred profile's steepest point *inward*, by a fraction of σ
that grows with ``B/A``: on a filament whose limb is dark (``A`` small, the real clip of
[003]) the derivative extremum lies about one σ inside, 2–3 px in width.

Convolved with a Gaussian of standard deviation σ, with ``z = s/σ`` and ``s`` the signed
distance from the edge (positive inside):

* the background ``b₀ + b₁·s`` stays itself;
* the step ``H(s)`` becomes ``Φ(z)``;
* the ramp ``s·H(s)`` becomes ``σ·(z·Φ(z) + φ(z))``;
* ``√s·H(s)`` becomes ``√σ·S(z)`` with ``S(z) = ∫₀^∞ √t φ(z − t) dt
  = Γ(3/2)/√(2π) · e^(−z²/4) · D_(−3/2)(−z)`` (``D`` the parabolic cylinder function;
  ``S(z) → √z·(1 − 1/(8z²) − 15/(128z⁴))`` for large ``z``).

For given (edge position, σ) the profile is linear in (b₀, b₁, A, C, B): a linear least
squares. The edge position and σ are found by a search over both (variable projection),
σ shared by the two edges of the filament (one focal plane), and refined to 0.01 px.
The fit is made on the *edge-aligned mean profile*: the rows kept on the edge's straight
line, each shifted by its whole-pixel offset from the line, averaged column by column
(every row contributes to every column, so row-to-row changes of background and
brightness average out instead of mixing into the profile), at the mean sub-pixel
offset.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.special import gamma, ndtr, pbdv

__all__ = ["EdgeFit", "EdgeProfile", "aligned_profile", "best_offsets", "blurred_pow15_edge",
           "blurred_sqrt_edge", "fit_edge_pair", "fit_edges", "mixed_sse", "parabola_vertex",
           "projected_columns", "sse_grid", "stack_profiles"]

F64 = npt.NDArray[np.float64]

_INV_SQRT_2PI = 1.0 / math.sqrt(2.0 * math.pi)
_Z_LO, _Z_HI, _DZ = -9.0, 12.0, 0.005
_Z = np.arange(_Z_LO, _Z_HI + 0.5 * _DZ, _DZ)
_S_TABLE = (gamma(1.5) * _INV_SQRT_2PI * np.exp(-0.25 * _Z * _Z)
            * pbdv(-1.5, -_Z)[0]).astype(np.float64)
_S3_TABLE = (gamma(2.5) * _INV_SQRT_2PI * np.exp(-0.25 * _Z * _Z)
             * pbdv(-2.5, -_Z)[0]).astype(np.float64)

#: Search grid of the total blur (σ of the Gaussian including the pixel), px.
_SIGMAS: F64 = 0.35 * 1.22 ** np.arange(12.0)          # 0.35 … 3.1 px
#: Search grid of the edge offset from the reference line, px, and the fine steps
#: around its best point.
_OFFSETS = np.arange(-3.0, 3.0001, 0.25)
_FINE = np.arange(-0.25, 0.2501, 0.05)
#: An edge found this close to the end of the search range did not converge.
_EDGE_LIMIT = 2.7


def _table(z: F64, table: F64) -> F64:
    u = (np.clip(z, _Z_LO, _Z_HI) - _Z_LO) * (1.0 / _DZ)
    k = np.minimum(u.astype(np.intp), _Z.size - 2)
    f = u - k
    return np.asarray(table[k] * (1.0 - f) + table[k + 1] * f, dtype=np.float64)


def blurred_pow15_edge(z: F64) -> F64:
    """``S₃(z) = ∫₀^∞ t^1.5 φ(z − t) dt``: the next term of a cylinder's shading seen
    through a unit Gaussian, ``Γ(5/2)/√(2π) · e^(−z²/4) · D_(−5/2)(−z)`` (tabulated;
    ``z^1.5·(1 + 3/(8z²) + 0.0703/z⁴)`` beyond ``z = 12``).

    Parameters
    ----------
    z
        Signed distance from the edge over σ (positive inside), any shape.

    Returns
    -------
    numpy.ndarray
        ``S₃(z)``, same shape.
    """
    z = np.asarray(z, dtype=np.float64)
    out = _table(z, _S3_TABLE)
    big = z > _Z_HI
    if np.any(big):
        zb = z[big]
        out[big] = zb ** 1.5 * (1.0 + 3.0 / (8.0 * zb * zb) + 0.0703125 / zb ** 4)
    return out


def blurred_sqrt_edge(z: F64) -> F64:
    """``S(z) = ∫₀^∞ √t φ(z − t) dt``: a unit square-root rise seen through a unit Gaussian.

    Parameters
    ----------
    z
        Signed distance from the edge over σ (positive inside), any shape.

    Returns
    -------
    numpy.ndarray
        ``S(z)``, same shape (closed form through the parabolic cylinder function
        ``D_(−3/2)``, tabulated; the asymptotic series beyond ``z = 12``).
    """
    z = np.asarray(z, dtype=np.float64)
    out = _table(z, _S_TABLE)
    big = z > _Z_HI
    if np.any(big):
        zb = z[big]
        out[big] = np.sqrt(zb) * (1.0 - 1.0 / (8.0 * zb * zb) - 15.0 / (128.0 * zb ** 4))
    return out


def _edge_columns(s: F64, sigma: F64, radius: F64) -> F64:
    """The model's edge columns for signed distances ``s`` (inside > 0), blurs ``sigma``
    and cylinder radii ``radius`` (broadcast together), shape ``broadcast + (3,)``:

    * the step ``Φ``;
    * ``cos²θ·R/2 = d − d²/(2R)`` blurred: ``σ(zΦ + φ) − σ²((z² + 1)Φ + zφ)/(2R)``;
    * ``cos θ·√(R/2) = √d·√(1 − d/(2R)) ≈ √d − d^1.5/(4R)`` blurred:
      ``√σ·S(z) − σ^1.5·S₃(z)/(4R)``.

    The background columns ``(1, s)`` span the same space as ``(1, x)`` for every edge
    position and are projected out once (:func:`sse_grid`)."""
    s, sigma, radius = np.broadcast_arrays(s, sigma, radius)
    z = s / sigma
    cdf = ndtr(z)
    pdf = _INV_SQRT_2PI * np.exp(-0.5 * z * z)
    inv_r = 1.0 / radius
    ramp = sigma * (z * cdf + pdf) - 0.5 * inv_r * sigma * sigma * ((z * z + 1.0) * cdf
                                                                     + z * pdf)
    rise = np.sqrt(sigma) * blurred_sqrt_edge(z) - 0.25 * inv_r * sigma ** 1.5 \
        * blurred_pow15_edge(z)
    return np.stack([cdf, ramp, rise], axis=-1)


@dataclass(frozen=True, slots=True)
class EdgeProfile:
    """An edge-aligned mean profile across one filament edge.

    Attributes
    ----------
    offset_px
        Position of each sample relative to the edge's reference line, px, shape ``(n,)``
        (increasing).
    value_dn
        Mean grey level of the rows at each position, DN, shape ``(n,)``.
    inside
        ``+1`` when the filament lies at larger offsets (its left edge), ``−1`` otherwise.
    rows
        Number of rows averaged.
    weight
        1 for samples the fit uses, 0 for samples left out (e.g. beyond another
        object's edge outside the filament); ``None``: all used.
    radius_px
        The filament's radius, px (half its width; a few per cent off do not matter),
        for the shading's curvature terms; infinite: leading terms only.
    """

    offset_px: F64
    value_dn: F64
    inside: int
    rows: int
    weight: F64 | None = None
    radius_px: float = math.inf

    @property
    def weights(self) -> F64:
        """Sample weights (1 used, 0 left out), shape ``(n,)``."""
        return np.ones(self.offset_px.size) if self.weight is None else self.weight


def aligned_profile(grey: npt.NDArray[np.float32], rows: npt.NDArray[np.intp], slope: float,
                    intercept: float, inside: int, out_px: int, in_px: int) -> EdgeProfile:
    """Mean profile of ``rows`` across the edge line ``x = slope·y + intercept``.

    Each row is shifted by its whole-pixel offset from the line, so that every row
    contributes to every sample; the samples lie at the rows' mean sub-pixel offset.

    Parameters
    ----------
    grey
        Image crop, shape ``(H, W)``.
    rows
        Rows to average (on the edge line), indices into ``grey``.
    slope, intercept
        The edge line in crop coordinates, ``x = slope·y + intercept``.
    inside
        ``+1``: the filament is on the right of this edge; ``−1``: on its left.
    out_px, in_px
        Extent of the profile outside and inside the filament, whole px (less where the
        crop ends sooner).

    Returns
    -------
    EdgeProfile
        The profile (empty when the edge leaves the crop).
    """
    line = slope * rows.astype(np.float64) + intercept
    k = np.rint(line).astype(np.intp)
    w = grey.shape[1]
    if k.size == 0:
        return EdgeProfile(np.zeros(0), np.zeros(0), inside, 0)
    # the extent every row has inside the crop (a ROI may end a few px outside the edge)
    room_left, room_right = int(k.min()), int(w - 1 - k.max())
    if inside > 0:
        js = np.arange(-min(out_px, room_left), min(in_px, room_right) + 1)
    else:
        js = np.arange(-min(in_px, room_left), min(out_px, room_right) + 1)
    if js.size < 2:
        return EdgeProfile(np.zeros(0), np.zeros(0), inside, 0)
    vals = grey[rows[:, None], k[:, None] + js[None, :]].astype(np.float64).mean(axis=0)
    return EdgeProfile(js.astype(np.float64) + float(np.mean(k - line)), vals, inside,
                       int(rows.size))


@dataclass(frozen=True, slots=True)
class EdgeFit:
    """The fitted edge model of one edge.

    Attributes
    ----------
    offset_px
        Silhouette position relative to the profile's reference line, px (NaN when the
        fit failed).
    blur_px
        Gaussian σ of the fit (optics and pixel together), px.
    step_dn
        Radiance step at the silhouette, ``A``, DN (signed: positive for a filament
        brighter than the background).
    rise_dn
        Square-root rise over the first pixel inside, ``B``, DN.
    rms_dn
        Residual root-mean-square of the fit, DN.
    contrast_dn
        Model's filament-minus-background contrast 3σ inside the edge, DN.
    ok
        The fit converged inside the search range.
    mix_rad
        The limb's shape, ``atan2(B, A)``: 0 a pure step, π/2 a pure square-root rise.
    """

    offset_px: float
    blur_px: float
    step_dn: float
    rise_dn: float
    rms_dn: float
    contrast_dn: float
    ok: bool
    mix_rad: float = math.nan


def projected_columns(t: F64, y: F64, w: F64, sigmas: F64, taus: F64,
                      radius: F64 | None = None) -> tuple[F64, F64]:
    """The profiles and the model's edge columns with the background line ``(1, t)``
    projected out (weighted least squares), for :func:`sse_grid`.

    Parameters
    ----------
    t, y, w, sigmas, taus, radius
        As for :func:`sse_grid`.

    Returns
    -------
    tuple of numpy.ndarray
        Projected values, shape ``(P, n)``, and columns, shape ``(P, S, K, n, 3)``.
    """
    sw = w.sum(axis=1)
    tc = t - ((w * t).sum(axis=1) / sw)[:, None]
    wtc = w * tc
    ntt = (wtc * tc).sum(axis=1)

    def project(v: F64, shape: tuple[int, ...]) -> F64:
        # v: (P, ..., n, a) -> weighted residual from its line in t
        ww = w.reshape(shape)
        mean = (ww * v).sum(axis=-2, keepdims=True) / sw.reshape(shape[:1] + (1,) * (
            len(shape) - 1))
        slope = (wtc.reshape(shape) * v).sum(axis=-2, keepdims=True) / ntt.reshape(
            shape[:1] + (1,) * (len(shape) - 1))
        return ww * (v - mean - tc.reshape(shape) * slope)

    p, n = t.shape
    yp = project(y[:, :, None], (p, n, 1))[:, :, 0]                   # (P, n)
    s = t[:, None, None, :] - taus[:, None, :, None]                   # (P, 1, K, n)
    r = np.full(p, np.inf) if radius is None else radius
    cols = project(_edge_columns(s, sigmas[None, :, None, None], r[:, None, None, None]),
                   (p, 1, 1, n, 1))
    return yp, cols


def mixed_sse(yp: F64, cols: F64, mix: F64) -> tuple[F64, F64]:
    """Residual sum of squares and coefficients ``(A, C, B)`` with the limb's shape fixed,
    ``(A, B) ∝ (cos α, sin α)``, from :func:`projected_columns`.

    Parameters
    ----------
    yp, cols
        Projected values ``(P, n)`` and columns ``(P, S, K, n, 3)``.
    mix
        Angles ``α``, shape ``(P,)`` or ``(P, S)`` (one per profile and σ, or per profile
        and shape when ``S`` is 1 and the columns are broadcast).

    Returns
    -------
    tuple of numpy.ndarray
        SSE, shape ``(P, S', K)``, and coefficients, shape ``(P, S', K, 3)``.
    """
    m = mix.reshape(mix.shape[0], -1)[:, :, None, None]               # (P, S', 1, 1)
    ca, sa = np.cos(m), np.sin(m)
    two = np.stack([ca * cols[..., 0] + sa * cols[..., 2],
                    np.broadcast_to(cols[..., 1], np.broadcast_shapes(
                        cols.shape[:-1], ca.shape))], axis=-1)
    tt = np.swapaxes(two, -1, -2)
    g2 = tt @ two
    h2 = (tt @ yp[:, None, None, :, None])[..., 0]
    g2 = g2 + 1e-9 * np.trace(g2, axis1=-2, axis2=-1)[..., None, None] * np.eye(2)
    c2 = np.linalg.solve(g2, h2[..., None])[..., 0]
    sse2 = (yp * yp).sum(axis=1)[:, None, None] - np.sum(h2 * c2, axis=-1)
    coef3 = np.stack([c2[..., 0] * ca[..., 0], c2[..., 1], c2[..., 0] * sa[..., 0]],
                     axis=-1)
    return np.maximum(sse2, 0.0), coef3


def sse_grid(t: F64, y: F64, w: F64, sigmas: F64, taus: F64, a_min: F64 | None = None,
             radius: F64 | None = None, mix: F64 | None = None) -> tuple[F64, F64]:
    """Residual sum of squares and edge coefficients ``(A, C, B)`` on a (σ, edge) grid.

    Variable projection: the background line ``(1, t)`` is eliminated once by weighted
    least squares, leaving a 3×3 system per grid point. With bounds, ``A ≥ a_min`` (the
    limb's radiance, background plus step, is not negative) and ``B ≥ 0`` (lit from the
    camera, the shading brightens inward); the constrained optimum is the best of the
    unconstrained one and those with ``A = a_min``, ``B = 0`` or both, among those that
    satisfy the bounds (a convex problem: its optimum lies on one of these faces).

    Parameters
    ----------
    t, y, w
        Positions (inside the filament at larger ``t``), values and weights of ``P``
        profiles, shape ``(P, n)``.
    sigmas
        Blurs, shape ``(S,)``.
    taus
        Edge positions per profile, shape ``(P, K)``.
    a_min
        Lower bound of each profile's step, shape ``(P,)``; ``None``: no bounds.
    radius
        Cylinder radius of each profile, px, shape ``(P,)``; ``None``: infinite (the
        leading terms only).
    mix
        A fixed shape of each profile's limb, ``(A, B) ∝ (cos α, sin α)``, angles ``α``
        shape ``(P,)`` (the bounds are then not applied); ``None``: ``A`` and ``B`` free.

    Returns
    -------
    tuple of numpy.ndarray
        SSE, shape ``(P, S, K)``, and coefficients, shape ``(P, S, K, 3)``.
    """
    yp, cols = projected_columns(t, y, w, sigmas, taus, radius)
    if mix is not None:
        return mixed_sse(yp, cols, mix)
    ct = np.swapaxes(cols, -1, -2)                                     # (P, S, K, 3, n)
    g = ct @ cols
    h = (ct @ yp[:, None, None, :, None])[..., 0]
    g = g + 1e-9 * np.trace(g, axis1=-2, axis2=-1)[..., None, None] * np.eye(3)
    yy = (yp * yp).sum(axis=1)[:, None, None]
    coef = np.linalg.solve(g, h[..., None])[..., 0]
    sse = yy - np.sum(h * coef, axis=-1)
    if a_min is None:
        return np.maximum(sse, 0.0), coef
    lo = a_min[:, None, None]

    def feasible(c: F64) -> npt.NDArray[np.bool_]:
        return (c[..., 0] >= lo - 1e-9) & (c[..., 2] >= -1e-9)

    sse = np.where(feasible(coef), sse, np.inf)
    lo_b = np.broadcast_to(lo, sse.shape)
    for fix_a, keep in ((False, (0, 1)), (True, (1, 2)), (True, (1,))):
        idx = np.array(keep)
        a = lo_b if fix_a else np.zeros_like(lo_b)
        hh = h[..., idx] - a[..., None] * g[..., idx, 0]
        sub = np.linalg.solve(g[..., idx[:, None], idx[None, :]], hh[..., None])[..., 0]
        c = np.zeros_like(coef)
        c[..., idx] = sub
        if fix_a:
            c[..., 0] = a
        base = yy - 2.0 * a * h[..., 0] + a * a * g[..., 0, 0] if fix_a else yy
        s_sub = np.where(feasible(c), base - np.sum(hh * sub, axis=-1), np.inf)
        better = s_sub < sse
        sse = np.where(better, s_sub, sse)
        coef = np.where(better[..., None], c, coef)
    return np.maximum(sse, 0.0), coef


def parabola_vertex(a: float, b: float, c: float) -> float:
    """Offset of the vertex of the parabola through ``(−1, a), (0, b), (1, c)`` from the
    middle point, in grid steps (0 when the points do not curve upward)."""
    den = a - 2.0 * b + c
    return 0.5 * (a - c) / den if den > 0 else 0.0


def best_offsets(sse: F64, taus: F64) -> tuple[F64, F64, F64]:
    """Per profile and σ: the smallest SSE over the edge positions, its position
    (parabola between grid points) and its grid index; shapes ``(P, S)``."""
    k = np.argmin(sse, axis=-1)
    n = taus.shape[-1]
    best = np.take_along_axis(sse, k[..., None], axis=-1)[..., 0]
    a = np.take_along_axis(sse, np.clip(k - 1, 0, n - 1)[..., None], axis=-1)[..., 0]
    c = np.take_along_axis(sse, np.clip(k + 1, 0, n - 1)[..., None], axis=-1)[..., 0]
    den = a - 2.0 * best + c
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.where((den > 0) & (k > 0) & (k < n - 1), 0.5 * (a - c) / den, 0.0)
    step = taus[:, 1] - taus[:, 0]
    pos = np.take_along_axis(taus[:, None, :], k[..., None], axis=-1)[..., 0] \
        + np.clip(frac, -0.5, 0.5) * step[:, None]
    return best, pos, k


def fit_edge_pair(left: EdgeProfile, right: EdgeProfile, *, blur_px: float | None = None,
                  bounded: bool = True, mix: tuple[float, float] | None = None
                  ) -> tuple[EdgeFit, EdgeFit]:
    """Fit the shaded-cylinder edge model to the two edges of one filament.

    Parameters
    ----------
    left, right
        Edge-aligned profiles (:func:`aligned_profile`) of the two edges.
    blur_px
        The blur (σ, optics and pixel), px, if known; ``None``: fitted, shared by both
        edges.
    bounded
        The limb's radiance (background plus step) must not be negative and the shading
        must brighten inward (:func:`sse_grid`); the background level is the mean of the
        profile more than 1 px outside the edge line.
    mix
        Fixed limb shapes of the two edges, ``α`` with ``(A, B) ∝ (cos α, sin α)``
        (:attr:`EdgeFit.mix_rad` of earlier fits); ``None``: free.

    Returns
    -------
    tuple of EdgeFit
        The two edges' fits; ``offset_px`` is relative to each profile's reference line.
    """
    profiles = (left, right)
    if blur_px is not None:
        fl, fr = fit_edges(profiles, float(blur_px), None if mix is None else np.array(mix),
                           bounded=bounded)
        return fl, fr
    t, y, w, radius = stack_profiles(profiles)
    mixes = None if mix is None else np.array(mix, dtype=np.float64)
    a_min = _step_floor(t, y, w) if bounded and mix is None else None
    # coarse: offsets every 0.25 px, every σ of the grid; σ shared by the two edges
    taus: F64 = np.broadcast_to(_OFFSETS, (2, _OFFSETS.size))
    sse, pos, _ = best_offsets(sse_grid(t, y, w, _SIGMAS, taus, a_min, radius, mixes)[0], taus)
    i = int(np.argmin(sse.sum(axis=0)))
    start = pos[:, i]
    # fine: σ between the neighbours of the best, edges ±0.25 px in 0.05 px
    fine_s = np.geomspace(_SIGMAS[max(i - 1, 0)], _SIGMAS[min(i + 1, len(_SIGMAS) - 1)], 7)
    taus = start[:, None] + _FINE[None, :]
    sse, pos, _ = best_offsets(sse_grid(t, y, w, fine_s, taus, a_min, radius, mixes)[0], taus)
    total = sse.sum(axis=0)
    k = int(np.argmin(total))
    sigma = float(fine_s[k])
    if 0 < k < len(fine_s) - 1:
        frac = parabola_vertex(float(total[k - 1]), float(total[k]), float(total[k + 1]))
        sigma *= float(fine_s[1] / fine_s[0]) ** frac
    fl, fr = _final_fits(profiles, (t, y, w, radius), sigma, pos[:, k], a_min, mixes)
    return fl, fr


def stack_profiles(profiles: Sequence[EdgeProfile]) -> tuple[F64, F64, F64, F64]:
    """Positions (inside the filament at larger ``t``), values, weights and radii of
    profiles, padded to one length (padding has weight 0), shapes ``(P, n)`` and
    ``(P,)``."""
    n = max(p.offset_px.size for p in profiles)
    t = np.zeros((len(profiles), n))
    y = np.zeros((len(profiles), n))
    w = np.zeros((len(profiles), n))
    for i, p in enumerate(profiles):
        m = p.offset_px.size
        t[i, :m] = p.inside * p.offset_px
        t[i, m:] = t[i, m - 1] if m else 0.0
        y[i, :m] = p.value_dn
        w[i, :m] = p.weights
    return t, y, w, np.array([p.radius_px for p in profiles], dtype=np.float64)


def _step_floor(t: F64, y: F64, w: F64) -> F64:
    """Lower bound of each profile's step: minus its background level, the mean more
    than 1 px outside the edge line (the limb's radiance is not negative)."""
    outside = (t < -1.0) & (w > 0)
    return np.array([-float(np.mean(y[i][outside[i]])) if outside[i].any() else -np.inf
                     for i in range(t.shape[0])])


def fit_edges(profiles: Sequence[EdgeProfile], blur_px: float, mix: F64 | None = None, *,
              bounded: bool = True) -> list[EdgeFit]:
    """Fit the edge model to many edges at a known blur, each edge on its own (edges
    every 0.25 px over ±3 px, then ±0.25 px in 0.05 px around the best), in one pass.

    Parameters
    ----------
    profiles
        Edge-aligned profiles (:func:`aligned_profile`), any number.
    blur_px
        The blur (σ, optics and pixel), px.
    mix
        Fixed limb shape of each profile, ``α``, shape ``(P,)``; ``None``: free.
    bounded
        As for :func:`fit_edge_pair` (applies when ``mix`` is ``None``).

    Returns
    -------
    list of EdgeFit
        One fit per profile, as :func:`fit_edge_pair` gives them at that blur.
    """
    if not profiles:
        return []
    data = stack_profiles(profiles)
    t, y, w, radius = data
    mixes = None if mix is None else np.asarray(mix, dtype=np.float64)
    a_min = _step_floor(t, y, w) if bounded and mix is None else None
    sigmas = np.array([float(blur_px)])
    taus: F64 = np.broadcast_to(_OFFSETS, (len(profiles), _OFFSETS.size))
    _, pos, _ = best_offsets(sse_grid(t, y, w, sigmas, taus, a_min, radius, mixes)[0], taus)
    return _final_fits(profiles, data, float(blur_px), pos[:, 0], a_min, mixes)


def _final_fits(profiles: Sequence[EdgeProfile], data: tuple[F64, F64, F64, F64],
                sigma: float, start: F64, a_min: F64 | None, mixes: F64 | None
                ) -> list[EdgeFit]:
    """Each edge ±0.25 px in 0.05 px around ``start`` at blur ``sigma``, and its fit."""
    t, y, w, radius = data
    taus = start[:, None] + _FINE[None, :]
    sse_g, coef_g = sse_grid(t, y, w, np.array([sigma]), taus, a_min, radius, mixes)
    _, pos, kk = best_offsets(sse_g, taus)
    out = []
    for j, p in enumerate(profiles):
        k = int(kk[j, 0])
        out.append(_fit_result(p, float(pos[j, 0]), sigma, float(sse_g[j, 0, k]),
                               coef_g[j, 0, k], int(w[j].sum())))
    return out


def _fit_result(p: EdgeProfile, tau: float, sigma: float, sse: float, coef: F64,
                n_used: int) -> EdgeFit:
    """The fit of one edge (``tau`` along the inside direction) and its checks."""
    a, c, b = (float(v) for v in coef)
    rms = math.sqrt(sse / max(n_used - 7, 1))
    mix = math.atan2(b, a)
    # model contrast 3σ inside: step + ramp + rise, the background's slope removed
    d = 3.0 * sigma
    contrast = a + c * d + b * math.sqrt(d)
    ok = abs(tau) < _EDGE_LIMIT and math.isfinite(a + b + c)
    return EdgeFit(p.inside * tau, sigma, a, b, rms, contrast, ok, mix)
