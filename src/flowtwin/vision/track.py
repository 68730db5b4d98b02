"""Feature tracking in one ROI: Shi–Tomasi features, pyramidal Lucas–Kanade [003 §2.2].

Per frame pair the tracker returns one robust displacement: along the filament axis
(translation, px) or about the gear axis (rotation, rad). The steps, after [003 §2.2] and
the OpenCV example it cites [003 ref. 24]:

1. The ROI, padded by the motion allowed between two frames, is cut out and normalised to
   zero mean and fixed contrast, so illumination/exposure changes do not read as motion.
2. Features are detected with ``goodFeaturesToTrack`` on the raw image of a keyframe
   (:func:`~flowtwin.vision.features.detect_features`); a feature is kept only if its
   smaller structure-tensor eigenvalue (Shi–Tomasi score) stands clear of what the image
   noise alone gives.
   Edges (one large eigenvalue, the aperture problem) and noise do not qualify, so a
   texture-less ROI yields no features and is *flagged*, never guessed. Each feature is
   followed from the keyframe (not from frame to frame, so position errors do not add
   up as a random walk); a new keyframe is taken after ``redetect_interval`` frames, when
   half the features have left the ROI or failed, or after a failed step.
3. Pyramidal LK forward, then backward; tracks whose round trip misses by more than
   ``fb_max_px`` are dropped. The last displacement (scaled by the time step) is the
   initial guess, so large steady motions stay inside the LK window.
4. Tracks moving sideways (across the filament, or radially on the gear) are rejected.
5. The displacement is the mean of the tracks within 3 robust standard deviations
   (1.4826·MAD) of their median; the sample is valid with at least ``min_tracks`` such
   tracks, at least half of the candidates, and a standard error below ``max_se_px``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Literal

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.vision.config import TrackingParams
from flowtwin.vision.features import detect_features, is_stale, robust_mean, window_std_at
from flowtwin.vision.roi import Roi

__all__ = ["RoiTracker", "StepEstimate"]

U8 = npt.NDArray[np.uint8]
F32 = npt.NDArray[np.float32]
TrackMode = Literal["translation", "rotation"]

#: Contrast of the normalised crops: one standard deviation maps to this many grey levels.
_NORM_CONTRAST = 40.0
#: Largest gear rotation against the keyframe before new features are taken, rad (the
#: current crop is turned back by the expected rotation before LK, see ``_derotate``).
_MAX_KEY_ROTATION = 0.5
#: Smallest rotation that is undone by warping before LK, rad. OpenCV warps quantise
#: source coordinates to 1/32 px, which biases tiny rotations (a 0.0017 rad turn reads
#: 17 % large with cubic interpolation); below this LK on the unwarped patch is better.
_MIN_DEROTATION = 0.02
#: Interpolation of the derotation warp.
_DEROTATE_INTERP = cv2.INTER_LINEAR
#: Lucas–Kanade stopping rule: iterations and the smallest update, px.
_LK_ITERATIONS = 30
_LK_EPS_PX = 0.003
#: Largest mean absolute difference of an aligned window, as a fraction of the window's
#: standard deviation in the keyframe (2/sqrt(pi) = 1.13 for pure noise; 0.6 needs a
#: texture about 1.6 times stronger than the per-frame noise).
_MATCH_RATIO = 0.6
#: Spread of agreeing-looking tracks (rms, px) above which a failed step is put down to
#: missing texture rather than to a tracking problem (textured steps scatter ~0.05 px).
_NOISE_SPREAD_PX = 0.5
#: A ROI whose last valid step moved less than this is still, px: repeated pixels then
#: mean "nothing changed" (a compressing codec copies still blocks), not a damaged frame.
_STILL_PX = 0.1
#: This many stale frames in a row mean a still region, not damaged frames.
_STALE_RUN_STILL = 3
#: Seed of the sub-pixel jitter of new features (results are reproducible).
_JITTER_SEED = 20170101


@dataclass(frozen=True, slots=True)
class StepEstimate:
    """Robust displacement of one ROI between two frames.

    Attributes
    ----------
    value
        Mean displacement along the axis (px, translation) or rotation angle (rad);
        NaN if the sample is not valid.
    n_tracks
        Tracks that agreed (inliers).
    n_candidates
        Tracks that passed the forward–backward and sideways checks.
    spread_px
        Standard deviation of the inliers about the mean, px.
    se_px
        Standard error of the mean, px.
    low_texture
        No trackable texture (see :class:`RoiTracker`).
    valid
        The value can be used.
    span_s
        Time the step covers, s: from the last frame this tracker processed (longer than
        one frame after a stale frame).
    stale
        The ROI repeated the previous frame's pixels (:func:`~.features.is_stale`: a
        damaged frame the decoder concealed), or this is the step right after such a frame (the
        decoder may have lost frames there that constant-rate timestamps cannot show).
        Either way the value is NaN.
    """

    value: float
    n_tracks: int
    n_candidates: int
    spread_px: float
    se_px: float
    low_texture: bool
    valid: bool
    span_s: float = math.nan
    stale: bool = False


class RoiTracker:
    """Tracks features inside one ROI from frame to frame.

    Parameters
    ----------
    roi
        Where features are detected and measured.
    frame_size
        ``(width, height)`` of the frames, px.
    params
        Tracking parameters.
    mode
        ``"translation"`` (displacement along ``axis``) or ``"rotation"`` (about
        ``center_px``).
    axis
        Unit vector of the positive direction for translation, ``(dx, dy)``.
    center_px
        Rotation axis ``(x, y)`` in frame pixels (rotation mode).
    inset_px
        Features are detected at least this far inside the ROI's left and right sides
        (keeps LK windows off the filament edges), px.
    check_stale
        Treat rows that repeat the previous frame's pixels as a damaged frame
        (:func:`~.features.is_stale`). Off for inter-frame codecs, which copy still
        blocks.
    """

    def __init__(self, roi: Roi, frame_size: tuple[int, int], params: TrackingParams, *,
                 mode: TrackMode = "translation", axis: tuple[float, float] = (0.0, 1.0),
                 center_px: tuple[float, float] | None = None, inset_px: int = 0,
                 check_stale: bool = True) -> None:
        if mode == "rotation" and center_px is None:
            raise ValueError("rotation mode needs center_px")
        self.roi = roi
        self.params = params
        self.mode = mode
        self.check_stale = check_stale
        self.axis = np.asarray(axis, dtype=np.float64) / math.hypot(*axis)
        w, h = frame_size
        x0, y0, x1, y1 = roi.padded(params.pad_px, w, h)
        if mode == "translation":
            # pad only along the motion: static background beside the filament would
            # otherwise dominate the coarse pyramid levels and pull LK to zero
            if abs(self.axis[0]) < 1e-9:
                x0, x1 = roi.x, roi.x1
            elif abs(self.axis[1]) < 1e-9:
                y0, y1 = roi.y, roi.y1
        self.x0, self.y0, self.x1, self.y1 = x0, y0, x1, y1
        self._origin = np.array([x0, y0], dtype=np.float64)
        #: Positions (frame px, shape ``(N, 2)``) of the tracks of the last step and which
        #: of them were kept (passed every check and agreed); for drawing.
        self.last_points = np.zeros((0, 2))
        self.last_kept = np.zeros(0, dtype=bool)
        self.center = None if center_px is None else np.array(
            [center_px[0] - self.x0, center_px[1] - self.y0], dtype=np.float64)
        # ROI inside the crop
        self._rx0, self._ry0 = roi.x - self.x0, roi.y - self.y0
        self._rx1, self._ry1 = self._rx0 + roi.w, self._ry0 + roi.h
        self._mask = np.zeros((self.y1 - self.y0, self.x1 - self.x0), np.uint8)
        ins = min(inset_px, roi.w // 4)
        self._mask[self._ry0:self._ry1, self._rx0 + ins:self._rx1 - ins] = 255
        self._mask_box = (slice(self._ry0, self._ry1), slice(self._rx0 + ins, self._rx1 - ins))
        self._win = (params.win_px, params.win_px)
        self._criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, _LK_ITERATIONS,
                          _LK_EPS_PX)
        self._min_dist = max(3, params.win_px // 4)
        self._rng = np.random.default_rng(_JITTER_SEED)
        crop_h, crop_w = self.y1 - self.y0, self.x1 - self.x0
        # coarsest level still at least one window wide
        fit = int(math.floor(math.log2(max(min(crop_h, crop_w) / params.win_px, 1.0))))
        self._levels = max(0, min(params.pyramid_levels, fit))
        # phase correlation (motion guess) on a crop reduced to <= ~128 px
        self._pc_factor = max(1, math.ceil(max(crop_h, crop_w) / 128))
        small = (max(8, crop_w // self._pc_factor), max(8, crop_h // self._pc_factor))
        self._pc_size = small
        self._pc_window = cv2.createHanningWindow(small, cv2.CV_32F)
        self.reset()

    def reset(self) -> None:
        """Forget the keyframe (after a blank or unusable frame)."""
        self._ref: U8 | None = None
        self._ref_pts = np.zeros((0, 2), np.float64)
        self._cur_pts = np.zeros((0, 2), np.float64)
        self._alive = np.zeros(0, dtype=bool)
        self._ref_std = np.zeros(0, np.float64)
        self._age = 0
        self._total = 0.0
        self._low_texture = False
        self._last_value = 0.0
        self._last_valid = False
        self._last_step_px = math.inf
        self._stale_run = 0
        self._last_dt: float | None = None
        self._prev_small: F32 | None = None
        self._prev_crop: U8 | None = None
        self._pending_s = 0.0
        self._damaged = False

    # --- helpers --------------------------------------------------------------------
    def _crop(self, gray: U8) -> U8:
        return gray[self.y0:self.y1, self.x0:self.x1]

    @staticmethod
    def _normalise(crop: U8) -> U8:
        """Zero mean, fixed contrast: gain and offset changes of the exposure cancel."""
        mean, std = cv2.meanStdDev(crop)
        s = max(float(std[0, 0]), 1e-3)
        alpha = _NORM_CONTRAST / s
        return np.asarray(cv2.addWeighted(crop, alpha, crop, 0.0,
                                          128.0 - alpha * float(mean[0, 0]), dtype=cv2.CV_8U))

    def _keyframe(self, crop: U8, norm: U8) -> None:
        """Make this frame the reference and detect fresh features on it."""
        p = self.params
        self._ref = norm
        self._age = 0
        self._total = 0.0
        pts = detect_features(crop, p, mask=self._mask, min_distance_px=self._min_dist,
                              noise_region=self._mask_box)
        # spread the features over sub-pixel phases: LK's interpolation error depends on
        # the sub-pixel part of the displacement, and with every feature on the integer
        # grid those errors would add up coherently instead of averaging out
        jitter = self._rng.uniform(-0.5, 0.5, size=(len(pts), 2))
        self._ref_pts = pts + jitter
        self._cur_pts = self._ref_pts.copy()
        self._alive = np.ones(len(self._ref_pts), dtype=bool)
        self._low_texture = len(self._ref_pts) < p.min_tracks
        # contrast of each feature's window in the keyframe, to judge later matches
        self._ref_std = window_std_at(norm, self._ref_pts, self.params.win_px)

    def _predict(self, pts: npt.NDArray[np.float64], step: float) -> npt.NDArray[np.float64]:
        if self.mode == "translation":
            return pts + self.axis[None, :] * step
        assert self.center is not None
        co, si = math.cos(step), math.sin(step)
        r = pts - self.center
        return np.stack([co * r[:, 0] - si * r[:, 1], si * r[:, 0] + co * r[:, 1]],
                        axis=1) + self.center

    # --- one frame ------------------------------------------------------------------
    def update(self, gray: U8, dt_s: float | None = None) -> StepEstimate | None:
        """Process the next frame.

        Parameters
        ----------
        gray
            Whole grey frame, shape ``(H, W)``, uint8.
        dt_s
            Time since the previous frame given to this tracker, s.

        Returns
        -------
        StepEstimate or None
            ``None`` for the first frame (nothing to compare with).
        """
        crop = self._crop(gray)
        still = ((self._last_valid and self._last_step_px <= _STILL_PX)
                 or self._stale_run >= _STALE_RUN_STILL)
        stale = (self.check_stale and self._prev_crop is not None
                 and is_stale(crop, self._prev_crop))
        self._stale_run = self._stale_run + 1 if stale else 0
        if stale and not still:
            # a repeated image region (decoder concealment, driver repeat) of a moving
            # surface holds no information about this instant: skip it and let the next
            # step span it. On a still surface (last step below _STILL_PX, or repeats in
            # _STALE_RUN_STILL frames running: concealment is sporadic) it is what a
            # compressing codec does with still blocks, and it is tracked as usual.
            if dt_s is not None:
                self._pending_s += dt_s
            self._damaged = True
            return StepEstimate(math.nan, 0, 0, math.nan, math.nan, False, False, stale=True)
        self._prev_crop = crop.copy()
        if dt_s is not None:
            dt_s += self._pending_s
        self._pending_s = 0.0
        norm = self._normalise(crop)
        small: F32 | None = None
        if self.mode == "translation":
            small = cv2.resize(norm, self._pc_size,
                               interpolation=cv2.INTER_AREA).astype(np.float32)
        prev_small, self._prev_small = self._prev_small, small
        if self._ref is None:
            self._keyframe(crop, norm)
            return None
        result = self._step(norm, dt_s, self._guess(prev_small, small, dt_s))
        result = replace(result, span_s=math.nan if dt_s is None else dt_s)
        if self._damaged:
            # the step across a concealed (damaged) frame: the decoder may have lost
            # frames there too, which constant-rate timestamps do not show
            self._damaged = False
            result = replace(result, value=math.nan, valid=False, stale=True)
        self._age += 1
        n_alive = int(self._alive.sum())
        if (not result.valid or self._age >= self.params.redetect_interval
                or n_alive < max(2 * self.params.min_tracks, len(self._alive) // 2)
                or (self.mode == "rotation" and abs(self._total) > _MAX_KEY_ROTATION)):
            self._keyframe(crop, norm)
        return result

    def _derotate(self, img: U8, theta: float) -> U8:
        """``img`` turned by ``-theta`` about the gear axis (bilinear interpolation)."""
        assert self.center is not None
        co, si = math.cos(theta), math.sin(theta)
        cx, cy = self.center
        # destination q -> source c + R(theta)(q - c)
        m = np.array([[co, -si, cx - co * cx + si * cy],
                      [si, co, cy - si * cx - co * cy]], dtype=np.float64)
        return np.asarray(cv2.warpAffine(img, m, (img.shape[1], img.shape[0]),
                                         flags=_DEROTATE_INTERP | cv2.WARP_INVERSE_MAP,
                                         borderMode=cv2.BORDER_REPLICATE))

    def _guess(self, prev_small: F32 | None, small: F32 | None, dt_s: float | None) -> float:
        """Expected step: the last step scaled by the time step; for translation the
        phase correlation of the reduced crops (robust to sudden speed changes)."""
        scale = 1.0
        if dt_s is not None and self._last_dt:
            scale = dt_s / self._last_dt
        predicted = self._last_value * scale
        if self.mode == "rotation" or prev_small is None or small is None:
            # a rotation about an axis inside the crop has no single shift to correlate
            return predicted
        (sx, sy), response = cv2.phaseCorrelate(prev_small, small, self._pc_window)
        if response < 0.05:
            return predicted
        return float(np.array([sx, sy]) @ self.axis) * self._pc_factor

    def _invalid(self, *, low_texture: bool, n_candidates: int = 0) -> StepEstimate:
        return StepEstimate(math.nan, 0, n_candidates, math.nan, math.nan, low_texture, False)

    def _step(self, cur: U8, dt_s: float | None, step_guess: float) -> StepEstimate:
        p = self.params
        if dt_s is not None:
            self._last_dt = dt_s
        if self._low_texture:
            self._last_valid = False
            return self._invalid(low_texture=True)
        idx = np.flatnonzero(self._alive)
        ref_pts, prev_pts = self._ref_pts[idx], self._cur_pts[idx]
        ref = self._ref
        assert ref is not None
        if self.mode == "rotation" and abs(self._total + step_guess) >= _MIN_DEROTATION:
            # undo the expected rotation since the keyframe, so LK only sees a small
            # residual motion of an unrotated patch (a translation model cannot follow
            # a patch that turns by several degrees without bias)
            theta = self._total + step_guess
            target = self._derotate(cur, theta)
            guess = self._predict(prev_pts, -self._total)
        else:
            theta = 0.0
            target = cur
            guess = self._predict(prev_pts, step_guess)
        p0 = np.ascontiguousarray(ref_pts[:, None, :], dtype=np.float32)
        flags = cv2.OPTFLOW_USE_INITIAL_FLOW
        p1, st1, err1 = cv2.calcOpticalFlowPyrLK(
            ref, target, p0, np.ascontiguousarray(guess[:, None, :], dtype=np.float32),
            winSize=self._win, maxLevel=self._levels, criteria=self._criteria,
            flags=flags)
        p0r, st2, _ = cv2.calcOpticalFlowPyrLK(target, ref, p1, p0.copy(), winSize=self._win,
                                               maxLevel=self._levels,
                                               criteria=self._criteria, flags=flags)
        b = p1[:, 0, :].astype(np.float64)
        fb = np.hypot(*(p0r[:, 0, :].astype(np.float64) - ref_pts).T)
        if theta != 0.0:
            b = self._predict(b, theta)
        half = p.win_px // 2
        h, w = cur.shape[:2]
        inside = ((b[:, 0] >= half) & (b[:, 0] < w - half) & (b[:, 1] >= half)
                  & (b[:, 1] < h - half))
        good = (st1[:, 0] == 1) & (st2[:, 0] == 1) & (fb < p.fb_max_px) & inside
        # the matched windows must agree better than noise would: the mean absolute
        # difference after alignment against the window's own contrast (noise alone
        # gives 2/sqrt(pi) = 1.13 of it, a clean texture much less)
        match = err1[:, 0].astype(np.float64) <= _MATCH_RATIO * self._ref_std[idx]
        unmatched = int(np.sum(good & ~match))
        good &= match
        if self.mode == "translation":
            perp = np.array([-self.axis[1], self.axis[0]])
            total = b - ref_pts
            step = (b - prev_pts) @ self.axis
            good &= (np.abs(total @ perp)
                     <= p.side_max_px + p.side_frac * np.abs(total @ self.axis))
            values, lever = step[good], np.ones(int(good.sum()))
        else:
            assert self.center is not None
            r_ref, r_prev, r_new = ref_pts - self.center, prev_pts - self.center, \
                b - self.center
            n_ref, n_new = np.hypot(*r_ref.T), np.hypot(*r_new.T)
            ang_new = np.arctan2(r_ref[:, 0] * r_new[:, 1] - r_ref[:, 1] * r_new[:, 0],
                                 np.sum(r_ref * r_new, axis=1))
            ang_prev = np.arctan2(r_ref[:, 0] * r_prev[:, 1] - r_ref[:, 1] * r_prev[:, 0],
                                  np.sum(r_ref * r_prev, axis=1))
            good &= n_ref >= 2 * p.win_px
            good &= np.abs(n_new - n_ref) <= p.side_max_px + p.side_frac * np.abs(
                ang_new * n_ref)
            values, lever = (ang_new - ang_prev)[good], n_ref[good]
        in_roi = ((b[:, 0] >= self._rx0) & (b[:, 0] < self._rx1) & (b[:, 1] >= self._ry0)
                  & (b[:, 1] < self._ry1))
        self._cur_pts[idx] = b
        self._alive[idx] = good & in_roi
        # for drawing (inspect): where the tracks went, and which passed the checks
        self.last_points = b + self._origin
        self.last_kept = good.copy()
        n_cand = int(values.size)
        self._last_valid = False
        if n_cand < p.min_tracks:
            # mostly windows that match no better than noise: the texture is too weak
            return self._invalid(low_texture=unmatched >= n_cand, n_candidates=n_cand)
        mean, inl = robust_mean(values, lever)
        n_in = int(inl.sum())
        res_px = (values[inl] - mean) * lever[inl]
        spread = float(np.sqrt(np.mean(res_px ** 2))) if n_in > 1 else math.inf
        se = spread / math.sqrt(max(n_in - 1, 1))
        valid = n_in >= p.min_tracks and n_in >= 0.5 * n_cand and se <= p.max_se_px
        if valid:
            self._last_value = mean
            self._last_valid = True
            self._last_step_px = abs(mean) * float(np.median(lever[inl]))
            self._total += mean
        if not valid and spread > _NOISE_SPREAD_PX:
            # tracks that passed every check yet scatter by this much follow noise
            # blotches and static structure, not the surface: no trackable texture
            self._alive[idx] = False
            return StepEstimate(math.nan, n_in, n_cand, spread, se, True, False)
        # outliers of this step do not continue
        keep = np.zeros(len(idx), dtype=bool)
        keep[np.flatnonzero(good)[inl]] = True
        self.last_kept = keep.copy()
        self._alive[idx] &= keep
        return StepEstimate(mean if valid else math.nan, n_in, n_cand, spread, se, False, valid)
