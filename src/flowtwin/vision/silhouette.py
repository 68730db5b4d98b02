"""The silhouette of a filament in one frame and over a clip, from the edge model.

:mod:`flowtwin.vision.edge_model` fits the blurred, shaded-cylinder edge to the
edge-aligned mean profiles of the filament's two edges. Here: the profiles of the two
edges with the background beyond another object's edge left out (:func:`edge_profiles`),
the checks that make a fit usable (:func:`fit_silhouette`; all frames of a clip at one
blur in one vectorised pass, :func:`fit_silhouettes`), and the clip's blur and limb
shapes fitted jointly over its frames (:func:`clip_model`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.vision.edge_model import (
    EdgeFit,
    EdgeProfile,
    aligned_profile,
    best_offsets,
    fit_edge_pair,
    fit_edges,
    mixed_sse,
    parabola_vertex,
    projected_columns,
    sse_grid,
    stack_profiles,
)

__all__ = ["IN_PX", "NO_FIT", "OUT_PX", "RIPPLE_FROM_PX", "RIPPLE_TO_RADIUS", "Silhouette",
           "clip_model", "edge_profiles", "fit_silhouette", "fit_silhouettes",
           "interior_ripple"]

F64 = npt.NDArray[np.float64]


#: Extent of the edge profiles: outside the filament (background) and inside, px.
OUT_PX = 6
IN_PX = 10
#: The interior span whose smoothness :func:`interior_ripple` measures: from this many px
#: inside the silhouette (clear of the blurred limb) to this fraction of the radius.
RIPPLE_FROM_PX = 2.5
RIPPLE_TO_RADIUS = 0.33
#: Outside the edge, samples beyond the point where the profile turns back from the
#: background by this fraction of the edge's contrast (another object: a gear rim) are
#: left out.
_TURN_BACK = 0.15


def _outside_weights(p: EdgeProfile, polarity: float) -> F64:
    """Weights that leave out the background beyond another object's edge.

    Going outward from the edge, the profile of a bright filament (``polarity`` +1)
    falls to the background and stays there; where it rises again by more than
    :data:`_TURN_BACK` of the edge's contrast, something else begins, and from there on
    the samples are not background.
    """
    t = p.inside * p.offset_px
    v = polarity * p.value_dn
    w = p.weights.copy()
    out = np.flatnonzero(t < 0)
    if out.size == 0:
        return w
    order = out[np.argsort(-t[out])]                     # from the edge outward
    inner = v[(t >= 2.0) & (t <= 6.0)]
    contrast = (float(np.median(inner)) if inner.size else float(v.max())) \
        - float(v[out].min())
    tol = max(3.0, _TURN_BACK * abs(contrast))
    low = np.minimum.accumulate(v[order])
    back = np.flatnonzero(v[order][1:] > low[:-1] + tol)
    if back.size:
        w[order[back[0] + 1:]] = 0.0
    return w


@dataclass(frozen=True, slots=True)
class Silhouette:
    """The two silhouette edges of a filament, fitted (see the module docstring).

    Attributes
    ----------
    left, right
        The fits; ``offset_px`` is the silhouette minus the reference line, px.
    profiles
        The edge-aligned profiles the fits were made on (kept to refit with another
        blur).
    polarity
        +1 for a filament brighter than its background, −1 for a darker one.
    ok
        Both fits converged with enough background beside each edge.
    reason
        Why not, if not ``ok``.
    """

    left: EdgeFit
    right: EdgeFit
    profiles: tuple[EdgeProfile, EdgeProfile]
    polarity: float
    ok: bool
    reason: str = ""


def edge_profiles(grey: npt.NDArray[np.float32], rows: tuple[npt.NDArray[np.intp],
                  npt.NDArray[np.intp]], lines: tuple[tuple[float, float],
                                                     tuple[float, float]],
                  polarity: float, radius_px: float = math.inf
                  ) -> tuple[EdgeProfile, EdgeProfile]:
    """The two edges' aligned profiles, with the background beyond other objects left
    out.

    Parameters
    ----------
    grey
        Image crop, shape ``(H, W)``.
    rows
        Rows on the left and on the right edge line.
    lines
        ``(slope, intercept)`` of the left and right edge lines, ``x = slope·y +
        intercept`` in crop coordinates.
    polarity
        +1 for a filament brighter than its background, −1 for a darker one.
    radius_px
        The filament's radius (half its width), px.

    Returns
    -------
    tuple of EdgeProfile
        Left and right profiles.
    """
    out = []
    for inside, r, (a, b) in ((1, rows[0], lines[0]), (-1, rows[1], lines[1])):
        p = aligned_profile(grey, r, a, b, inside, OUT_PX, IN_PX)
        if p.rows:
            p = EdgeProfile(p.offset_px, p.value_dn, inside, p.rows,
                            _outside_weights(p, polarity), radius_px)
        out.append(p)
    return out[0], out[1]


def fit_silhouette(profiles: tuple[EdgeProfile, EdgeProfile], polarity: float, *,
                   blur_px: float | None = None, mix: tuple[float, float] | None = None
                   ) -> Silhouette:
    """Fit both edges (:func:`fit_edge_pair`) and check that the fits are usable.

    Parameters
    ----------
    profiles
        Left and right profiles (:func:`edge_profiles`).
    polarity
        +1 for a filament brighter than its background, −1 for a darker one.
    blur_px
        Known blur σ (optics and pixel), px; ``None``: fitted.
    mix
        Known limb shapes of the two edges (:func:`fit_edge_pair`); ``None``: fitted.

    Returns
    -------
    Silhouette
        The fits, ``ok`` false with a reason when an edge has too little background
        beside it or its fit ran to the end of the search range.
    """
    bad = _unfit(profiles, polarity)
    if bad is not None:
        return bad
    fl, fr = fit_edge_pair(profiles[0], profiles[1], blur_px=blur_px, mix=mix)
    return _checked(profiles, polarity, fl, fr)


def fit_silhouettes(items: list[tuple[tuple[EdgeProfile, EdgeProfile], float]],
                    blur_px: float, mix: tuple[float, float] | None = None
                    ) -> list[Silhouette]:
    """:func:`fit_silhouette` of many frames at one known blur, in one pass
    (:func:`~flowtwin.vision.edge_model.fit_edges`).

    Parameters
    ----------
    items
        Each frame's left and right profiles and polarity.
    blur_px
        The blur σ (optics and pixel), px.
    mix
        Known limb shapes of the two edges; ``None``: fitted.

    Returns
    -------
    list of Silhouette
        One per item, as :func:`fit_silhouette` gives it.
    """
    out: list[Silhouette | None] = [_unfit(pr, pol) for pr, pol in items]
    todo = [i for i, sil in enumerate(out) if sil is None]
    edges = [p for i in todo for p in items[i][0]]
    mixes = None if mix is None else np.tile(np.array(mix, dtype=np.float64), len(todo))
    fits = fit_edges(edges, blur_px, mixes)
    for j, i in enumerate(todo):
        out[i] = _checked(items[i][0], items[i][1], fits[2 * j], fits[2 * j + 1])
    return [sil for sil in out if sil is not None]


def _unfit(profiles: tuple[EdgeProfile, EdgeProfile], polarity: float) -> Silhouette | None:
    """A refusal when an edge has too little background or filament beside it."""
    for name, p in zip(("left", "right"), profiles, strict=True):
        t = p.inside * p.offset_px
        if p.rows == 0 or int(np.sum((t < -1.0) & (p.weights > 0))) < 2:
            return Silhouette(NO_FIT, NO_FIT, profiles, polarity, False,
                              f"too little background beside the {name} edge in the ROI")
        if int(np.sum(t > 2.0)) < 4:
            return Silhouette(NO_FIT, NO_FIT, profiles, polarity, False,
                              f"too little filament inside the {name} edge in the ROI")
    return None


def _checked(profiles: tuple[EdgeProfile, EdgeProfile], polarity: float, fl: EdgeFit,
             fr: EdgeFit) -> Silhouette:
    """The silhouette of two fits, refused when a fit ran to the end of its range."""
    for name, f in (("left", fl), ("right", fr)):
        if not f.ok:
            return Silhouette(fl, fr, profiles, polarity, False,
                              f"the {name} edge does not fit a silhouette "
                              f"({f.offset_px:+.1f} px from its derivative extremum)")
    return Silhouette(fl, fr, profiles, polarity, True)


#: The fit of an edge that was not (or could not be) fitted.
NO_FIT = EdgeFit(math.nan, math.nan, math.nan, math.nan, math.nan, math.nan, False)


#: Limb shapes ``α`` tried for a clip, rad (``α`` and ``α + π`` are the same shape).
_MIXES = np.arange(-0.5 * math.pi, 0.5 * math.pi, 0.1)
#: Edge positions tried around each frame's own fit in the clip fit, px.
_NEAR = np.arange(-0.6, 0.6001, 0.1)


def _shape_residuals(t: F64, y: F64, w: F64, radius: F64, starts: F64, sigma: float
                     ) -> F64:
    """Residual of every profile at every limb shape of :data:`_MIXES`, each at its
    own best edge position near ``starts`` (:data:`_NEAR`), with blur ``sigma``: shape
    ``(P, len(_MIXES))``. The model's columns do not depend on the shape: they are
    computed once and combined for each."""
    taus = starts[:, None] + _NEAR[None, :]
    yp, cols = projected_columns(t, y, w, np.array([sigma]), taus, radius)
    mixes = np.broadcast_to(_MIXES, (t.shape[0], _MIXES.size))
    sse, _, _ = best_offsets(mixed_sse(yp, cols, mixes)[0], taus)
    return sse


def _parabola_min(values: F64, grid: F64) -> tuple[float, float]:
    """Grid point of the smallest value, refined by a parabola, and that value."""
    k = int(np.argmin(values))
    x = float(grid[k])
    if 0 < k < values.size - 1:
        x += parabola_vertex(float(values[k - 1]), float(values[k]), float(values[k + 1])) \
            * float(grid[1] - grid[0])
    return x, float(values[k])


def clip_model(pairs: list[tuple[EdgeProfile, EdgeProfile]],
               fits: list[tuple[EdgeFit, EdgeFit]], blur_guess_px: float
               ) -> tuple[float, tuple[float, float]]:
    """The blur and the two edges' limb shapes of a clip, fitted jointly over its frames.

    Each frame's edges keep their own positions (searched ±0.6 px around the frame's
    own fit), backgrounds and amplitudes; the blur σ and the shapes ``α`` (``(A, B) ∝
    (cos α, sin α)``) are the clip's: those that leave the least residual summed over
    the frames. One frame's texture and noise trade the blur, ``A`` and ``B`` against
    the edge position; summed over many frames they do not.

    Parameters
    ----------
    pairs
        Left and right profiles of each frame (:func:`edge_profiles`).
    fits
        Each frame's own fits of them (:func:`fit_edge_pair`).
    blur_guess_px
        A first blur (e.g. the median of single-frame fits): σ is searched from 0.68 to
        1.46 times it.

    Returns
    -------
    tuple
        ``(σ, (α_left, α_right))``, px and rad.
    """
    t, y, w, radius = stack_profiles([p for pair in pairs for p in pair])
    starts = np.array([f.offset_px * p.inside for pair, fp in zip(pairs, fits, strict=True)
                       for p, f in zip(pair, fp, strict=True)])
    # the blur: least residual summed over the frames, each frame's shapes free (bounded)
    outside = (t < -1.0) & (w > 0)
    a_min = np.array([-float(np.mean(y[i][outside[i]])) if outside[i].any() else -np.inf
                      for i in range(t.shape[0])])
    log_grid = math.log(blur_guess_px) + np.log(1.1) * np.arange(-4, 5)
    taus = starts[:, None] + _NEAR[None, :]
    sse = sse_grid(t, y, w, np.exp(log_grid), taus, a_min, radius)[0]     # (P, S, K)
    log_sigma, _ = _parabola_min(sse.min(axis=2).sum(axis=0), log_grid)
    sigma = math.exp(log_sigma)
    # the shapes at that blur
    res = _shape_residuals(t, y, w, radius, starts, sigma)
    al, _ = _parabola_min(res[0::2].sum(axis=0), _MIXES)
    ar, _ = _parabola_min(res[1::2].sum(axis=0), _MIXES)
    return sigma, (al, ar)


def interior_ripple(grey: npt.NDArray[np.float32], rows: npt.NDArray[np.intp],
                    lines: tuple[tuple[float, float], tuple[float, float]], sil: Silhouette,
                    radius_px: float) -> tuple[float, float]:
    """How far the filament's interior next to each edge departs from a smooth shaded
    cylinder, as a fraction of the edge's contrast.

    A front-lit cylinder's radiance inward of its limb is a smooth function of
    ``cos θ = √(2d/R − d²/R²)`` (:mod:`~flowtwin.vision.edge_model`), so over
    ``d`` from :data:`RIPPLE_FROM_PX` to :data:`RIPPLE_TO_RADIUS` · ``R`` the edge-aligned
    mean profile is a cubic in ``√d`` to well within the noise. Structure that survives
    the mean over the rows runs *along* the filament — stripes of its texture, which
    move along themselves and so never change in the image. Foreshortened towards the
    limb, such a stripe there is a ripple finer than the blur, which the edge model
    takes for limb shading and the edge's position; its amplitude further in, where it
    is resolved, is this measure: the rms departure of the profile from its best cubic
    in ``√d``, over the edge's contrast (:attr:`EdgeFit.contrast_dn`).

    Parameters
    ----------
    grey
        Image crop (e.g. a mean of several frames), shape ``(H, W)``.
    rows
        Rows on both edge lines.
    lines
        ``(slope, intercept)`` of the left and right edge lines in crop coordinates.
    sil
        The fitted silhouette (``ok``) of that crop.
    radius_px
        The filament's radius, px.

    Returns
    -------
    tuple of float
        Left and right ripple, fractions of the contrast (NaN where the span has fewer
        than 8 samples inside the crop).
    """
    out = []
    d_max = RIPPLE_TO_RADIUS * radius_px
    for (a, b), inside, fit in ((lines[0], 1, sil.left), (lines[1], -1, sil.right)):
        p = aligned_profile(grey, rows, a, b, inside, 0, math.ceil(d_max) + 2)
        d = p.inside * p.offset_px - fit.offset_px * inside
        m = (d >= RIPPLE_FROM_PX) & (d <= d_max)
        if int(m.sum()) < 8 or not math.isfinite(fit.contrast_dn):
            out.append(math.nan)
            continue
        s = np.sqrt(d[m])
        x = np.stack([np.ones_like(s), s, s * s, s * s * s], axis=1)
        coef, *_ = np.linalg.lstsq(x, p.value_dn[m], rcond=None)
        res = p.value_dn[m] - x @ coef
        out.append(float(np.sqrt(np.mean(res * res))) / max(abs(fit.contrast_dn), 1.0))
    return out[0], out[1]
