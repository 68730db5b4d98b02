"""Frames and their capture timestamps from a video file, a camera or an image folder.

Timestamps come from the capture, never from the CPU clock at processing time ([003
§2.1] used the CPU clock and an average period, which turns dropped frames into speed
errors):

* **video file** — the container's presentation time of each frame
  (``CAP_PROP_POS_MSEC``). If ``<video>.timestamps.txt`` exists beside the file (or a
  file is given explicitly) it overrides them: mkvmerge "timestamp format v2", one time
  in milliseconds per frame, ``#`` lines ignored. Use it for constant-rate containers
  that were filled from a camera with dropped frames.
* **image folder** — images (png, jpg, jpeg, bmp, tif, tiff, pgm, ppm) in natural name
  order; times from ``timestamps.txt`` in the folder (same format, one line per image)
  or else the files' modification times.
* **camera index** — the driver's buffer timestamp (``CAP_PROP_POS_MSEC``); a backend
  that gives none falls back to the host's monotonic clock at grab time, and the source
  says so in ``timestamp_source``.
"""

from __future__ import annotations

import math
import os
import re
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.errors import VisionError
from flowtwin.vision.loader import IMAGE_SUFFIXES, open_video, read_grey_image, to_grey_u8

__all__ = ["IMAGE_SUFFIXES", "INTER_FRAME_CODECS", "Frame", "FrameSource", "open_source",
           "read_timestamps_file"]

TIMESTAMPS_NAME = "timestamps.txt"
#: FOURCCs of codecs that predict frames from earlier ones (MPEG-4 part 2, H.264/5, VP8/9,
#: AV1, MPEG-1/2): they copy unchanged blocks, so a still region repeats its pixels
#: exactly and repeated rows are no sign of a damaged frame.
INTER_FRAME_CODECS = frozenset({
    "FMP4", "XVID", "DIVX", "DX50", "MP4V", "MP42", "MP43", "H264", "AVC1", "X264", "DAVC",
    "HEVC", "H265", "HVC1", "HEV1", "VP80", "VP90", "AV01", "MPG1", "MPG2", "PIM1", "WMV3",
    "WVC1", "THEO"})


@dataclass(frozen=True, slots=True)
class Frame:
    """One grey frame and its capture time.

    Attributes
    ----------
    index
        0-based position in the source.
    t_s
        Capture time, s (origin arbitrary).
    image
        Grey image, shape ``(H, W)``, uint8.
    """

    index: int
    t_s: float
    image: npt.NDArray[np.uint8]


