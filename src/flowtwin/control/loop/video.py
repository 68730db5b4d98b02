"""Camera and video measurement sources for the loop, on top of :mod:`flowtwin.vision`.

Both cut the frame stream into bursts of ``window_frames`` frames and measure the newest
complete burst with the vision pipeline (:func:`~flowtwin.control.loop.burst.measure_burst`):
one loop measurement per burst. When the loop polls often enough, consecutive bursts
share their boundary frame and no step is lost; when it falls behind, older bursts are
skipped (their measurement would be stale).

* :class:`VideoSource` replays a recorded video (or image folder) **on the loop's clock**:
  a frame becomes available when the loop's time since the first ``read()`` reaches its
  capture time (divided by ``speed``). Deterministic, no thread: with a
  :class:`~flowtwin.control.loop.clock.SimClock` a recording replays as fast as it can be
  measured. When the recording is used up, :attr:`VideoSource.finished` turns True and
  ``read()`` returns None (the CLI ends the run then).
* :class:`CameraSource` reads a live camera (an index, as :func:`flowtwin.vision.open_source`
  takes it — or any other source, e.g. a file, read as fast as it decodes) in a
  background thread, so ``read()`` never blocks; a frame's loop time is the loop clock at
  its arrival, its capture time (driver timestamp) sets the step ``Δt`` of the vision.
  A camera that fails or ends raises :class:`~flowtwin.control.loop.measurement.MeasurementLost`.
"""

from __future__ import annotations

import collections
import math
import threading
from collections.abc import Iterator
from pathlib import Path

from flowtwin.control.loop.burst import measure_burst
from flowtwin.control.loop.clock import Clock
from flowtwin.control.loop.measurement import Measurement, MeasurementLost
from flowtwin.errors import FlowtwinError, ProfileError
from flowtwin.vision import Frame, VisionConfig, open_source

__all__ = ["CameraSource", "VideoSource"]

#: Frames the camera thread keeps while the loop is busy (older frames are dropped).
_CAMERA_BUFFER = 256


def _check_window(window_frames: int) -> int:
    if window_frames < 2:
        raise ProfileError("a measurement needs at least two frames", field="window_frames",
                           value=window_frames, allowed=">= 2")
    return int(window_frames)


class VideoSource:
    """Replay a recording on the loop's clock and measure it burst by burst.

    Parameters
    ----------
    path
        Video file or image folder (see :func:`flowtwin.vision.open_source`).
    config
        Vision configuration (ROIs, scale, gear geometry).
    clock
        The loop's clock.
    window_frames
        Frames per measurement (>= 2).
    timestamps
        Timestamp file overriding the recording's own times.
    speed
        Replay speed (1 = as recorded).

    Raises
    ------
    VisionError
        The recording cannot be opened or decoded.
    """

    def __init__(self, path: str | Path, config: VisionConfig, clock: Clock, *,
                 window_frames: int = 8, timestamps: str | Path | None = None,
                 speed: float = 1.0) -> None:
        if not (math.isfinite(speed) and speed > 0.0):
            raise ProfileError("replay speed must be positive", field="speed", value=speed,
                               allowed="> 0")
        self.window_frames = _check_window(window_frames)
        self.config = config
        self.clock = clock
        self.speed = float(speed)
        self._src = open_source(str(path), timestamps=timestamps)
        self.description = self._src.description
        self._frames: Iterator[Frame] = iter(self._src)
        self._size = (self._src.width_px, self._src.height_px)
        self._pending: Frame | None = None
        self._buffer: collections.deque[Frame] = collections.deque(maxlen=self.window_frames)
        self._new = 0
        self._t0_clock: float | None = None
        self._t0_video: float | None = None
        self._exhausted = False
        #: Measurements delivered so far.
        self.measurements = 0

    @property
    def finished(self) -> bool:
        """True once every frame has been replayed and measured."""
        return self._exhausted and self._pending is None and \
            self._new < self.window_frames - 1

    def _next_frame(self) -> Frame | None:
        if self._pending is None and not self._exhausted:
            self._pending = next(self._frames, None)
            if self._pending is None:
                self._exhausted = True
        return self._pending

    def _loop_time(self, frame: Frame) -> float:
        assert self._t0_clock is not None and self._t0_video is not None
        return self._t0_clock + (frame.t_s - self._t0_video) / self.speed

    def read(self) -> Measurement | None:
        """The measurement of the newest complete burst that is due (None if none)."""
        now = self.clock.now()
        first = self._next_frame()
        if first is None:
            return None
        if self._t0_clock is None:
            self._t0_clock, self._t0_video = now, first.t_s
        while (frame := self._next_frame()) is not None and self._loop_time(frame) <= now:
            self._pending = None
            self._buffer.append(frame)
            self._new += 1
        if len(self._buffer) < self.window_frames or self._new < self.window_frames - 1:
            return None
        # only the newest burst: older complete bursts are stale by now
        self._new = 0
        self.measurements += 1
        last = self._buffer[-1]
        m, _ = measure_burst(list(self._buffer), self.config, t_s=self._loop_time(last),
                             frame_size=self._size)
        return m

    def close(self) -> None:
        """Release the video."""
        self._src.close()


