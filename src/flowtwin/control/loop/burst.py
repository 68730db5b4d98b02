"""One slip measurement from a short burst of frames, with the vision pipeline.

Shared by the camera, video and twin-camera sources: the frames go through
:func:`flowtwin.vision.measure_frames` (Shi–Tomasi + pyramidal Lucas–Kanade on the gear
and the filament, [003 §2.2]) and the burst's slip is ``1 − L_fil/L_gear`` over its steps
[000 Eq. 1]. A burst counts as a slip measurement only over steady forward feeding —
every step tracked and the gear turning forward in each — since [003 §3.3] reports slip
"only for periods of gear movement"; a burst whose gear is at rest is *idle* (the camera
works, the printer waits), anything else is invalid.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from flowtwin.control.loop.measurement import Measurement
from flowtwin.vision import Frame, VisionConfig, VisionResult, measure_frames

__all__ = ["IDLE_GEAR_SPEED_MM_S", "measure_burst", "measurement_from_result"]

#: Below this gear surface speed the drive counts as at rest, mm/s: 5 % of [003]'s 2 mm/s
#: set point, well above the tracking noise on a still image (a few 0.01 mm/s).
IDLE_GEAR_SPEED_MM_S = 0.1


def measurement_from_result(result: VisionResult, t_s: float, *,
                            idle_gear_speed_mm_s: float = IDLE_GEAR_SPEED_MM_S
                            ) -> Measurement:
    """Turn the vision result of a burst into one loop measurement.

    Parameters
    ----------
    result
        Vision result of the burst's frames.
    t_s
        Loop-clock time of the burst's last frame, s.
    idle_gear_speed_mm_s
        A gear whose measured speed stays below this (median of the steps' absolute
        speeds) is at rest, mm/s. Tracking noise on a still image reads a few 0.01 mm/s,
        so the vision's own ``min_gear_speed_mm_s`` is too fine for this decision.

    Returns
    -------
    Measurement
        Valid with the burst's slip when every step was tracked with the gear turning
        forward faster than ``idle_gear_speed_mm_s``; idle when the gear rests; otherwise
        invalid (a retraction, a restart, lost tracks).
    """
    series = result.series
    gear = series.gear_speed_mm_s[1:]
    fil = series.filament_speed_mm_s[1:]
    summ = result.summary
    g_mean = float(summ.gear_speed_mm_s)
    finite = np.isfinite(gear)
    if finite.any() and float(np.median(np.abs(gear[finite]))) <= idle_gear_speed_mm_s:
        return Measurement(t_s, math.nan, valid=False, idle=True, gear_speed_mm_s=g_mean)
    slip = float(summ.slip)
    ok = bool(gear.size > 0 and math.isfinite(slip) and np.all(finite)
              and np.all(np.isfinite(fil)) and np.all(gear > idle_gear_speed_mm_s))
    f_mean = float(summ.filament_speed_mm_s)
    return Measurement(t_s, slip if ok else math.nan,
                       filament_speed_mm_s=f_mean if math.isfinite(f_mean) else None,
                       valid=ok, gear_speed_mm_s=g_mean if math.isfinite(g_mean) else None)


def measure_burst(frames: Sequence[Frame], config: VisionConfig, *, t_s: float,
                  frame_size: tuple[int, int]) -> tuple[Measurement, VisionResult]:
    """Measure a burst of frames and make it a loop measurement.

    Parameters
    ----------
    frames
        At least two frames in capture order.
    config
        Vision configuration (ROIs, scale, gear geometry).
    t_s
        Loop-clock time of the last frame, s.
    frame_size
        ``(width, height)`` of the frames, px.

    Returns
    -------
    (Measurement, VisionResult)
    """
    result = measure_frames(frames, config, frame_size=frame_size)
    return measurement_from_result(result, t_s), result
