"""From per-frame steps to speeds, slip, width, flags, summary and warnings.

The second half of the pipeline (:mod:`flowtwin.vision.measure` is the first): the scale
(known, or ``k_cal = w_µ/w_detected`` [003 Eq. 4]), speeds ``v = k_cal·S/Δt`` with each
step's own capture-time ``Δt`` [003 Eq. 5], gear surface speed ``ω·R`` [003 Eq. 3] in
rotation mode, slip [000 Eq. 1] only where both speeds are above their floors, volume
flow, Gaussian smoothing in time, gaps from the timestamps, and a summary built from
travelled distances (uneven steps weigh by their duration).

**Motion sanity.** A step whose speed, or whose Gaussian-smoothed speed (the
``smooth_sigma_s`` window around it), is not above its floor (``min_gear_speed_mm_s``,
``min_filament_speed_mm_s``) is a *still* reading: the row is flagged GEAR_STOPPED or
FILAMENT_STOPPED and has no slip (a single noisy step of a still drive can pass the
floor, its neighbourhood does not). The run's slip needs at least
:data:`~flowtwin.vision.readings.MIN_SLIP_STEPS` steps with both speeds valid and above
their floors, *and* both mean speeds above their floors; otherwise it is undefined (NaN,
``null`` in JSON) and ``slip_note`` says why — a still drive never reads as a slip
percentage.

**No axis, no gear speed.** When the gear turns but no axis was given and none could be
estimated from the motion (``--gear-mode auto``), the tangential reading that remains is
``ω`` times the lever arm of whatever features were tracked, not the drive's surface
speed: the gear speed and the slip are refused (GEAR_NO_AXIS, ``gear_note``), not
reported with a warning. ``--gear-mode tangential`` asks for [003]'s method explicitly.

**Warnings.** A quantity valid in fewer than ``min_valid_fraction`` of its steps, a slip
from few steps, a refused gear speed or width, and tangential mode on a turning gear are
listed in ``VisionSummary.warnings`` (the CLI prints them and fails with ``--strict``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.errors import VisionError
from flowtwin.vision.axis import AxisEstimate
from flowtwin.vision.config import VisionConfig
from flowtwin.vision.flow import gaussian_smooth, slip_fraction, speed_mm_s, volume_flow_mm3_s
from flowtwin.vision.readings import (
    FILAMENT_INVALID,
    GEAR_INVALID,
    MIN_SLIP_STEPS,
    WIDTH_INVALIDATING,
    Quality,
    VisionResult,
    VisionSeries,
    VisionSummary,
)
from flowtwin.vision.width import calibration_factor

__all__ = ["GearSetup", "RowLog", "SourceInfo", "finish"]

NAN = math.nan
F64 = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class SourceInfo:
    """Description of where frames came from (for the summary and messages)."""

    description: str = "<frames>"
    kind: str = "frames"
    timestamp_source: str = "given"
    frames_expected: int | None = None
    codec: str | None = None


@dataclass(frozen=True, slots=True)
class GearSetup:
    """How the gear speed was measured: the axis (if any) and where it came from."""

    center_px: tuple[float, float] | None
    source: str | None
    estimate: AxisEstimate | None


@dataclass(slots=True)
class RowLog:
    """Per-frame raw results collected by the pipeline loop (lists, one item per row)."""

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
    def empty(cls) -> RowLog:
        """No rows yet."""
        return cls([], [], [], [], [], [], [], [], [], [], [], [], [], [], [])

    def add(self, frame: int, t: float, dt: float, flags: Quality,
            gear: tuple[float, float, int, float] | None,
            fil: tuple[float, float, int, float] | None,
            width: tuple[float, float, float]) -> None:
        """One row: steps as ``(value, span_s, n_tracks, se_px)``, width as
        ``(width_px, left_px, right_px)`` in frame columns."""
        self.frame.append(frame)
        self.t.append(t)
        self.dt.append(dt)
        self.flags.append(int(flags))
        for est, value, span, n, se in ((gear, self.gear, self.gear_span, self.gear_n,
                                         self.gear_se),
                                        (fil, self.fil, self.fil_span, self.fil_n,
                                         self.fil_se)):
            value.append(est[0] if est is not None else NAN)
            span.append(est[1] if est is not None else NAN)
            n.append(est[2] if est is not None else 0)
            se.append(est[3] if est is not None else NAN)
        self.width.append(width[0])
        self.left.append(width[1])
        self.right.append(width[2])


def _gear_speed(rows: RowLog, config: VisionConfig, gear: GearSetup, k_cal: float,
                w_ok: npt.NDArray[np.bool_], source: str
                ) -> tuple[F64, str, float | None, str | None]:
    """Gear surface speed per row, the mode, and the drive radius used."""
    step = np.asarray(rows.gear)
    span = np.asarray(rows.gear_span)
    if gear.center_px is None:
        return speed_mm_s(step, span, k_cal), "tangential", None, None
    cx = gear.center_px[0]
    if config.gear_radius_mm is not None:
        radius_mm, radius_source = config.gear_radius_mm, "config"
    else:
        left, right = np.asarray(rows.left), np.asarray(rows.right)
        contact = np.minimum(np.abs(left - cx), np.abs(right - cx))[w_ok]
        if contact.size == 0:
            raise VisionError("cannot measure the gear radius: the filament edges were "
                              "not found", source=source, field="gear.radius_mm",
                              allowed="give --gear-radius-mm, or a before ROI across "
                              "both filament edges")
        radius_mm, radius_source = float(np.mean(contact)) * k_cal, "measured contact radius"
    fil_x = config.rois.after.center[0]
    turn = (1.0 if fil_x >= cx else -1.0) * (1.0 if config.direction == "down" else -1.0)
    with np.errstate(invalid="ignore"):
        speed = turn * step * radius_mm / span
    return speed, "rotation", radius_mm, radius_source


def finish(rows: RowLog, config: VisionConfig, info: SourceInfo, elapsed_s: float,
           gear: GearSetup, *, width_note: str | None = None, blur_px: float | None = None,
           width_window_frames: int = 1) -> VisionResult:
    """Turn the rows of the pipeline loop into a :class:`VisionResult`.

    Parameters
    ----------
    rows
        Raw per-frame results.
    config
        The measurement's configuration.
    info
        Where the frames came from.
    elapsed_s
        Processing time of the loop, s.
    gear
        Gear axis used (and how it was found).
    width_note
        Why every width of the clip was refused (:mod:`flowtwin.vision.clip_width`).
    blur_px
        The clip's edge blur, px (None if no edges were found).
    width_window_frames
        Frames in the local line each width was taken from (1: none).

    Returns
    -------
    VisionResult

    Raises
    ------
    VisionError
        A calibration width or a contact radius with no filament edges to measure.
    """
    p = config.tracking
    where = config.source or info.description
    t = np.asarray(rows.t)
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
                              "in any frame", source=where, field="roi.before",
                              value=config.rois.before.text(),
                              allowed="a before ROI across both filament edges")
        k_cal = calibration_factor(config.calib_width_mm, float(np.mean(width_px[w_ok])))
        scale_source = "calib_width_mm"
    gear_v, gear_mode, radius_mm, radius_source = _gear_speed(rows, config, gear, k_cal,
                                                              w_ok, where)
    fil_v = speed_mm_s(np.asarray(rows.fil), np.asarray(rows.fil_span), k_cal)
    floors = (p.min_gear_speed_mm_s, p.min_filament_speed_mm_s)
    gear_note = _refuse_tangential_fallback(gear_v, np.asarray(rows.gear_span), flags,
                                            config, gear, floors[0])
    g_s = gaussian_smooth(t, gear_v, p.smooth_sigma_s)
    f_s = gaussian_smooth(t, fil_v, p.smooth_sigma_s)
    # still: the step, or the speed around it (the Gaussian window), at or below the floor
    # (one noisy step of a still drive can pass the floor; its neighbourhood does not)
    g_still = np.isfinite(gear_v) & ((np.abs(gear_v) <= floors[0])
                                     | (np.abs(np.nan_to_num(g_s, nan=np.inf)) <= floors[0]))
    f_still = np.isfinite(fil_v) & ((np.abs(fil_v) < floors[1])
                                    | (np.abs(np.nan_to_num(f_s, nan=np.inf)) < floors[1]))
    flags[g_still] |= int(Quality.GEAR_STOPPED)
    flags[f_still] |= int(Quality.FILAMENT_STOPPED)
    slip = slip_fraction(gear_v, fil_v, min_gear_speed_mm_s=floors[0],
                         min_filament_speed_mm_s=floors[1])
    slip[g_still | f_still] = NAN
    width_mm = width_px * k_cal
    w_s = gaussian_smooth(t, width_mm, p.smooth_sigma_s)
    series = VisionSeries(
        frame=np.asarray(rows.frame, dtype=np.int64), t_s=t, dt_s=np.asarray(rows.dt),
        gear_speed_mm_s=gear_v, filament_speed_mm_s=fil_v, slip=slip, width_mm=width_mm,
        volume_flow_mm3_s=volume_flow_mm3_s(fil_v, width_mm),
        gear_speed_smooth_mm_s=g_s, filament_speed_smooth_mm_s=f_s,
        slip_smooth=slip_fraction(g_s, f_s, min_gear_speed_mm_s=floors[0],
                                  min_filament_speed_mm_s=floors[1]),
        width_smooth_mm=w_s, volume_flow_smooth_mm3_s=volume_flow_mm3_s(f_s, w_s),
        flags=flags, gear_tracks=np.asarray(rows.gear_n, dtype=np.int64),
        filament_tracks=np.asarray(rows.fil_n, dtype=np.int64),
        gear_se_px=np.asarray(rows.gear_se), filament_se_px=np.asarray(rows.fil_se),
        width_px=width_px)
    summary = _summary(series, config, info, gear, gear_span=np.asarray(rows.gear_span),
                       fil_span=np.asarray(rows.fil_span), period=period, dropped=dropped,
                       k_cal=k_cal, scale_source=scale_source, gear_mode=gear_mode,
                       radius_mm=radius_mm, radius_source=radius_source, elapsed_s=elapsed_s,
                       width_note=width_note, blur_px=blur_px, gear_note=gear_note,
                       width_window_frames=width_window_frames)
    return VisionResult(series, summary)


def _refuse_tangential_fallback(gear_v: F64, span: F64, flags: npt.NDArray[np.int64],
                                config: VisionConfig, gear: GearSetup, floor: float
                                ) -> str | None:
    """Refuse the gear speed (in place) when the gear turns and tangential mode was only
    the fallback of a failed axis estimate; returns why (None when not refused).

    The tangential method of [003] reads the mean motion of the gear ROI's features
    along the filament: ``ω`` times their lever arm, not the drive radius (16 % slow in a
    ROI next to the contact, −64 pp of slip on a 40×40 box on the teeth, docs). Asked for
    explicitly (``--gear-mode tangential``) it is reported, with a warning.
    """
    if gear.center_px is not None or config.gear_method != "auto":
        return None
    ok = np.isfinite(gear_v) & np.isfinite(span) & (span > 0)
    time_s = float(np.sum(span[ok]))
    if time_s <= 0 or abs(float(np.sum(gear_v[ok] * span[ok])) / time_s) <= floor:
        return None
    flags[np.isfinite(gear_v)] |= int(Quality.GEAR_NO_AXIS)
    gear_v[:] = NAN
    why = "" if gear.estimate is None else f" ({gear.estimate.reason})"
    return ("the gear turns but no gear axis was found" + why + "; the tangential reading "
            "left reads the lever arm of the tracked features, not the drive radius, so "
            "the gear speed and the slip are not reported: give --gear-center x,y, a gear "
            "ROI whose motion shows the rotation (its face, or a wide strip of the rim), "
            "or --gear-mode tangential to accept [003]'s method")


def _state(speed: float, n_valid: int, floor: float) -> str:
    if n_valid == 0 or not math.isfinite(speed):
        return "unknown"
    return "moving" if abs(speed) > floor else "still"


def _slip_note(gear_state: str, fil_state: str, g: float, f: float, steps: int,
               floors: tuple[float, float]) -> str | None:
    """Why the run's slip is undefined (None if it is defined)."""
    if gear_state == "unknown" or fil_state == "unknown":
        which = " and ".join(n for n, s in (("gear", gear_state), ("filament", fil_state))
                             if s == "unknown")
        return f"no valid {which} speed"
    if gear_state == "still" and fil_state == "still":
        return (f"gear and filament still (|{g:.4f}| <= {floors[0]:g} and |{f:.4f}| < "
                f"{floors[1]:g} mm/s): no slip to measure")
    if gear_state == "still":
        return (f"gear still (|{g:.4f}| <= {floors[0]:g} mm/s) while the filament moves "
                f"({f:.4f} mm/s): check the gear ROI")
    if fil_state == "still":
        return (f"filament still (|{f:.4f}| < {floors[1]:g} mm/s) while the gear turns "
                f"({g:.4f} mm/s): a stall; slip needs both speeds above their floors")
    if steps < MIN_SLIP_STEPS:
        return (f"only {steps} steps with both speeds valid and above their floors "
                f"(at least {MIN_SLIP_STEPS} needed)")
    return None


