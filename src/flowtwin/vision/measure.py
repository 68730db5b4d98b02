"""The slip-camera pipeline: frames in, gear speed, filament speed, slip and width out.

Per frame (docs/spec.md §3.7, [003 §2.2]): skip blank frames and exact repeats, track the gear ROI
(rotation about the gear axis, or tangential motion) and the ``after`` ROI (translation
along the filament) with :class:`~flowtwin.vision.track.RoiTracker`, and measure the width
in the ``before`` ROI (:func:`~flowtwin.vision.width.measure_width_px`, refused when the
edges are ambiguous). When the gear axis is not given, the first ``axis_frames`` frames
are first used to estimate it from the tracked motion (:mod:`flowtwin.vision.axis`).
Speeds, slip, flags and the summary follow in :mod:`flowtwin.vision.summarize`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterable, Sequence
from itertools import chain, islice
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.errors import VisionError
from flowtwin.vision.axis import estimate_gear_axis
from flowtwin.vision.capture import INTER_FRAME_CODECS, Frame, open_source
from flowtwin.vision.clip_width import ClipWidth
from flowtwin.vision.config import VisionConfig
from flowtwin.vision.features import is_stale
from flowtwin.vision.readings import Quality, VisionResult
from flowtwin.vision.summarize import GearSetup, RowLog, SourceInfo, finish
from flowtwin.vision.track import RoiTracker, StepEstimate
from flowtwin.vision.width import EdgeMeasurement, expected_width_px

__all__ = ["Pipeline", "SourceInfo", "find_gear_axis", "measure", "measure_frames"]

NAN = math.nan


def _step_flags(est: StepEstimate | None, low: Quality, bad: Quality, stale: Quality
                ) -> Quality:
    if est is None or est.valid:
        return Quality(0)
    if est.stale:
        return stale
    return low if est.low_texture else bad


def _spread_dn(img: npt.NDArray[np.uint8]) -> float:
    """Standard deviation of every 4th pixel of every 4th row, DN (a blank frame's)."""
    return float(cv2.meanStdDev(np.ascontiguousarray(img[::4, ::4]))[1][0, 0])


def _step_tuple(est: StepEstimate | None) -> tuple[float, float, int, float] | None:
    return None if est is None else (est.value, est.span_s, est.n_tracks, est.se_px)


def find_gear_axis(frames: Sequence[Frame], config: VisionConfig,
                   frame_size: tuple[int, int], *, source: str = "<frames>") -> GearSetup:
    """Decide how the gear speed is measured: the given axis, an estimated one, or none.

    Parameters
    ----------
    frames
        The first frames of the recording (used only when the axis is not given).
    config
        ``gear_center_px`` and ``gear_method`` decide (see :class:`VisionConfig`).
    frame_size
        ``(width, height)`` of the frames, px.
    source
        Name for messages.

    Returns
    -------
    GearSetup
        The axis (``None``: tangential mode), its source and the estimate.

    Raises
    ------
    VisionError
        ``gear_method`` is ``"rotation"`` but the motion shows no rotation axis.
    """
    if config.gear_center_px is not None:
        return GearSetup(config.gear_center_px, "config", None)
    if config.gear_method == "tangential":
        return GearSetup(None, None, None)
    w, h = frame_size
    images = [f.image for f in frames if f.image.shape[:2] == (h, w)]
    est = estimate_gear_axis(images, config.rois.gear, config.tracking)
    if est.is_rotation:
        return GearSetup(est.center_px, "estimated from the motion", est)
    if config.gear_method == "rotation":
        raise VisionError(f"no gear axis could be estimated from the motion: {est.reason}",
                          source=source, field="gear.mode", value="rotation",
                          allowed="give --gear-center x,y, a gear ROI with texture that "
                          "turns within the first frames, or --gear-mode auto")
    return GearSetup(None, None, est)


class Pipeline:
    """The per-frame loop of a measurement; :meth:`result` finishes it.

    Parameters
    ----------
    config
        ROIs, scale, gear geometry and tracking parameters.
    frame_size
        ``(width, height)`` of the frames, px.
    gear
        How the gear speed is measured (:func:`find_gear_axis`).
    info
        Description of the source.

    Attributes
    ----------
    gear_tracker, filament_tracker
        The two trackers (their ``last_points`` / ``last_kept`` show the last step).
    last_width
        Width measurement of the last processed frame (None before the first; its
        status is ``"pending"`` once the clip's blur is fixed: fitted in :meth:`result`).
    """

    def __init__(self, config: VisionConfig, frame_size: tuple[int, int], gear: GearSetup,
                 info: SourceInfo | None = None) -> None:
        self.config = config
        self.info = info or SourceInfo()
        self.gear = gear
        self.frame_size = frame_size
        p = config.tracking
        sign = 1.0 if config.direction == "down" else -1.0
        # an inter-frame codec copies still blocks: repeated rows are not damage there
        check = self.info.codec not in INTER_FRAME_CODECS
        self.check_stale = check
        self.filament_tracker = RoiTracker(config.rois.after, frame_size, p,
                                           axis=(0.0, sign), inset_px=p.win_px // 2,
                                           check_stale=check)
        if gear.center_px is not None:
            self.gear_tracker = RoiTracker(config.rois.gear, frame_size, p, mode="rotation",
                                           center_px=gear.center_px, check_stale=check)
        else:
            self.gear_tracker = RoiTracker(config.rois.gear, frame_size, p, axis=(0.0, sign),
                                           check_stale=check)
        self.expected_px = expected_width_px(config.mm_per_px, config.diameter_mm)
        self.widths = ClipWidth(config.rois.before, self.expected_px, p.width_sigma_px,
                                p.min_edge_dn_px, codec=None if check else self.info.codec)
        self.rows = RowLog.empty()
        self.last_width: EdgeMeasurement | None = None
        self._prev: npt.NDArray[np.uint8] | None = None
        self._t_last: float | None = None
        self._t0: float | None = None

    def add(self, frame: Frame) -> None:
        """Process the next frame (capture order).

        Raises
        ------
        VisionError
            A frame of another size, or a capture time that does not increase.
        """
        p = self.config.tracking
        width_px, height_px = self.frame_size
        img = frame.image
        if img.shape[:2] != (height_px, width_px):
            raise VisionError("frame size differs from the declared size",
                              source=f"{self.info.description} frame {frame.index}",
                              value=f"{img.shape[1]}×{img.shape[0]}",
                              allowed=f"{width_px}×{height_px}")
        if self._t0 is None:
            self._t0 = frame.t_s
        t_rel = frame.t_s - self._t0
        no_width = (NAN, NAN, NAN)
        if _spread_dn(img) < p.blank_std_dn:
            self.rows.add(frame.index, t_rel, NAN, Quality.BLANK, None, None, no_width)
            return
        if (self._prev is not None and np.array_equal(img[::8, ::8], self._prev[::8, ::8])
                and np.array_equal(img, self._prev)):
            self.rows.add(frame.index, t_rel, NAN, Quality.DUPLICATE, None, None, no_width)
            return
        dt: float | None = None
        if self._t_last is not None:
            dt = frame.t_s - self._t_last
            if not dt > 0:
                raise VisionError("capture timestamps do not increase",
                                  source=f"{self.info.description} frame {frame.index}",
                                  value=f"{frame.t_s:.6f} s after {self._t_last:.6f} s",
                                  allowed="strictly increasing times (fix the timestamp "
                                  "file or give one)")
        g = self.gear_tracker.update(img, dt)
        f = self.filament_tracker.update(img, dt)
        before = self.config.rois.before
        before_crop = img[before.slices]
        em = self.widths.measure(before_crop)
        if em.lines is not None:
            self.widths.scan_frame(img)
        self.last_width = em
        flags = Quality.FIRST if dt is None else Quality(0)
        flags |= _step_flags(g, Quality.GEAR_LOW_TEXTURE, Quality.GEAR_TRACKING,
                             Quality.GEAR_STALE)
        flags |= _step_flags(f, Quality.FILAMENT_LOW_TEXTURE, Quality.FILAMENT_TRACKING,
                             Quality.FILAMENT_STALE)
        # a pending width (edges found, fit left to the end of the run) is provisionally
        # NaN without a flag; result() fits it or refuses it
        ok = em.ok or em.status == "pending"
        stale = False
        if not ok:
            flags |= Quality.WIDTH_INVALID
            if em.status == "ambiguous":
                flags |= Quality.WIDTH_AMBIGUOUS
        elif (self.check_stale and self._prev is not None
              and is_stale(before_crop, self._prev[before.slices])):
            flags |= Quality.WIDTH_INVALID
            ok, stale = False, True
        width = (em.width_px, em.left_px + before.x, em.right_px + before.x) if ok \
            else no_width
        self.rows.add(frame.index, t_rel, NAN if dt is None else dt, flags, _step_tuple(g),
                      _step_tuple(f), width)
        if not stale:
            self.widths.record(len(self.rows.t) - 1, em)
        self._prev = img
        self._t_last = frame.t_s

    def result(self, elapsed_s: float = NAN) -> VisionResult:
        """Speeds, slip, flags and summary of the frames so far.

        Raises
        ------
        VisionError
            No frames, or a scale / contact radius that needs edges never found.
        """
        if not self.rows.t:
            raise VisionError("the source delivered no frames", source=self.info.description)
        width_note = self.widths.finish(self.rows, self.gear.center_px, self.config.mm_per_px)
        return finish(self.rows, self.config, self.info, elapsed_s, self.gear,
                      width_note=width_note, blur_px=self.widths.blur_px,
                      width_window_frames=self.widths.window_frames)


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
        ROI outside the frame, no scale, timestamps that do not increase, no frames, a
        calibration width with no measurable filament edges, or rotation mode asked for
        without an axis given or found.
    """
    info = info or SourceInfo()
    if config.mm_per_px is None and config.calib_width_mm is None:
        raise VisionError("no image scale given", source=config.source, field="scale",
                          allowed="--mm-per-px K or --calib-width-mm W "
                          "(or [scale] in the config file)")
    width_px, height_px = frame_size
    config.rois.check_inside(width_px, height_px, source=config.source or info.description)
    started = time.perf_counter()
    stream = iter(frames)
    head: list[Frame] = []
    if config.gear_center_px is None and config.gear_method != "tangential":
        head = list(islice(stream, config.tracking.axis_frames))
    gear = find_gear_axis(head, config, frame_size, source=info.description)
    pipe = Pipeline(config, frame_size, gear, info)
    for frame in chain(head, stream):
        pipe.add(frame)
    return pipe.result(time.perf_counter() - started)


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
                          frames_expected=src.frames_expected, codec=src.codec)
        return measure_frames(src, config, frame_size=(src.width_px, src.height_px),
                              info=info)
