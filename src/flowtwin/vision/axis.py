"""The gear axis from the tracked motion: is the motion in the gear ROI a rotation, and
about which point?

Rotation mode (gear speed ``ω·R`` [003 Eq. 3]) needs the gear axis in the image. Here it
is estimated from the features tracked in the gear ROI over the first frames of a
recording, so a user does not have to find it by hand:

1. **Tracks.** Shi–Tomasi features of the gear ROI (with the same noise gate as the
   tracker) are followed frame to frame with pyramidal Lucas–Kanade, forward and
   backward, in the ROI padded by the allowed motion, always from their keyframe (so
   errors do not chain); a new keyframe is taken every :data:`KEY_FRAMES` frames or
   :data:`_KEY_CHORD_PX` px of motion. In every frame each live track contributes a
   correspondence ``(p_key, p_now)``; correspondences of the same ``(keyframe, frame)``
   pair form a *group*, which shares one rotation angle.
2. **Rigid rotation about one axis.** ``p_now = c + R(θ_g)(p_key − c)`` for every group
   ``g``, with one centre ``c`` for all. Start: each chord ``d = p_now − p_key`` is
   perpendicular to the line from its midpoint ``m`` to the centre (the two points are
   equally far from it), ``d·c = d·m`` — linear in ``c`` and exact for any angle. Then
   alternate the closed-form best angle of each group (2-D Procrustes) and the linear
   least-squares centre for those angles.
3. **Rotation or not.** The same correspondences are fitted with one translation per
   group. The motion is a rotation when the rotation model leaves clearly less residual
   (:data:`_ROTATION_GAIN`), the centre is determined to within
   :data:`_MAX_CENTER_SIGMA` of its distance from the tracks (standard error from the
   residual), and the gear turned measurably. A filament (a translation), a still gear,
   or too few tracks give no axis — tangential mode then, said in the summary.
4. **Refinement on derotated frames.** Lucas–Kanade's translation model is biased on a
   patch that turns by several degrees, and that bias leaks into the axis. So the axis is
   refined: every frame is turned back about the present axis by its predicted angle, the
   keyframe's features are matched in it (they now barely move and do not turn), and
   the small residual motions give the axis correction and each frame's angle
   correction by linear least squares (:mod:`flowtwin.vision.axis_refine`); two or
   three rounds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.vision.axis_refine import (
    KEY_FRAMES,
    MIN_TOL_PX,
    ROBUST_ROUNDS,
    refine_axis,
)
from flowtwin.vision.config import TrackingParams
from flowtwin.vision.features import FeatureMemo
from flowtwin.vision.roi import Roi

__all__ = ["AxisEstimate", "estimate_gear_axis", "fit_rotation_axis"]

F64 = npt.NDArray[np.float64]
U8 = npt.NDArray[np.uint8]

#: The rotation model must leave at most this fraction of the translation model's rms.
_ROTATION_GAIN = 0.5
#: Largest standard error of the centre, as a fraction of its distance from the tracks:
#: an axis off by e along the tracks' radius changes the angular speed by e/r, so at two
#: standard errors the axis adds at most about 1 % to the gear speed.
_MAX_CENTER_SIGMA = 0.005
#: Looser limits for the first fit, which only decides whether to refine (LK's bias on
#: turning patches inflates its residual).
_COARSE_GAIN = 0.8
_COARSE_SIGMA = 0.05
#: Least chord (rms over the correspondences) for a decision, px: below, the gear is still.
_MIN_CHORD_PX = 2.0
#: A new keyframe is taken after KEY_FRAMES frames, or once the median track moved this
#: far (LK matches a patch that turned by a few degrees; farther, its bias grows).
_KEY_CHORD_PX = 20.0
#: Iterations of the alternating angle / centre refinement.
_ITERATIONS = 30
#: Refinement (step 4): rounds.
_REFINE_ROUNDS = 3
#: A refinement step larger than this fraction of the distance to the tracks means the
#: first axis was not near enough for the linear correction: no axis.
_MAX_REFINE_SHIFT = 0.03



@dataclass(frozen=True, slots=True)
class AxisEstimate:
    """Result of fitting one rotation axis to tracked motion.

    Attributes
    ----------
    center_px
        Estimated axis ``(x, y)`` in frame pixels, or ``None``.
    is_rotation
        The motion is a rotation about ``center_px`` (use rotation mode).
    center_sigma_px
        Standard error of the centre along its worst direction, px.
    rms_rotation_px, rms_translation_px
        Residual rms of the rotation and of the translation model, px.
    max_angle_rad
        Largest rotation of one group, rad.
    n_points
        Correspondences used.
    frames
        Frames looked at.
    reason
        Why the motion was (not) taken for a rotation.
    moved
        The tracked points moved measurably (rms chord at least
        :data:`_MIN_CHORD_PX`): when false there was nothing to decide.
    angle_per_frame_rad
        Median rotation per frame (when the groups' frame counts are known), rad.
    """

    center_px: tuple[float, float] | None
    is_rotation: bool
    center_sigma_px: float
    rms_rotation_px: float
    rms_translation_px: float
    max_angle_rad: float
    n_points: int
    frames: int
    reason: str
    moved: bool = True
    angle_per_frame_rad: float = math.nan

    def to_dict(self) -> dict[str, object]:
        """JSON-ready dictionary (NaN becomes None)."""
        out: dict[str, object] = {}
        for key in self.__dataclass_fields__:
            value = getattr(self, key)
            if isinstance(value, float) and not math.isfinite(value):
                value = None
            out[key] = list(value) if isinstance(value, tuple) else value
        return out


def _no_axis(reason: str, n: int = 0, frames: int = 0, rms_t: float = math.nan,
             moved: bool = False) -> AxisEstimate:
    return AxisEstimate(None, False, math.nan, math.nan, rms_t, 0.0, n, frames, reason, moved)


def _angles(a: F64, b: F64, group: npt.NDArray[np.intp], n_groups: int) -> F64:
    """Best rotation angle per group taking vectors ``a`` to ``b`` (2-D Procrustes)."""
    cross = np.bincount(group, a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], minlength=n_groups)
    dot = np.bincount(group, np.sum(a * b, axis=1), minlength=n_groups)
    return np.arctan2(cross, dot)


def fit_rotation_axis(p0: F64, p1: F64, group: npt.NDArray[np.intp], *, frames: int = 0,
                      track: npt.NDArray[np.intp] | None = None,
                      age: npt.NDArray[np.intp] | None = None,
                      gain: float = _ROTATION_GAIN,
                      max_sigma: float = _MAX_CENTER_SIGMA) -> AxisEstimate:
    """Fit ``p1 = c + R(θ_g)(p0 − c)`` (one centre, one angle per group) and decide.

    The fit is repeated without the correspondences whose residual exceeds three robust
    standard deviations (tracks that slid along a tooth edge or onto the background),
    at most :data:`ROBUST_ROUNDS` times; the translation model is judged on the same
    points.

    Parameters
    ----------
    p0, p1
        Corresponding positions ``(x, y)``, px, shape ``(N, 2)``.
    group
        Group of each correspondence (same time interval, same angle), shape ``(N,)``.
    frames
        Frames the correspondences came from (reported only).
    track
        Which track each correspondence belongs to, shape ``(N,)``. One track seen in
        many frames gives correlated errors: the centre's standard error is computed as
        if there were only as many correspondences as tracks. Default: all independent.
    age
        Frames between the two positions of each correspondence, shape ``(N,)``
        (gives ``angle_per_frame_rad``).
    gain, max_sigma
        Decision: the rotation model's rms at most ``gain`` times the translation
        model's, and the centre's standard error at most ``max_sigma`` times its
        distance from the points.

    Returns
    -------
    AxisEstimate
    """
    p0 = np.asarray(p0, dtype=np.float64)
    n_tracks = p0.shape[0] if track is None else int(np.unique(track).size)
    corr = math.sqrt(max(p0.shape[0] / max(n_tracks, 1), 1.0))
    p1 = np.asarray(p1, dtype=np.float64)
    _, g = np.unique(np.asarray(group), return_inverse=True)
    keep = np.ones(p0.shape[0], dtype=bool)
    est, res = _fit_once(p0, p1, g, keep, frames, corr, gain, max_sigma)
    for _ in range(ROBUST_ROUNDS):
        if res is None:
            break
        mad = float(np.median(res[keep]))
        new = keep & (res <= max(3.0 * 1.4826 * mad, MIN_TOL_PX))
        if int(new.sum()) == int(keep.sum()):
            break
        keep = new
        est, res = _fit_once(p0, p1, g, keep, frames, corr, gain, max_sigma)
    if age is not None and est.center_px is not None and keep.any():
        c = np.asarray(est.center_px)
        kg = g[keep]
        theta = _angles(p0[keep] - c, p1[keep] - c, kg, int(g.max()) + 1)
        n_age = np.zeros(int(g.max()) + 1)
        n_age[kg] = np.asarray(age)[keep]
        used = np.unique(kg)
        used = used[n_age[used] > 0]
        if used.size:
            est = replace(est, angle_per_frame_rad=float(np.median(theta[used]
                                                                   / n_age[used])))
    return est


def _fit_once(p0_all: F64, p1_all: F64, g_all: npt.NDArray[np.intp],
              keep: npt.NDArray[np.bool_], frames: int, corr: float, gain: float,
              max_sigma: float) -> tuple[AxisEstimate, F64 | None]:
    """One rotation and translation fit on the kept points; residual norms of all."""
    p0, p1 = p0_all[keep], p1_all[keep]
    n = int(p0.shape[0])
    if n < 6:
        return _no_axis(f"too few tracked points on the gear ({n})", n, frames), None
    n_groups = int(g_all.max()) + 1
    g = g_all[keep]
    d = p1 - p0
    # translation model: one shift per group
    counts = np.maximum(np.bincount(g, minlength=n_groups), 1).astype(np.float64)
    shift: F64 = np.stack([np.bincount(g, d[:, k], minlength=n_groups)
                           for k in (0, 1)], 1) / counts[:, None]
    rms_t = float(np.sqrt(np.mean(np.sum((d - shift[g]) ** 2, axis=1))))
    chord = float(np.sqrt(np.mean(np.sum(d ** 2, axis=1))))
    if chord < _MIN_CHORD_PX:
        return _no_axis(f"the gear did not move (rms chord {chord:.2f} px)", n, frames,
                        rms_t), None
    # start: chords are perpendicular to (centre − midpoint): d·c = d·m
    m = 0.5 * (p0 + p1)
    a_mat = d.T @ d
    eig = np.linalg.eigvalsh(a_mat)
    if eig[0] <= 1e-9 * max(eig[1], 1e-12):
        return _no_axis("all tracks move in parallel: a translation", n, frames,
                        rms_t, True), None
    c = np.linalg.solve(a_mat, d.T @ np.sum(d * m, axis=1))
    for _ in range(_ITERATIONS):
        theta = _angles(p0 - c, p1 - c, g, n_groups)
        co, si = np.cos(theta)[g], np.sin(theta)[g]
        # p1 − R p0 = (I − R) c with (I − R)ᵀ(I − R) = 2(1 − cos θ)·I
        y = p1 - np.stack([co * p0[:, 0] - si * p0[:, 1], si * p0[:, 0] + co * p0[:, 1]], 1)
        u = 1.0 - co
        lhs = float(np.sum(2.0 * u))
        if lhs <= 1e-12:
            break
        c_new = np.array([np.sum(u * y[:, 0] - si * y[:, 1]),
                          np.sum(si * y[:, 0] + u * y[:, 1])]) / lhs
        step = float(np.hypot(*(c_new - c)))
        c = c_new
        if step < 1e-4:
            break
    theta_g = _angles(p0 - c, p1 - c, g, n_groups)

    def residual(q0: F64, q1: F64, gg: npt.NDArray[np.intp]) -> F64:
        co, si = np.cos(theta_g)[gg], np.sin(theta_g)[gg]
        r = q0 - c
        pred = c + np.stack([co * r[:, 0] - si * r[:, 1], si * r[:, 0] + co * r[:, 1]], 1)
        return np.asarray(np.hypot(*(q1 - pred).T))

    res = residual(p0, p1, g)
    dof = max(2 * n - 2 - n_groups, 1)
    sigma2 = float(np.sum(res ** 2)) / dof
    rms_r = float(np.sqrt(np.mean(res ** 2)))
    # the centre's covariance is sigma² (Σ (I−R)ᵀ(I−R))⁻¹ = sigma² / Σ 2(1 − cos θ) · I,
    # inflated for the correlation of one track's correspondences
    info = float(np.sum(2.0 * (1.0 - np.cos(theta_g)[g])))
    c_sigma = corr * math.sqrt(sigma2 / info) if info > 0 else math.inf
    dist = float(np.median(np.hypot(*(m - c).T)))
    max_angle = float(np.max(np.abs(theta_g)))
    centre = (float(c[0]), float(c[1]))
    res_all = residual(p0_all, p1_all, g_all)
    if not rms_r <= gain * rms_t:
        return AxisEstimate(centre, False, c_sigma, rms_r, rms_t, max_angle, n, frames,
                            f"a rotation fits no better than a translation "
                            f"(rms {rms_r:.3f} px against {rms_t:.3f} px)"), res_all
    if not c_sigma <= max_sigma * dist:
        return AxisEstimate(centre, False, c_sigma, rms_r, rms_t, max_angle, n, frames,
                            f"the axis is not determined (±{c_sigma:.1f} px at "
                            f"{dist:.0f} px from the tracks)"), res_all
    return AxisEstimate(centre, True, c_sigma, rms_r, rms_t, max_angle, n, frames,
                        f"rotation about ({centre[0]:.1f}, {centre[1]:.1f}) ± {c_sigma:.2f} px"
                        f" (rms {rms_r:.3f} px against {rms_t:.3f} px for a translation)"
                        ), res_all


def estimate_gear_axis(images: Sequence[U8], roi: Roi, params: TrackingParams | None = None
                       ) -> AxisEstimate:
    """Track features in the gear ROI over ``images`` and fit the rotation axis.

    Steps 1–3 of the module docstring give a first axis; step 4 refines it.

    Parameters
    ----------
    images
        Consecutive grey frames, shape ``(H, W)`` each, uint8 (30–90 frames are plenty
        at normal feed speeds; blank or repeated frames do no harm).
    roi
        The gear ROI.
    params
        Tracking parameters (LK window, pyramid, forward–backward limit, texture gate).

    Returns
    -------
    AxisEstimate
        The axis in frame pixels, and whether the motion is a rotation about it.
    """
    p = params or TrackingParams()
    memo = _memo(images, roi, p)
    est = _coarse_axis(images, roi, p, memo)
    if not est.is_rotation or est.center_px is None:
        return est
    centre = est.center_px
    dist = math.nan
    for _ in range(_REFINE_ROUNDS):
        ref = refine_axis(images, roi, p, centre, est.angle_per_frame_rad, memo)
        if ref is None:
            return replace(est, is_rotation=False,
                           reason=f"the axis found first ({centre[0]:.1f}, {centre[1]:.1f}) "
                           "could not be refined (too few tracks)")
        shift, sigma, rms, n, dist = ref
        if float(np.hypot(*shift)) > _MAX_REFINE_SHIFT * dist:
            return replace(est, is_rotation=False,
                           reason=f"the axis found first ({centre[0]:.1f}, {centre[1]:.1f}) "
                           f"moves by {float(np.hypot(*shift)):.1f} px when refined: not "
                           "determined")
        centre = (centre[0] + float(shift[0]), centre[1] + float(shift[1]))
        if float(np.hypot(*shift)) < 0.05:
            break
    if not rms <= _ROTATION_GAIN * est.rms_translation_px:
        return replace(est, center_px=centre, is_rotation=False, rms_rotation_px=rms,
                       reason=f"a rotation fits no better than a translation (rms {rms:.3f} "
                       f"px after derotation against {est.rms_translation_px:.3f} px)")
    if not (math.isfinite(sigma) and sigma <= _MAX_CENTER_SIGMA * dist):
        return replace(est, center_px=centre, is_rotation=False, center_sigma_px=sigma,
                       reason=f"the refined axis is not determined (±{sigma:.1f} px at "
                       f"{dist:.0f} px from the tracks)")
    return replace(est, center_px=centre, center_sigma_px=sigma, rms_rotation_px=rms,
                   n_points=n,
                   reason=f"rotation about ({centre[0]:.1f}, {centre[1]:.1f}) ± {sigma:.2f} px "
                   f"(rms {rms:.3f} px after derotation; {est.rms_translation_px:.3f} px "
                   "for a translation)")


def _memo(images: Sequence[U8], roi: Roi, p: TrackingParams) -> FeatureMemo:
    """Keyframe features of the padded gear ROI, detected once per frame for every pass."""
    h, w = images[0].shape[:2] if images else (roi.y1, roi.x1)
    x0, y0, x1, y1 = roi.padded(p.pad_px, w, h)
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    mask[roi.y - y0:roi.y1 - y0, roi.x - x0:roi.x1 - x0] = 255
    return FeatureMemo(p, mask)


def _coarse_axis(images: Sequence[U8], roi: Roi, p: TrackingParams, memo: FeatureMemo
                 ) -> AxisEstimate:
    """Step 1–3 of the module docstring: keyframe tracks, rigid fit, decision."""
    if len(images) < 2:
        return _no_axis("fewer than two frames", 0, len(images))
    h, w = images[0].shape[:2]
    x0, y0, x1, y1 = roi.padded(p.pad_px, w, h)
    win = (p.win_px, p.win_px)
    levels = max(0, min(p.pyramid_levels, int(math.log2(max(min(y1 - y0, x1 - x0)
                                                            / p.win_px, 1.0)))))
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 0.01)
    half = p.win_px // 2
    origin = np.array([x0, y0], dtype=np.float64)
    p0s: list[F64] = []
    p1s: list[F64] = []
    groups: list[npt.NDArray[np.intp]] = []
    tracks: list[npt.NDArray[np.intp]] = []
    ages: list[npt.NDArray[np.intp]] = []
    n_group = 0
    ids = np.zeros(0, np.intp)
    next_id = 0
    key: U8 | None = None
    key_pts = np.zeros((0, 2))
    pts = np.zeros((0, 2))
    vel = np.zeros(2)
    prev: U8 | None = None
    age = 0
    flags = cv2.OPTFLOW_USE_INITIAL_FLOW
    for index, image in enumerate(images):
        crop = np.ascontiguousarray(image[y0:y1, x0:x1])
        if prev is not None and np.array_equal(crop, prev):
            continue
        if key is not None and len(pts):
            # from the keyframe itself (no chained drift), guided by the last velocity
            guess = (pts + vel).astype(np.float32)[:, None, :]
            a = key_pts.astype(np.float32)[:, None, :]
            b, st, _ = cv2.calcOpticalFlowPyrLK(key, crop, a, guess.copy(), winSize=win,
                                                maxLevel=levels, criteria=crit, flags=flags)
            back, st2, _ = cv2.calcOpticalFlowPyrLK(crop, key, b, a.copy(), winSize=win,
                                                    maxLevel=levels, criteria=crit,
                                                    flags=flags)
            new = b[:, 0, :].astype(np.float64)
            fb = np.hypot(*(back[:, 0, :].astype(np.float64) - key_pts).T)
            ok = ((st[:, 0] == 1) & (st2[:, 0] == 1) & (fb < p.fb_max_px)
                  & (new[:, 0] >= half) & (new[:, 0] < x1 - x0 - half)
                  & (new[:, 1] >= half) & (new[:, 1] < y1 - y0 - half))
            if ok.any():
                vel = np.median(new[ok] - pts[ok], axis=0)
            key_pts, pts, ids = key_pts[ok], new[ok], ids[ok]
            age += 1
            if len(pts):
                p0s.append(key_pts + origin)
                p1s.append(pts + origin)
                groups.append(np.full(len(pts), n_group, np.intp))
                tracks.append(ids)
                ages.append(np.full(len(pts), age, np.intp))
                n_group += 1
        if (len(pts) < p.min_tracks or age >= KEY_FRAMES
                or (len(pts) and float(np.median(np.hypot(*(pts - key_pts).T))) > _KEY_CHORD_PX)):
            key = crop
            key_pts = memo(index, crop)
            pts = key_pts.copy()
            ids = np.arange(next_id, next_id + len(key_pts), dtype=np.intp)
            next_id += len(key_pts)
            age = 0
        prev = crop
    if not p0s:
        return _no_axis("no feature could be followed on the gear", 0, len(images))
    # a first, loose decision: the refinement (step 4) decides with the strict one
    return fit_rotation_axis(np.concatenate(p0s), np.concatenate(p1s),
                             np.concatenate(groups), frames=len(images),
                             track=np.concatenate(tracks), age=np.concatenate(ages),
                             gain=_COARSE_GAIN, max_sigma=_COARSE_SIGMA)
