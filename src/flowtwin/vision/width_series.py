"""A frame's width from its neighbours: a local line through the clip's width series.

The filament's diameter changes slowly along it — a few hundredths of a millimetre over
centimetres to metres of filament — while the camera samples it every frame, and a
``before`` ROI already averages the width over its rows, a millimetre or more of
filament. Frames a few apart therefore see nearly the same stretch of filament, and
whatever makes their readings differ by more than the filament does is the camera's:
noise, the filament's moving texture and, under an inter-frame codec (MPEG-4 part 2,
H.264), the quantizer, which changes from frame to frame with the frame's place in its
group of pictures. On the independent renderer (``tests/vision/realcam.py``) the
frames whose widths were off by more than 0.5 px sat next to the encoder's key frames
and departed from the local trend of their ±6 neighbours by 0.19–0.41 px
(docs/vision.md, "Measured accuracy").

Each frame's width is therefore the value at that frame of the least-squares line
through the widths of up to :data:`WINDOW_FRAMES` frames centred on it (the window is
shifted inwards at the clip's ends, and refused frames are left out of it). A line, not
a mean, so that a diameter that changes steadily is followed without lag; the full
window spans a group of pictures of the common MPEG-4 settings (12 frames), so that the
quantizer's cycle averages out. The window spans no more filament travel than the
ROI's height at the clip's fast speed (the 95th percentile of the measured steps,
:func:`neighbour_frames`): at 15 mm/s through a 100-row ROI at 20 µm/px it is 5 frames.
A clip mostly still with a few fast moves, or whose fast steps were not tracked, gets a
longer window over those moves. The bias a full window leaves on a diameter varying
as a sine of period ``P`` frames is ``1 − (1/L)·Σ cos(2πk/P)``, about
``(2π/P)² · 14 / 2`` of the amplitude: 0.08 of it at ``P`` = 60 frames (renderer 2: a
6 mm wave at 3 mm/s), 0.007 at 200.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

__all__ = ["MIN_FRAMES", "WINDOW_FRAMES", "local_line", "neighbour_frames"]

#: Frames in the window whose line gives a frame's width (odd: the frame and 6 each side).
WINDOW_FRAMES = 13
#: Fewest measured frames in a window for its line to replace the frame's own reading.
MIN_FRAMES = 3


def local_line(values: npt.ArrayLike, window: int = WINDOW_FRAMES,
               min_frames: int = MIN_FRAMES) -> npt.NDArray[np.float64]:
    """Each finite value replaced by the least-squares line through its window, at it.

    Parameters
    ----------
    values
        A series, one value per frame, shape ``(n,)``; NaN marks a frame without one.
    window
        Frames in the window (odd, ≥ 3), centred on the frame and shifted inwards at
        the series' ends so that it keeps its length where the series is long enough.
    min_frames
        Fewest finite values in a window for its line to be used; a frame whose window
        has fewer keeps its own value.

    Returns
    -------
    numpy.ndarray
        Shape ``(n,)``, float64: NaN where ``values`` is NaN, the local line elsewhere.
    """
    if window < 3 or window % 2 == 0:
        raise ValueError(f"window must be odd and at least 3 frames, got {window}")
    y = np.asarray(values, dtype=np.float64)
    n = y.size
    out = y.copy()
    if n < 2:
        return out
    span = min(window, n)
    start = np.clip(np.arange(n) - window // 2, 0, n - span)
    idx = start[:, None] + np.arange(span)[None, :]          # (n, span)
    x = (idx - np.arange(n)[:, None]).astype(np.float64)     # offsets from the frame
    w = y[idx]
    m = np.isfinite(w)
    w = np.where(m, w, 0.0)
    x = np.where(m, x, 0.0)
    s0 = m.sum(axis=1).astype(np.float64)
    s1 = x.sum(axis=1)
    s2 = (x * x).sum(axis=1)
    t0 = w.sum(axis=1)
    t1 = (x * w).sum(axis=1)
    det = s0 * s2 - s1 * s1
    use = np.isfinite(y) & (s0 >= min_frames) & (det > 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = (s0 * t1 - s1 * t0) / det
        at_frame = (t0 - slope * s1) / s0                     # the line at offset 0
    out[use] = at_frame[use]
    return out


def neighbour_frames(t_s: Sequence[float], step_px: Sequence[float],
                     span_s: Sequence[float], reach_px: float,
                     most: int = WINDOW_FRAMES) -> int:
    """Frames in the window of :func:`local_line` for a filament that moves.

    The window's frames must see nearly the same stretch of filament: it spans no more
    than ``reach_px`` of travel (a ``before`` ROI's height, the length its width is
    already an average over) at the clip's fast speed, the 95th percentile of the
    filament's measured speed (steps not measured do not count; nor do the few fastest).

    Parameters
    ----------
    t_s
        The frames' capture times, s, shape ``(n,)``.
    step_px
        The filament's step between frames, px, shape ``(n,)`` (NaN where none was
        measured).
    span_s
        The time each step spans, s, shape ``(n,)``.
    reach_px
        Greatest travel over the window, px.
    most
        Most frames in the window (odd).

    Returns
    -------
    int
        An odd number of frames, 1 to ``most``; 1 (no window) when the filament's speed
        was not measured or the frames have no valid capture interval.
    """
    step = np.abs(np.asarray(step_px, dtype=np.float64))
    span = np.asarray(span_s, dtype=np.float64)
    t = np.asarray(t_s, dtype=np.float64)
    ok = np.isfinite(step) & np.isfinite(span) & (span > 0.0)
    intervals = np.diff(t)
    intervals = intervals[np.isfinite(intervals) & (intervals > 0.0)]
    if not ok.any() or intervals.size == 0:
        return 1
    period = float(np.median(intervals))
    per_frame = float(np.percentile(step[ok] / span[ok], 95)) * period
    frames = most if per_frame <= reach_px / (most - 1) else int(reach_px // per_frame) + 1
    frames = min(frames, most)
    return frames if frames % 2 else frames - 1
