"""Step 4 of the gear-axis estimate (:mod:`flowtwin.vision.axis`): refinement on derotated
frames.

Lucas–Kanade's translation model is biased on a patch that turns by several degrees,
and that bias leaks into an axis fitted to raw tracks. Here each frame is turned back
about the present axis ``c₀`` by its predicted angle ``θ`` before the keyframe's features
are matched in it, so the patches neither turn nor move much. With the true axis
``c₀ + e`` and the true angle ``θ + δ``, a keyframe point ``p₀`` is then found at

    p₀ + (R(−θ) − I)·e + δ·J(p₀ − c₀)          (first order in e and δ; J = quarter turn)

— linear in ``e`` and in one ``δ`` per frame, solved by least squares with outlier
rejection. Points that do not move with the gear (background seen through the teeth)
are dropped first: a static point looks exactly like an axis shift towards it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.vision.config import TrackingParams
from flowtwin.vision.features import FeatureMemo, detect_features
from flowtwin.vision.roi import Roi

__all__ = ["KEY_FRAMES", "MIN_TOL_PX", "ROBUST_ROUNDS", "refine_axis"]

F64 = npt.NDArray[np.float64]
U8 = npt.NDArray[np.uint8]

#: Largest number of frames followed from one keyframe.
KEY_FRAMES = 30
#: Rounds of outlier rejection, and the smallest rejection threshold, px.
ROBUST_ROUNDS = 4
MIN_TOL_PX = 0.15
#: Rotation after which a new keyframe is taken, rad (the derotated patch must still
#: lie in the padded ROI).
_REFINE_KEY_RAD = 0.15


def refine_axis(images: Sequence[U8], roi: Roi, p: TrackingParams,
                 centre: tuple[float, float], rate_rad: float,
                 memo: FeatureMemo | None = None
                 ) -> tuple[F64, float, float, int, float] | None:
    """Correction of the gear axis from tracks on derotated frames (module docstring).

    Parameters
    ----------
    images
        Consecutive grey frames, shape ``(H, W)``, uint8.
    roi
        The gear ROI.
    p
        Tracking parameters.
    centre
        Present axis ``(x, y)``, frame px.
    rate_rad
        Expected rotation per frame (first prediction), rad.
    memo
        Keyframe features already detected in other passes over the same frames (the
        same padded ROI and mask); ``None``: detected here.

    Returns
    -------
    tuple or None
        ``(e, standard error of the corrected axis, rms residual, points used, median
        distance of the points from the axis)`` with ``e`` the correction ``(dx, dy)``,
        px; ``None`` with too few tracks.
    """
    h, w = images[0].shape[:2]
    x0, y0, x1, y1 = roi.padded(p.pad_px, w, h)
    mask = np.zeros((y1 - y0, x1 - x0), np.uint8)
    mask[roi.y - y0:roi.y1 - y0, roi.x - x0:roi.x1 - x0] = 255
    c = np.array([centre[0] - x0, centre[1] - y0])
    win = (p.win_px, p.win_px)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 0.01)
    flags = cv2.OPTFLOW_USE_INITIAL_FLOW
    half = p.win_px // 2
    rows_p0: list[F64] = []
    rows_r: list[F64] = []
    rows_th: list[float] = []
    rows_g: list[npt.NDArray[np.intp]] = []
    rows_id: list[npt.NDArray[np.intp]] = []
    rows_seg: list[int] = []
    n_keys = 0
    ids = np.zeros(0, np.intp)
    next_id = 0
    key: U8 | None = None
    pts = np.zeros((0, 2))
    theta = 0.0
    inc = rate_rad if math.isfinite(rate_rad) else 0.0
    age = 0
    prev: U8 | None = None
    for index, image in enumerate(images):
        crop = np.ascontiguousarray(image[y0:y1, x0:x1])
        if prev is not None and np.array_equal(crop, prev):
            continue
        prev = crop
        if key is not None and len(pts) >= p.min_tracks:
            pred = theta + inc
            co, si = math.cos(pred), math.sin(pred)
            m = np.array([[co, -si, c[0] - co * c[0] + si * c[1]],
                          [si, co, c[1] - si * c[0] - co * c[1]]])
            der = cv2.warpAffine(crop, m, (crop.shape[1], crop.shape[0]),
                                 flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                 borderMode=cv2.BORDER_REPLICATE)
            a = pts.astype(np.float32)[:, None, :]
            b, st, _ = cv2.calcOpticalFlowPyrLK(key, der, a, a.copy(), winSize=win,
                                                maxLevel=2, criteria=crit, flags=flags)
            back, st2, _ = cv2.calcOpticalFlowPyrLK(der, key, b, a.copy(), winSize=win,
                                                    maxLevel=2, criteria=crit, flags=flags)
            q = b[:, 0, :].astype(np.float64)
            # where the point really is: turn q forward again; a point that did not move
            # (background seen through the teeth) is not on the gear
            arm_q = q - c
            raw = c + np.stack([co * arm_q[:, 0] - si * arm_q[:, 1],
                                si * arm_q[:, 0] + co * arm_q[:, 1]], 1)
            chord = np.hypot(*(raw - pts).T)
            expect = abs(pred) * np.hypot(*(pts - c).T)
            ok = ((st[:, 0] == 1) & (st2[:, 0] == 1) & (chord >= 0.5 * expect)
                  & (np.hypot(*(back[:, 0, :].astype(np.float64) - pts).T) < p.fb_max_px)
                  & (q[:, 0] >= half) & (q[:, 0] < x1 - x0 - half)
                  & (q[:, 1] >= half) & (q[:, 1] < y1 - y0 - half))
            if ok.sum() >= p.min_tracks:
                r = q[ok] - pts[ok]
                arm = pts[ok] - c
                jr = np.stack([-arm[:, 1], arm[:, 0]], 1)
                # quick per-frame angle correction: r ≈ t + δ·J(p₀ − c₀)
                a_mat = np.column_stack([np.tile(np.eye(2), (len(r), 1)),
                                         jr.reshape(-1, 1)])
                sol = np.linalg.lstsq(a_mat, r.reshape(-1), rcond=None)[0]
                new = pred + float(sol[2])
                inc, theta = new - theta, new
                rows_p0.append(pts[ok])
                rows_r.append(r)
                rows_th.append(pred)
                rows_g.append(np.full(int(ok.sum()), len(rows_th) - 1, np.intp))
                rows_id.append(ids[ok])
                rows_seg.append(n_keys)
            else:
                theta = pred            # lost this frame: carry on at the same rate
            age += 1
            if abs(theta) < _REFINE_KEY_RAD and age < KEY_FRAMES:
                continue
        # new keyframe: this frame, its features, angles from here
        key = crop
        pts = memo(index, crop) if memo is not None else detect_features(crop, p, mask=mask)
        ids = np.arange(next_id, next_id + len(pts), dtype=np.intp)
        next_id += len(pts)
        n_keys += 1
        theta, age = 0.0, 0
    if len(rows_th) < 2:
        return None
    p0 = np.concatenate(rows_p0)
    r = np.concatenate(rows_r)
    g = np.concatenate(rows_g)
    n_g = len(rows_th)
    th = np.asarray(rows_th)[g]
    arm = p0 - c
    jr = np.stack([-arm[:, 1], arm[:, 0]], 1)              # J(p₀ − c₀)
    co, si = np.cos(-th), np.sin(-th)
    b_cols = (np.stack([co - 1.0, si], 1), np.stack([-si, co - 1.0], 1))  # R(−θ) − I
    keep = np.ones(len(p0), dtype=bool)
    e = np.zeros(2)
    for _ in range(ROBUST_ROUNDS):
        solved = _shift_solve(b_cols, jr, r, g, n_g, keep)
        if solved is None:
            return None
        e, delta, _ = solved
        res = np.hypot(*_residual(b_cols, jr, r, g, e, delta).T)
        mad = float(np.median(res[keep]))
        new_keep = res <= max(3.0 * 1.4826 * mad, MIN_TOL_PX)
        if np.array_equal(new_keep, keep):
            break
        keep = new_keep
    solved = _shift_solve(b_cols, jr, r, g, n_g, keep)
    if solved is None:
        return None
    e, delta, schur = solved
    res = _residual(b_cols, jr, r, g, e, delta)[keep]
    n_keep = int(keep.sum())
    dof = max(2 * n_keep - 2 - len(np.unique(g[keep])), 1)
    sigma2 = float(np.sum(res ** 2)) / dof
    try:
        cov = sigma2 * np.linalg.inv(schur)
    except np.linalg.LinAlgError:
        return None
    sigma = float(np.sqrt(np.max(np.linalg.eigvalsh(cov))))
    # one track seen in many frames: correlated errors, count it about once
    tracks = np.concatenate(rows_id)[keep]
    sigma *= math.sqrt(max(n_keep / max(len(np.unique(tracks)), 1), 1.0))
    # errors shared by the frames of one keyframe (compression blocks, a speck) do not
    # average out: the spread of the solutions without one keyframe's frames at a time
    # (jackknife) is the honest error when it is larger
    seg = np.asarray(rows_seg)[g]
    segs = np.unique(seg[keep])
    if segs.size >= 3:
        est_e = []
        for k in segs:
            part = _shift_solve(b_cols, jr, r, g, n_g, keep & (seg != k))
            if part is not None:
                est_e.append(part[0])
        if len(est_e) >= 3:
            spread = np.asarray(est_e) - np.mean(est_e, axis=0)
            jack = (len(est_e) - 1) / len(est_e) * (spread.T @ spread)
            sigma = max(sigma, float(np.sqrt(np.max(np.linalg.eigvalsh(jack)))))
    rms = float(np.sqrt(np.mean(np.sum(res ** 2, axis=1))))
    dist = float(np.median(np.hypot(*arm[keep].T)))
    return e, sigma, rms, n_keep, dist


def _residual(b_cols: tuple[F64, F64], jr: F64, r: F64, g: npt.NDArray[np.intp], e: F64,
              delta: F64) -> F64:
    """``r − (R(−θ) − I)·e − δ_g·J(p₀ − c₀)`` for every point, shape ``(N, 2)``."""
    model = b_cols[0] * e[0] + b_cols[1] * e[1] + delta[g][:, None] * jr
    return np.asarray(r - model)


def _shift_solve(b_cols: tuple[F64, F64], jr: F64, r: F64, g: npt.NDArray[np.intp],
                 n_g: int, keep: npt.NDArray[np.bool_]
                 ) -> tuple[F64, F64, F64] | None:
    """Least squares for the axis shift ``e`` and the angle corrections ``δ_g``.

    Each ``δ_g`` touches only its own frame's points, so the normal equations are a
    2×2 block for ``e``, a diagonal for the ``δ``, and a coupling between them: ``δ``
    is eliminated (Schur complement) and ``e`` solved from a 2×2 system — O(N), where a
    dense solve of all unknowns costs O(N·G²).

    Returns ``(e, δ, Schur complement)`` (the complement is ``e``'s normal matrix, for
    its covariance), or ``None`` if singular.
    """
    gk, b0, b1, jk, rk = g[keep], b_cols[0][keep], b_cols[1][keep], jr[keep], r[keep]
    if gk.size < 3:
        return None
    a_ee = np.array([[np.sum(b0 * b0), np.sum(b0 * b1)],
                     [np.sum(b1 * b0), np.sum(b1 * b1)]])
    rhs_e = np.array([np.sum(b0 * rk), np.sum(b1 * rk)])
    d = np.bincount(gk, np.sum(jk * jk, axis=1), minlength=n_g)
    a_ed = np.stack([np.bincount(gk, np.sum(b0 * jk, axis=1), minlength=n_g),
                     np.bincount(gk, np.sum(b1 * jk, axis=1), minlength=n_g)])
    rhs_d = np.bincount(gk, np.sum(jk * rk, axis=1), minlength=n_g)
    used = d > 0
    inv_d = np.zeros(n_g)
    inv_d[used] = 1.0 / d[used]
    schur = a_ee - (a_ed * inv_d) @ a_ed.T
    try:
        e: F64 = np.asarray(np.linalg.solve(schur, rhs_e - (a_ed * inv_d) @ rhs_d),
                            dtype=np.float64)
    except np.linalg.LinAlgError:
        return None
    delta = inv_d * (rhs_d - a_ed.T @ e)
    return e, delta, schur