def read_timestamps_file(path: str | Path) -> npt.NDArray[np.float64]:
    """Read a timestamp file (mkvmerge "timestamp format v2": one ms value per line).

    Parameters
    ----------
    path
        The file.

    Returns
    -------
    numpy.ndarray
        Times in seconds, strictly increasing, shape ``(N,)``.

    Raises
    ------
    VisionError
        Unreadable file, a line that is not a number, or times that do not increase.
    """
    src = str(path)
    try:
        lines = Path(path).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise VisionError(f"cannot read the timestamp file: {exc}", source=src) from None
    out: list[float] = []
    for number, line in enumerate(lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        try:
            value = float(text)
        except ValueError:
            raise VisionError("not a timestamp in milliseconds", source=src, line=number,
                              value=text,
                              allowed="one number (ms) per line, # comments") from None
        if not math.isfinite(value):
            raise VisionError("timestamp is not finite", source=src, line=number,
                              value=text, allowed="finite milliseconds")
        if out and value / 1000.0 <= out[-1]:
            raise VisionError("timestamps must increase strictly", source=src, line=number,
                              value=text, allowed=f"> {out[-1] * 1000.0:g} ms")
        out.append(value / 1000.0)
    if not out:
        raise VisionError("the timestamp file holds no timestamps", source=src,
                          allowed="one number (ms) per frame")
    return np.asarray(out, dtype=np.float64)


def _natural_key(path: Path) -> list[object]:
    return [int(tok) if tok.isdigit() else tok.lower() for tok in re.split(r"(\d+)", path.name)]


class FrameSource:
    """Iterable of :class:`Frame` from one source; use :func:`open_source`.

    Attributes
    ----------
    description
        What was opened (path or ``camera N``).
    kind
        ``"video"``, ``"images"`` or ``"camera"``.
    width_px, height_px
        Frame size, px.
    nominal_fps
        Frame rate the source declares, 1/s, or ``None``.
    frames_expected
        Frame count the container declares, or ``None``.
    timestamp_source
        Where the capture times come from.
    codec
        FOURCC of a video's codec, upper case (``None`` for images and cameras).
    frames_read
        Frames delivered so far.
    """

    def __init__(self, *, description: str, kind: str, first: npt.NDArray[np.uint8],
                 nominal_fps: float | None, frames_expected: int | None,
                 timestamp_source: str, max_frames: int | None) -> None:
        self.description = description
        self.kind = kind
        self.height_px, self.width_px = first.shape[:2]
        self.nominal_fps = nominal_fps
        self.frames_expected = frames_expected
        self.timestamp_source = timestamp_source
        self.max_frames = max_frames
        self.frames_read = 0
        self.codec: str | None = None
        self._first: npt.NDArray[np.uint8] | None = first

    def _check_size(self, image: npt.NDArray[np.uint8], where: str) -> None:
        if image.shape[:2] != (self.height_px, self.width_px):
            raise VisionError("frame size changed within the source", source=where,
                              value=f"{image.shape[1]}×{image.shape[0]}",
                              allowed=f"{self.width_px}×{self.height_px} like the first frame")

    def __iter__(self) -> Iterator[Frame]:
        raise NotImplementedError

    def close(self) -> None:
        """Release the underlying capture (idempotent)."""

    def __enter__(self) -> FrameSource:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class _VideoSource(FrameSource):
    def __init__(self, cap: cv2.VideoCapture, *, description: str, kind: str,
                 timestamps: npt.NDArray[np.float64] | None, ts_name: str | None,
                 max_frames: int | None) -> None:
        self._cap = cap
        ok, image = cap.read()
        if not ok or image is None:
            cap.release()
            raise VisionError("no frame could be decoded (corrupt, empty or not a video)",
                              source=description,
                              allowed="a video OpenCV/FFmpeg can decode (AVI, MKV, MP4, ...)")
        gray = to_grey_u8(image, source=description)
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if kind == "video" else 0
        self._timestamps = timestamps
        self._ts_name = ts_name
        self._host_clock = False
        first_ms = float(cap.get(cv2.CAP_PROP_POS_MSEC))
        if timestamps is not None:
            ts_source = f"timestamp file {ts_name}"
        elif kind == "video":
            ts_source = "container (CAP_PROP_POS_MSEC)"
        elif first_ms > 0:
            ts_source = "camera driver (CAP_PROP_POS_MSEC)"
        else:
            self._host_clock = True
            ts_source = "host monotonic clock at grab (camera gave no timestamps)"
        self._t0 = time.monotonic()
        self._first_t = self._time(0, first_ms)
        super().__init__(description=description, kind=kind, first=gray,
                         nominal_fps=fps if math.isfinite(fps) and fps > 0 else None,
                         frames_expected=count if count > 0 else None,
                         timestamp_source=ts_source, max_frames=max_frames)
        code = int(cap.get(cv2.CAP_PROP_FOURCC)) if kind == "video" else 0
        if code > 0:
            self.codec = "".join(chr((code >> (8 * i)) & 0xFF) for i in range(4)).upper()

    def _time(self, index: int, pos_ms: float) -> float:
        if self._timestamps is not None:
            if index >= self._timestamps.size:
                raise VisionError("the video has more frames than the timestamp file "
                                  "has lines", source=self._ts_name, value=index + 1,
                                  allowed=f"{self._timestamps.size} frames")
            return float(self._timestamps[index])
        if self._host_clock:
            return time.monotonic() - self._t0
        return pos_ms / 1000.0

    def __iter__(self) -> Iterator[Frame]:
        if self._first is None:
            raise VisionError("a frame source can be read only once", source=self.description)
        first, self._first = self._first, None
        self.frames_read = 1
        yield Frame(0, self._first_t, first)
        index = 1
        while self.max_frames is None or index < self.max_frames:
            ok, image = self._cap.read()
            if not ok or image is None:
                break
            pos_ms = float(self._cap.get(cv2.CAP_PROP_POS_MSEC))
            gray = to_grey_u8(image, source=f"{self.description} frame {index}")
            self._check_size(gray, f"{self.description} frame {index}")
            self.frames_read = index + 1
            yield Frame(index, self._time(index, pos_ms), gray)
            index += 1

    def close(self) -> None:
        self._cap.release()


class _ImageFolderSource(FrameSource):
    def __init__(self, folder: Path, *, timestamps: Path | None,
                 max_frames: int | None) -> None:
        files = sorted((p for p in folder.iterdir()
                        if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES), key=_natural_key)
        if not files:
            raise VisionError("the folder holds no images", source=str(folder),
                              allowed="files ending in " + ", ".join(IMAGE_SUFFIXES))
        if max_frames is not None:
            files = files[:max_frames]
        ts_path = timestamps if timestamps is not None else folder / TIMESTAMPS_NAME
        if ts_path.is_file():
            times = read_timestamps_file(ts_path)
            if times.size < len(files):
                raise VisionError("fewer timestamps than images", source=str(ts_path),
                                  value=int(times.size), allowed=f">= {len(files)} lines")
            self._times = times[:len(files)]
            ts_source = f"timestamp file {ts_path}"
        elif timestamps is not None:
            raise VisionError("timestamp file not found", source=str(timestamps))
        else:
            self._times = np.array([os.stat(p).st_mtime_ns * 1e-9 for p in files])
            ts_source = "file modification times"
            if np.any(np.diff(self._times) <= 0):
                bad = int(np.flatnonzero(np.diff(self._times) <= 0)[0]) + 1
                raise VisionError("image modification times do not increase in name order",
                                  source=str(files[bad]),
                                  allowed=f"increasing mtimes, or a {TIMESTAMPS_NAME} "
                                  "file with one time (ms) per image")
        self._files = files
        first = self._read(files[0])
        super().__init__(description=str(folder), kind="images", first=first,
                         nominal_fps=None, frames_expected=len(files),
                         timestamp_source=ts_source, max_frames=max_frames)

    @staticmethod
    def _read(path: Path) -> npt.NDArray[np.uint8]:
        return read_grey_image(path)

    def __iter__(self) -> Iterator[Frame]:
        if self._first is None:
            raise VisionError("a frame source can be read only once", source=self.description)
        first, self._first = self._first, None
        self.frames_read = 1
        yield Frame(0, float(self._times[0]), first)
        for index in range(1, len(self._files)):
            image = self._read(self._files[index])
            self._check_size(image, str(self._files[index]))
            self.frames_read = index + 1
            yield Frame(index, float(self._times[index]), image)


def open_source(source: str | Path | int, *, timestamps: str | Path | None = None,
                max_frames: int | None = None) -> FrameSource:
    """Open a video file, an image folder or a camera index.

    Parameters
    ----------
    source
        A path to a video file or an image folder, or a camera index (``int`` or a
        string of digits that is not an existing path).
    timestamps
        Timestamp file overriding the source's own times (see the module docstring).
    max_frames
        Stop after this many frames (required for a camera).

    Returns
    -------
    FrameSource
        Iterate it once for the frames; close it (or use ``with``) when done.

    Raises
    ------
    VisionError
        Missing path, unreadable or corrupt video, empty folder, camera that cannot be
        opened, bad timestamp file.
    """
    if max_frames is not None and max_frames < 1:
        raise VisionError("max_frames must be at least 1", field="max_frames",
                          value=max_frames, allowed=">= 1")
    ts_path = None if timestamps is None else Path(timestamps)
    if ts_path is not None and not ts_path.is_file():
        raise VisionError("timestamp file not found", source=str(ts_path))
    if isinstance(source, int) or (isinstance(source, str) and source.isdigit()
                                   and not Path(source).exists()):
        index = int(source)
        if max_frames is None:
            raise VisionError("a camera needs a frame limit", source=f"camera {index}",
                              field="max_frames", allowed="--frames N")
        cap = cv2.VideoCapture(index)
        if not cap.isOpened():
            raise VisionError("the camera could not be opened", source=f"camera {index}",
                              value=index, allowed="the index of a connected camera "
                              "(0 is usually the first)")
        times = None if ts_path is None else read_timestamps_file(ts_path)
        return _VideoSource(cap, description=f"camera {index}", kind="camera",
                            timestamps=times, ts_name=None if ts_path is None else str(ts_path),
                            max_frames=max_frames)
    path = Path(source)
    if not path.exists():
        raise VisionError("no such file or folder", source=str(path),
                          allowed="a video file, an image folder or a camera index")
    if path.is_dir():
        return _ImageFolderSource(path, timestamps=ts_path, max_frames=max_frames)
    sidecar = path.with_name(path.name + ".timestamps.txt")
    if ts_path is None and sidecar.is_file():
        ts_path = sidecar
    cap = open_video(path)
    times = None if ts_path is None else read_timestamps_file(ts_path)
    return _VideoSource(cap, description=str(path), kind="video", timestamps=times,
                        ts_name=None if ts_path is None else str(ts_path),
                        max_frames=max_frames)
