"""Write synthetic recordings as real files: videos, image folders, timestamps, config.

The files go through the same readers users' recordings do (:mod:`flowtwin.vision.capture`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Literal

import cv2
import numpy as np
import tomli_w

from flowtwin.atomic import atomic_write_bytes, atomic_write_text
from flowtwin.errors import VisionError
from flowtwin.vision.capture import TIMESTAMPS_NAME
from flowtwin.vision.config import VisionConfig
from flowtwin.vision.synth.render import SyntheticFrame

__all__ = ["timestamps_text", "write_config_toml", "write_image_folder", "write_video"]


def _fourcc(code: str) -> int:
    if len(code) != 4:
        raise VisionError("a codec FOURCC has four characters", field="fourcc", value=code,
                          allowed="e.g. FFV1, MJPG")
    return int(cv2.VideoWriter.fourcc(*code))


def timestamps_text(times_s: Sequence[float]) -> str:
    """Timestamps as mkvmerge "timestamp format v2" text (one ms value per line)."""
    return "# timestamp format v2\n" + "".join(f"{t * 1000.0:.6f}\n" for t in times_s)


def write_video(frames: Iterable[SyntheticFrame], path: str | Path, *, fps: float,
                fourcc: str = "FFV1",
                timestamps: Literal["auto", "always", "never"] = "auto") -> Path:
    """Write frames to a video with ``cv2.VideoWriter`` (constant frame rate).

    A constant-rate container cannot hold dropped frames or jitter, so with
    ``timestamps="auto"`` a ``<video>.timestamps.txt`` file is written beside the video
    whenever the capture times are not exactly ``index/fps``.

    Parameters
    ----------
    frames
        Frames in order.
    path
        Video file (``.avi``, ``.mkv``, ...).
    fps
        Frame rate stored in the container, 1/s.
    fourcc
        Codec: ``"FFV1"`` (lossless), ``"MJPG"``, ...
    timestamps
        Whether to write the timestamp file.

    Returns
    -------
    pathlib.Path
        The video path.

    Raises
    ------
    VisionError
        If OpenCV cannot open a writer for that codec and container.
    """
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    writer: cv2.VideoWriter | None = None
    times: list[float] = []
    uniform = True
    try:
        for k, fr in enumerate(frames):
            if writer is None:
                h, w = fr.image.shape[:2]
                writer = cv2.VideoWriter(str(out), _fourcc(fourcc), fps,
                                         (w, h), False)
                if not writer.isOpened():
                    raise VisionError("OpenCV cannot write this codec/container",
                                      source=str(out), value=fourcc,
                                      allowed="e.g. FFV1 or MJPG in .avi/.mkv")
            writer.write(np.ascontiguousarray(fr.image))
            times.append(fr.t_s)
            uniform &= math.isclose(fr.t_s, k / fps, abs_tol=1e-9)
    finally:
        if writer is not None:
            writer.release()
    if writer is None:
        raise VisionError("no frames to write", source=str(out))
    sidecar = out.with_name(out.name + ".timestamps.txt")
    if timestamps == "always" or (timestamps == "auto" and not uniform):
        atomic_write_text(sidecar, timestamps_text(times))
    return out


def write_image_folder(frames: Iterable[SyntheticFrame], folder: str | Path, *,
                       suffix: str = ".png", write_timestamps: bool = True) -> Path:
    """Write frames as numbered images plus ``timestamps.txt``.

    Parameters
    ----------
    frames
        Frames in order.
    folder
        Output folder (created).
    suffix
        Image type, e.g. ``".png"`` (lossless) or ``".jpg"``.
    write_timestamps
        Write the capture times to ``timestamps.txt`` (else readers use mtimes).

    Returns
    -------
    pathlib.Path
        The folder.
    """
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    times: list[float] = []
    for k, fr in enumerate(frames):
        ok, buf = cv2.imencode(suffix, fr.image)
        if not ok:
            raise VisionError("cannot encode image", source=str(out), value=suffix,
                              allowed=".png, .jpg, .bmp, .tif")
        atomic_write_bytes(out / f"frame_{k:06d}{suffix}", buf.tobytes())
        times.append(fr.t_s)
    if write_timestamps:
        atomic_write_text(out / TIMESTAMPS_NAME, timestamps_text(times))
    return out


def write_config_toml(config: VisionConfig, path: str | Path) -> Path:
    """Write the ROIs, scale and gear geometry of ``config`` as a vision TOML file."""
    data: dict[str, object] = {
        "roi": {r.name: [r.x, r.y, r.w, r.h] for r in config.rois},
        "filament": {"direction": config.direction},
    }
    if config.diameter_mm is not None:
        data["filament"] = {"direction": config.direction, "diameter_mm": config.diameter_mm}
    scale: dict[str, float] = {}
    if config.mm_per_px is not None:
        scale["mm_per_px"] = config.mm_per_px
    if config.calib_width_mm is not None:
        scale["calib_width_mm"] = config.calib_width_mm
    if scale:
        data["scale"] = scale
    gear: dict[str, object] = {}
    if config.gear_center_px is not None:
        gear["center_px"] = [float(config.gear_center_px[0]), float(config.gear_center_px[1])]
    if config.gear_radius_mm is not None:
        gear["radius_mm"] = config.gear_radius_mm
    if config.gear_method != "auto":
        gear["mode"] = config.gear_method
    if gear:
        data["gear"] = gear
    atomic_write_text(path, tomli_w.dumps(data))
    return Path(path)