def _summary(s: VisionSeries, config: VisionConfig, info: SourceInfo, gear: GearSetup, *,
             gear_span: F64, fil_span: F64, period: float, dropped: int, k_cal: float,
             scale_source: str, gear_mode: str, radius_mm: float | None,
             radius_source: str | None, elapsed_s: float, width_note: str | None,
             blur_px: float | None, gear_note: str | None,
             width_window_frames: int) -> VisionSummary:
    p = config.tracking
    fl = s.flags
    g_ok = ((fl & int(GEAR_INVALID)) == 0) & np.isfinite(s.gear_speed_mm_s)
    f_ok = ((fl & int(FILAMENT_INVALID)) == 0) & np.isfinite(s.filament_speed_mm_s)
    w_ok = ((fl & int(WIDTH_INVALIDATING)) == 0) & np.isfinite(s.width_mm)
    both = g_ok & f_ok
    g_dt = np.where(np.isfinite(gear_span), gear_span, 0.0)
    f_dt = np.where(np.isfinite(fil_span), fil_span, 0.0)

    def mean_speed(v: F64, ok: npt.NDArray[np.bool_], dt: F64) -> float:
        time_s = float(np.sum(dt[ok]))
        return float(np.sum(v[ok] * dt[ok]) / time_s) if time_s > 0 else NAN

    floors = (p.min_gear_speed_mm_s, p.min_filament_speed_mm_s)
    g_mean = mean_speed(s.gear_speed_mm_s, g_ok, g_dt)
    f_mean = mean_speed(s.filament_speed_mm_s, f_ok, f_dt)
    gear_state = "moving" if gear_note else _state(g_mean, int(g_ok.sum()), floors[0])
    fil_state = _state(f_mean, int(f_ok.sum()), floors[1])
    # slip over the run: distances where both speeds are valid and above their floors,
    # counted along the gear's direction, so feeding and retracting both add up
    # (s = 1 − Σ sign(g)·v_fil·Δt / Σ |g|·Δt, [000 Eq. 1] for the whole run)
    stopped = int(Quality.GEAR_STOPPED | Quality.FILAMENT_STOPPED)
    moving = both & ((fl & stopped) == 0)
    steps = int(moving.sum())
    note = gear_note or _slip_note(gear_state, fil_state, g_mean, f_mean, steps, floors)
    g_dir = np.sign(s.gear_speed_mm_s[moving])
    l_gear = float(np.sum(np.abs(s.gear_speed_mm_s[moving]) * g_dt[moving]))
    l_fil = float(np.sum(g_dir * s.filament_speed_mm_s[moving] * f_dt[moving]))
    slip = 1.0 - l_fil / l_gear if note is None and l_gear > 0 else NAN
    n = len(s)
    skipped = (fl & int(Quality.BLANK | Quality.DUPLICATE)) != 0
    n_frames = int(np.sum(~skipped))
    n_steps = max(n_frames - 1, 0)
    warnings = _warnings(s, config, gear, gear_mode=gear_mode, gear_state=gear_state,
                         g_ok=g_ok, f_ok=f_ok, w_ok=w_ok, n_steps=n_steps,
                         n_frames=n_frames, slip_steps=steps, slip=slip,
                         width_note=width_note, gear_note=gear_note)
    frames_expected = info.frames_expected
    return VisionSummary(
        gear_speed_mm_s=g_mean, filament_speed_mm_s=f_mean, slip=slip, slip_pct=100.0 * slip,
        width_mm=float(np.mean(s.width_mm[w_ok])) if w_ok.any() else NAN,
        width_std_mm=float(np.std(s.width_mm[w_ok])) if w_ok.any() else NAN,
        volume_flow_mm3_s=mean_speed(s.volume_flow_mm3_s, f_ok & w_ok, f_dt),
        frames=n, valid_frames=int(np.sum(both & w_ok)),
        gear_valid_frames=int(g_ok.sum()), filament_valid_frames=int(f_ok.sum()),
        width_valid_frames=int(w_ok.sum()), dropped_frames=dropped,
        gap_frames=int(np.sum((fl & int(Quality.GAP)) != 0)),
        duplicate_frames=int(np.sum((fl & int(Quality.DUPLICATE)) != 0)),
        blank_frames=int(np.sum((fl & int(Quality.BLANK)) != 0)),
        gear_low_texture_frames=int(np.sum((fl & int(Quality.GEAR_LOW_TEXTURE)) != 0)),
        filament_low_texture_frames=int(np.sum((fl & int(Quality.FILAMENT_LOW_TEXTURE)) != 0)),
        width_ambiguous_frames=int(np.sum((fl & int(Quality.WIDTH_AMBIGUOUS)) != 0)),
        frames_expected=frames_expected,
        truncated=bool(frames_expected is not None and n < frames_expected),
        duration_s=float(s.t_s[-1] - s.t_s[0]), frame_period_s=period,
        mm_per_px=k_cal, scale_source=scale_source, gear_mode=gear_mode,
        gear_radius_mm=radius_mm, gear_radius_source=radius_source,
        gear_axis_px=gear.center_px, gear_axis_source=gear.source,
        gear_axis_note=None if gear.estimate is None else gear.estimate.reason,
        slip_steps=steps, slip_note=note, gear_state=gear_state, filament_state=fil_state,
        gear_speed_floor_mm_s=floors[0], filament_speed_floor_mm_s=floors[1],
        warnings=tuple(warnings),
        source=info.description, source_kind=info.kind,
        timestamp_source=info.timestamp_source, opencv_version=cv2.__version__,
        processing_fps=n / elapsed_s if elapsed_s > 0 else NAN,
        width_note=width_note, width_blur_px=NAN if blur_px is None else blur_px,
        gear_note=gear_note, width_window_frames=width_window_frames)


