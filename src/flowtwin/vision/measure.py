"""The slip-camera pipeline: frames in, gear speed, filament speed, slip and width out.

Per frame (SPEC §3.7, [003 §2.2]): skip blank frames and exact repeats, track the gear ROI
(rotation about the gear axis, or tangential motion) and the ``after`` ROI (translation
along the filament) with :class:`~flowtwin.vision.track.RoiTracker`, and measure the width
in the ``before`` ROI (:func:`~flowtwin.vision.width.measure_width_px`). Afterwards: the
scale (known, or ``k_cal`` from a known width [003 Eq. 4]), speeds ``v = k_cal·S/Δt``
with each step's own capture-time ``Δt`` [003 Eq. 5], slip [000 Eq. 1], volume flow,
Gaussian smoothing in time, gaps from the timestamps, and a summary built from travelled
distances (so uneven steps weigh by their duration).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.errors import VisionError
from flowtwin.vision.config import VisionConfig
from flowtwin.vision.features import is_stale
from flowtwin.vision.flow import gaussian_smooth, slip_fraction, speed_mm_s, volume_flow_mm3_s
from flowtwin.vision.result import (
    FILAMENT_INVALID,
    GEAR_INVALID,
    WIDTH_INVALIDATING,
    Quality,
    VisionResult,
    VisionSeries,
    VisionSummary,
)
from flowtwin.vision.source import Frame, open_source
from flowtwin.vision.track import RoiTracker, StepEstimate
from flowtwin.vision.width import calibration_factor, measure_width_px

__all__ = ["SourceInfo", "measure", "measure_frames"]

NAN = math.nan


@dataclass(frozen=True, slots=True)
class SourceInfo:
    """Description of where frames came from (for the summary and messages)."""

    description: str = "<frames>"
    kind: str = "frames"
    timestamp_source: str = "given"
    frames_expected: int | None = None


@dataclass(slots=True)
class _Rows:
    frame: list[int]
    t: list[float]
    dt: list[float]
    flags: list[int]
    gear: list[float]
    gear_span: list[float]
    gear_n: list[int]
    gear_se: list[float]
    fil: list[float]
    fil_span: list[float]
    fil_n: list[int]
    fil_se: list[float]
    width: list[float]
    left: list[float]
    right: list[float]

    @classmethod
    def empty(cls) -> _Rows:
        return cls([], [], [], [], [], [], [], [], [], [], [], [], [], [], [])

    def add(self, frame: int, t: float, dt: float, flags: Quality, gear: StepEstimate | None,
            fil: StepEstimate | None, width: tuple[float, float, float]) -> None:
        self.frame.append(frame)
        self.t.append(t)
        self.dt.append(dt)
        self.flags.append(int(flags))
        self.gear.append(gear.value if gear is not None else NAN)
        self.gear_span.append(gear.span_s if gear is not None else NAN)
        self.gear_n.append(gear.n_tracks if gear is not None else 0)
        self.gear_se.append(gear.se_px if gear is not None else NAN)
        self.fil.append(fil.value if fil is not None else NAN)
        self.fil_span.append(fil.span_s if fil is not None else NAN)
        self.fil_n.append(fil.n_tracks if fil is not None else 0)
        self.fil_se.append(fil.se_px if fil is not None else NAN)
        self.width.append(width[0])
        self.left.append(width[1])
        self.right.append(width[2])


def _step_flags(est: StepEstimate | None, low: Quality, bad: Quality, stale: Quality
                ) -> Quality:
    if est is None or est.valid:
        return Quality(0)
    if est.stale:
        return stale
    return low if est.low_texture else bad


def measure_frames(frames: Iterable[Frame], config: VisionConfig, *,
                   frame_size: tuple[int, int], info: SourceInfo | None = None,
                   ) -> VisionResult:
    """Measure gear speed, filament speed, slip and width from a sequence of frames.

    Parameters
    ----------
    frames
        Frames in capture order (grey uint8 images, capture times in s).
    config
        ROIs, scale, gear geometry and tracking parameters.
    frame_size
        ``(width, height)`` of the frames, px.
    info
        Description of the source for the summary.

    Returns
    -------
    VisionResult
        Per-frame series and summary.

    Raises
    ------
    VisionError
        ROI outside the frame, no scale, timestamps that do not increase, no frames, or
        a calibration width with no measurable filament edges.
    """
    info = info or SourceInfo()
    if config.mm_per_px is None and config.calib_width_mm is None:
        raise VisionError("no image scale given", source=config.source, field="scale",
                          allowed="--mm-per-px K or --calib-width-mm W "
                          "(or [scale] in the config file)")
    width_px, height_px = frame_size
    config.rois.check_inside(width_px, height_px, source=config.source or info.description)
    p = config.tracking
    sign = 1.0 if config.direction == "down" else -1.0
    fil_tr = RoiTracker(config.rois.after, frame_size, p, axis=(0.0, sign),
                        inset_px=p.win_px // 2)
    if config.gear_center_px is not None:
        gear_tr = RoiTracker(config.rois.gear, frame_size, p, mode="rotation",
                             center_px=config.gear_center_px)
    else:
        gear_tr = RoiTracker(config.rois.gear, frame_size, p, axis=(0.0, sign))
    before = config.rois.before
    rows = _Rows.empty()
    prev_img: npt.NDArray[np.uint8] | None = None
    t_last: float | None = None
    t0: float | None = None
    started = time.perf_counter()
    for frame in frames:
        img = frame.image
        if img.shape[:2] != (height_px, width_px):
            raise VisionError("frame size differs from the declared size",
                              source=f"{info.description} frame {frame.index}",
                              value=f"{img.shape[1]}×{img.shape[0]}",
                              allowed=f"{width_px}×{height_px}")
        if t0 is None:
            t0 = frame.t_s
        t_rel = frame.t_s - t0
        no_width = (NAN, NAN, NAN)
        if float(np.std(img[::4, ::4])) < p.blank_std_dn:
            rows.add(frame.index, t_rel, NAN, Quality.BLANK, None, None, no_width)
            continue
        if prev_img is not None and np.array_equal(img, prev_img):
            rows.add(frame.index, t_rel, NAN, Quality.DUPLICATE, None, None, no_width)
            continue
        dt: float | None = None
        if t_last is not None:
            dt = frame.t_s - t_last
            if not dt > 0:
                raise VisionError("capture timestamps do not increase",
                                  source=f"{info.description} frame {frame.index}",
                                  value=f"{frame.t_s:.6f} s after {t_last:.6f} s",
                                  allowed="strictly increasing times (fix the timestamp "
                                  "file or give one)")
        g = gear_tr.update(img, dt)
        f = fil_tr.update(img, dt)
        em = measure_width_px(img[before.slices], sigma_px=p.width_sigma_px,
                              min_edge_dn_px=p.min_edge_dn_px)
        flags = Quality.FIRST if dt is None else Quality(0)
        flags |= _step_flags(g, Quality.GEAR_LOW_TEXTURE, Quality.GEAR_TRACKING,
                             Quality.GEAR_STALE)
        flags |= _step_flags(f, Quality.FILAMENT_LOW_TEXTURE, Quality.FILAMENT_TRACKING,
                             Quality.FILAMENT_STALE)
        before_crop = img[before.slices]
        if not em.ok or (prev_img is not None
                         and is_stale(before_crop, prev_img[before.slices])):
            flags |= Quality.WIDTH_INVALID
            em = replace(em, ok=False)
        width = (em.width_px, em.left_px + before.x, em.right_px + before.x) if em.ok \
            else no_width
        rows.add(frame.index, t_rel, NAN if dt is None else dt, flags, g, f, width)
        prev_img = img
        t_last = frame.t_s
    elapsed = time.perf_counter() - started
    if not rows.t:
        raise VisionError("the source delivered no frames", source=info.description)
    return _finish(rows, config, info, elapsed)


def _finish(rows: _Rows, config: VisionConfig, info: SourceInfo, elapsed: float
            ) -> VisionResult:
    p = config.tracking
    t = np.asarray(rows.t)
    dt = np.asarray(rows.dt)
    flags = np.asarray(rows.flags, dtype=np.int64)
    width_px = np.asarray(rows.width)
    # gaps: a capture interval much longer than the typical one means dropped frames
    # (measured between delivered frames, so skipped blank/duplicate frames do not count)
    intervals = np.diff(t)
    period = float(np.median(intervals)) if intervals.size else NAN
    gap = np.zeros(t.size, dtype=bool)
    gap[1:] = intervals > p.gap_factor * period
    flags[gap] |= int(Quality.GAP)
    dropped = int(np.sum(np.rint(intervals[gap[1:]] / period) - 1)) if gap.any() else 0
    # scale [003 Eq. 4]
    w_ok = np.isfinite(width_px)
    if config.mm_per_px is not None:
        k_cal, scale_source = config.mm_per_px, "mm_per_px"
    else:
        assert config.calib_width_mm is not None
        if not w_ok.any():
            raise VisionError("cannot calibrate the scale: the filament edges were not found "
                              "in any frame", source=config.source or info.description,
                              field="roi.before", value=config.rois.before.text(),
                              allowed="a before ROI across both filament edges")
        k_cal = calibration_factor(config.calib_width_mm, float(np.mean(width_px[w_ok])))
        scale_source = "calib_width_mm"
    # gear surface speed; each step over its own span (longer after a stale ROI)
    gear_step = np.asarray(rows.gear)
    gear_span = np.asarray(rows.gear_span)
    fil_span = np.asarray(rows.fil_span)
    radius_mm: float | None = None
    radius_source: str | None = None
    if config.gear_center_px is not None:
        cx = config.gear_center_px[0]
        if config.gear_radius_mm is not None:
            radius_mm, radius_source = config.gear_radius_mm, "config"
        else:
            left, right = np.asarray(rows.left), np.asarray(rows.right)
            contact = np.minimum(np.abs(left - cx), np.abs(right - cx))[w_ok]
            if contact.size == 0:
                raise VisionError("cannot measure the gear radius: the filament edges were "
                                  "not found", source=config.source or info.description,
                                  field="gear.radius_mm",
                                  allowed="give --gear-radius-mm, or a before ROI across "
                                  "both filament edges")
            radius_mm, radius_source = float(np.mean(contact)) * k_cal, \
                "measured contact radius"
        fil_x = config.rois.after.center[0]
        turn = (1.0 if fil_x >= cx else -1.0) * (1.0 if config.direction == "down" else -1.0)
        with np.errstate(invalid="ignore"):
            gear = turn * gear_step * radius_mm / gear_span
        gear_mode = "rotation"
    else:
        gear = speed_mm_s(gear_step, gear_span, k_cal)
        gear_mode = "tangential"
    fil = speed_mm_s(np.asarray(rows.fil), fil_span, k_cal)
    width_mm = width_px * k_cal
    stopped = np.isfinite(gear) & (np.abs(gear) <= p.min_gear_speed_mm_s)
    flags[stopped] |= int(Quality.GEAR_STOPPED)
    slip = slip_fraction(gear, fil, min_gear_speed_mm_s=p.min_gear_speed_mm_s)
    flow = volume_flow_mm3_s(fil, width_mm)
    g_s = gaussian_smooth(t, gear, p.smooth_sigma_s)
    f_s = gaussian_smooth(t, fil, p.smooth_sigma_s)
    w_s = gaussian_smooth(t, width_mm, p.smooth_sigma_s)
    series = VisionSeries(
        frame=np.asarray(rows.frame, dtype=np.int64), t_s=t, dt_s=dt,
        gear_speed_mm_s=gear, filament_speed_mm_s=fil, slip=slip, width_mm=width_mm,
        volume_flow_mm3_s=flow, gear_speed_smooth_mm_s=g_s, filament_speed_smooth_mm_s=f_s,
        slip_smooth=slip_fraction(g_s, f_s, min_gear_speed_mm_s=p.min_gear_speed_mm_s),
        width_smooth_mm=w_s, volume_flow_smooth_mm3_s=volume_flow_mm3_s(f_s, w_s),
        flags=flags, gear_tracks=np.asarray(rows.gear_n, dtype=np.int64),
        filament_tracks=np.asarray(rows.fil_n, dtype=np.int64),
        gear_se_px=np.asarray(rows.gear_se), filament_se_px=np.asarray(rows.fil_se),
        width_px=width_px)
    summary = _summary(series, config, info, gear_span=gear_span, fil_span=fil_span,
                       period=period, dropped=dropped, k_cal=k_cal,
                       scale_source=scale_source, gear_mode=gear_mode, radius_mm=radius_mm,
                       radius_source=radius_source, elapsed=elapsed)
    return VisionResult(series, summary)


def _summary(s: VisionSeries, config: VisionConfig, info: SourceInfo, *,
             gear_span: npt.NDArray[np.float64], fil_span: npt.NDArray[np.float64],
             period: float,
             dropped: int, k_cal: float, scale_source: str, gear_mode: str,
             radius_mm: float | None, radius_source: str | None, elapsed: float
             ) -> VisionSummary:
    fl = s.flags
    g_ok = ((fl & int(GEAR_INVALID)) == 0) & np.isfinite(s.gear_speed_mm_s)
    f_ok = ((fl & int(FILAMENT_INVALID)) == 0) & np.isfinite(s.filament_speed_mm_s)
    w_ok = ((fl & int(WIDTH_INVALIDATING)) == 0) & np.isfinite(s.width_mm)
    both = g_ok & f_ok
    g_dt = np.where(np.isfinite(gear_span), gear_span, 0.0)
    f_dt = np.where(np.isfinite(fil_span), fil_span, 0.0)

    def mean_speed(v: npt.NDArray[np.float64], ok: npt.NDArray[np.bool_],
                   dt: npt.NDArray[np.float64]) -> float:
        time_s = float(np.sum(dt[ok]))
        return float(np.sum(v[ok] * dt[ok]) / time_s) if time_s > 0 else NAN

    # slip over the run: distances where both speeds are valid and the gear turns,
    # counted along the gear's direction, so feeding and retracting both add up
    # (s = 1 − Σ sign(g)·v_fil·Δt / Σ |g|·Δt, [000 Eq. 1] for the whole run)
    moving = both & ((fl & int(Quality.GEAR_STOPPED)) == 0)
    g_dir = np.sign(s.gear_speed_mm_s[moving])
    l_gear = float(np.sum(np.abs(s.gear_speed_mm_s[moving]) * g_dt[moving]))
    l_fil = float(np.sum(g_dir * s.filament_speed_mm_s[moving] * f_dt[moving]))
    slip = 1.0 - l_fil / l_gear if l_gear > 0 else NAN
    flow_ok = f_ok & w_ok
    frames_expected = info.frames_expected
    n = len(s)
    return VisionSummary(
        gear_speed_mm_s=mean_speed(s.gear_speed_mm_s, g_ok, g_dt),
        filament_speed_mm_s=mean_speed(s.filament_speed_mm_s, f_ok, f_dt),
        slip=slip, slip_pct=100.0 * slip,
        width_mm=float(np.mean(s.width_mm[w_ok])) if w_ok.any() else NAN,
        width_std_mm=float(np.std(s.width_mm[w_ok])) if w_ok.any() else NAN,
        volume_flow_mm3_s=mean_speed(s.volume_flow_mm3_s, flow_ok, f_dt),
        frames=n, valid_frames=int(np.sum(both & w_ok)),
        gear_valid_frames=int(g_ok.sum()), filament_valid_frames=int(f_ok.sum()),
        width_valid_frames=int(w_ok.sum()), dropped_frames=dropped,
        gap_frames=int(np.sum((fl & int(Quality.GAP)) != 0)),
        duplicate_frames=int(np.sum((fl & int(Quality.DUPLICATE)) != 0)),
        blank_frames=int(np.sum((fl & int(Quality.BLANK)) != 0)),
        gear_low_texture_frames=int(np.sum((fl & int(Quality.GEAR_LOW_TEXTURE)) != 0)),
        filament_low_texture_frames=int(np.sum((fl & int(Quality.FILAMENT_LOW_TEXTURE)) != 0)),
        frames_expected=frames_expected,
        truncated=bool(frames_expected is not None and n < frames_expected),
        duration_s=float(s.t_s[-1] - s.t_s[0]), frame_period_s=period,
        mm_per_px=k_cal, scale_source=scale_source, gear_mode=gear_mode,
        gear_radius_mm=radius_mm, gear_radius_source=radius_source,
        source=info.description, source_kind=info.kind,
        timestamp_source=info.timestamp_source, opencv_version=cv2.__version__,
        processing_fps=n / elapsed if elapsed > 0 else NAN)


def measure(source: str | Path | int, config: VisionConfig, *,
            timestamps: str | Path | None = None, max_frames: int | None = None
            ) -> VisionResult:
    """Measure a video file, image folder or camera (see :func:`open_source`).

    Parameters
    ----------
    source
        Video file, image folder or camera index.
    config
        ROIs, scale, gear geometry and tracking parameters.
    timestamps
        Optional timestamp file (one ms value per frame).
    max_frames
        Stop after this many frames (required for a camera).

    Returns
    -------
    VisionResult

    Raises
    ------
    VisionError
        Bad source, ROI outside the frame, missing scale, bad timestamps.
    """
    with open_source(source, timestamps=timestamps, max_frames=max_frames) as src:
        info = SourceInfo(description=src.description, kind=src.kind,
                          timestamp_source=src.timestamp_source,
                          frames_expected=src.frames_expected)
        return measure_frames(src, config, frame_size=(src.width_px, src.height_px),
                              info=info)