class CameraSource:
    """A live camera read in a background thread, measured burst by burst.

    Parameters
    ----------
    source
        Camera index (or a video file / image folder read as fast as it decodes).
    config
        Vision configuration (ROIs, scale, gear geometry).
    clock
        The loop's clock (a frame's loop time is its arrival time).
    window_frames
        Frames per measurement (>= 2).
    max_frames
        Stop reading after this many frames (a camera needs a limit).

    Raises
    ------
    VisionError
        The camera cannot be opened.
    """

    def __init__(self, source: int | str | Path, config: VisionConfig, clock: Clock, *,
                 window_frames: int = 8, max_frames: int = 10**9) -> None:
        self.window_frames = _check_window(window_frames)
        self.config = config
        self.clock = clock
        src = source if isinstance(source, int) else str(source)
        self._src = open_source(src, max_frames=max_frames)
        self.description = self._src.description
        self._size = (self._src.width_px, self._src.height_px)
        self._lock = threading.Lock()
        self._arrived: collections.deque[tuple[float, Frame]] = collections.deque(
            maxlen=_CAMERA_BUFFER)
        self._stop = threading.Event()
        self._ended = False
        self._error: str | None = None
        self._buffer: collections.deque[tuple[float, Frame]] = collections.deque(
            maxlen=self.window_frames)
        self._new = 0
        self.measurements = 0
        self._thread = threading.Thread(target=self._pump, name="flowtwin-camera",
                                        daemon=True)
        self._thread.start()

    def _pump(self) -> None:
        try:
            for frame in self._src:
                t = self.clock.now()
                with self._lock:
                    self._arrived.append((t, frame))
                if self._stop.is_set():
                    break
        except FlowtwinError as exc:
            with self._lock:
                self._error = exc.message
        except Exception as exc:  # handed to the loop as a lost camera (read() raises)
            with self._lock:
                self._error = f"{type(exc).__name__}: {exc}"
        finally:
            with self._lock:
                self._ended = True

    def read(self) -> Measurement | None:
        """The measurement of the newest complete burst (None if none yet)."""
        with self._lock:
            arrived = list(self._arrived)
            self._arrived.clear()
            ended, error = self._ended, self._error
        out: Measurement | None = None
        self._buffer.extend(arrived)
        self._new += len(arrived)
        if len(self._buffer) == self.window_frames and self._new >= self.window_frames - 1:
            # only the newest burst: older complete bursts are stale by now
            out, _ = measure_burst([f for _, f in self._buffer], self.config,
                                   t_s=self._buffer[-1][0], frame_size=self._size)
            self.measurements += 1
            self._new = 0
        if out is None and ended:
            if error is not None:
                raise MeasurementLost(f"camera failed: {error}", source=self.description)
            raise MeasurementLost("the camera stream ended", source=self.description)
        return out

    def close(self) -> None:
        """Stop the thread and release the camera."""
        self._stop.set()
        self._thread.join(timeout=5.0)
        if not self._thread.is_alive():
            self._src.close()