def _count(fl: npt.NDArray[np.int64], flag: Quality) -> int:
    return int(np.sum((fl & int(flag)) != 0))


def _warnings(s: VisionSeries, config: VisionConfig, gear: GearSetup, *, gear_mode: str,
              gear_state: str, g_ok: npt.NDArray[np.bool_], f_ok: npt.NDArray[np.bool_],
              w_ok: npt.NDArray[np.bool_], n_steps: int, n_frames: int, slip_steps: int,
              slip: float, width_note: str | None, gear_note: str | None) -> list[str]:
    """What a user must not miss (see the module docstring)."""
    frac = config.tracking.min_valid_fraction
    fl = s.flags
    out: list[str] = [f"gear speed and slip refused: {gear_note}"] if gear_note else []
    for name, ok, low, bad, stale in (
            ("gear speed", g_ok, Quality.GEAR_LOW_TEXTURE, Quality.GEAR_TRACKING,
             Quality.GEAR_STALE),
            ("filament speed", f_ok, Quality.FILAMENT_LOW_TEXTURE, Quality.FILAMENT_TRACKING,
             Quality.FILAMENT_STALE)):
        if n_steps and int(ok.sum()) < frac * n_steps and not (gear_note and ok is g_ok):
            out.append(f"{name} valid in only {int(ok.sum())} of {n_steps} steps "
                       f"({100.0 * ok.sum() / n_steps:.0f} %): {_count(fl, low)} without "
                       f"texture, {_count(fl, bad)} with too few or disagreeing tracks, "
                       f"{_count(fl, stale)} stale")
    if width_note is not None:
        out.append(f"width refused in every frame: {width_note}")
    elif n_frames and int(w_ok.sum()) < frac * n_frames:
        out.append(f"width valid in only {int(w_ok.sum())} of {n_frames} frames "
                   f"({_count(fl, Quality.WIDTH_AMBIGUOUS)} refused as ambiguous, the others "
                   "without a plausible pair of filament edges)")
    if math.isfinite(slip) and n_steps and slip_steps < frac * n_steps:
        out.append(f"slip from only {slip_steps} of {n_steps} steps")
    if gear_mode == "tangential" and gear_state == "moving" and not gear_note:
        why = "" if gear.estimate is None else f" ({gear.estimate.reason})"
        out.append("gear speed in tangential mode: it reads the lever arm of the tracked "
                   f"features, not the drive radius{why}; give --gear-center x,y or a "
                   "gear ROI whose motion shows the rotation")
    return out
