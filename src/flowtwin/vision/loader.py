"""Image and video loading for vision: any file or array to one grey 8-bit image.

Every measurement in :mod:`flowtwin.vision` works on grey ``uint8`` images. This module is
the one place where files and arrays become such images:

* **colour** (BGR, BGRA — OpenCV's channel order) → grey with OpenCV's luma weights
  (``0.299 R + 0.587 G + 0.114 B``, ``cv2.COLOR_BGR2GRAY``);
* **16-bit** (``uint16``, e.g. a machine-vision camera's PNG or TIFF) → 8-bit by
  ``x·255/65535 = x/257``, rounded to the nearest level: full scale stays full scale
  (65535 → 255) and 0 stays 0. A shift by 8 bits (``x >> 8``) would map full scale to 255
  too, but floors every level: a mean bias of −0.5 DN and a different step at the top;
* a single-channel 3-D array ``(H, W, 1)`` → ``(H, W)``.

Anything else (float images, 2-channel arrays, other integer types) is refused with a
:class:`~flowtwin.errors.VisionError` naming the file and what is allowed, never guessed.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from flowtwin.errors import VisionError

__all__ = ["IMAGE_SUFFIXES", "U16_TO_U8", "load_grey", "open_video", "read_grey_image",
           "to_grey_u8"]

U8Image = npt.NDArray[np.uint8]

#: Image file endings read by :func:`read_grey_image` (and the image-folder source).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".pgm", ".ppm")
#: 16-bit to 8-bit divisor: 65535 / 255 = 257 exactly.
U16_TO_U8 = 257


def _u16_to_u8(arr: npt.NDArray[Any]) -> U8Image:
    """``round(x/257)``, i.e. ``x·255/65535`` to the nearest 8-bit level."""
    wide = np.asarray(arr, dtype=np.uint32)
    return ((wide + U16_TO_U8 // 2) // U16_TO_U8).astype(np.uint8)


def to_grey_u8(image: npt.NDArray[Any], *, source: str = "<array>") -> U8Image:
    """One grey 8-bit image from a grey/BGR/BGRA array of 8 or 16 bits.

    Parameters
    ----------
    image
        Shape ``(H, W)``, ``(H, W, 1)``, ``(H, W, 3)`` (BGR) or ``(H, W, 4)`` (BGRA);
        dtype ``uint8`` or ``uint16``.
    source
        Name used in error messages (file, frame).

    Returns
    -------
    numpy.ndarray
        Grey image, shape ``(H, W)``, uint8, C-contiguous. 16-bit input is scaled by
        ``1/257`` (``x·255/65535``) and rounded; colour is converted to grey first, in
        the input's bit depth.

    Raises
    ------
    VisionError
        Unsupported dtype or layout.
    """
    arr = np.asarray(image)
    if arr.dtype not in (np.uint8, np.uint16):
        raise VisionError("unsupported pixel type", source=source, value=str(arr.dtype),
                          allowed="8-bit or 16-bit unsigned images (uint8, uint16)")
    if arr.ndim == 3 and arr.shape[2] == 1:
        arr = arr[:, :, 0]
    elif arr.ndim == 3 and arr.shape[2] == 3:
        arr = cv2.cvtColor(arr, cv2.COLOR_BGR2GRAY)
    elif arr.ndim == 3 and arr.shape[2] == 4:
        arr = cv2.cvtColor(arr, cv2.COLOR_BGRA2GRAY)
    elif arr.ndim != 2:
        raise VisionError("unsupported image layout", source=source, value=arr.shape,
                          allowed="grey (H, W), BGR (H, W, 3) or BGRA (H, W, 4)")
    if arr.dtype == np.uint16:
        return np.ascontiguousarray(_u16_to_u8(arr))
    return np.ascontiguousarray(arr, dtype=np.uint8)


def read_grey_image(path: str | os.PathLike[str]) -> U8Image:
    """Read an image file as grey 8-bit (see :func:`to_grey_u8` for 16-bit and colour).

    Parameters
    ----------
    path
        PNG, JPEG, BMP, TIFF or PNM file.

    Returns
    -------
    numpy.ndarray
        Shape ``(H, W)``, uint8.

    Raises
    ------
    VisionError
        Missing file, a file OpenCV cannot decode, or an unsupported pixel type.
    """
    name = os.fspath(path)
    if not os.path.isfile(name):
        raise VisionError("no such image file", source=name)
    try:
        image = cv2.imread(name, cv2.IMREAD_UNCHANGED)
    except cv2.error as exc:   # OpenCV refuses some headers outright (e.g. > 2^20 px wide)
        reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else "decoder error"
        raise VisionError(f"not a readable image ({reason})", source=name,
                          allowed="PNG, JPEG, BMP, TIFF or PNM images within OpenCV's "
                                  "size limits") from None
    if image is None:
        raise VisionError("not a readable image", source=name,
                          allowed="PNG, JPEG, BMP, TIFF or PNM images")
    return to_grey_u8(image, source=name)


def load_grey(image: str | os.PathLike[str] | npt.NDArray[Any]) -> tuple[U8Image, str]:
    """A grey 8-bit image from a file or an array, and its name for messages.

    Parameters
    ----------
    image
        A file path, or an array as accepted by :func:`to_grey_u8`.

    Returns
    -------
    (numpy.ndarray, str)
        The image, shape ``(H, W)``, uint8, and the file name (``"<array>"`` for arrays).
    """
    if isinstance(image, np.ndarray):
        return to_grey_u8(image), "<array>"
    name = os.fspath(image)
    return read_grey_image(name), name


def open_video(path: str | Path) -> cv2.VideoCapture:
    """Open a video file with OpenCV's FFmpeg back end.

    Parameters
    ----------
    path
        Video file (AVI, MKV, MP4, ...).

    Returns
    -------
    cv2.VideoCapture
        An opened capture; frames it returns go through :func:`to_grey_u8`.

    Raises
    ------
    VisionError
        Missing or empty file, or a file FFmpeg cannot open.
    """
    p = Path(path)
    if not p.is_file():
        raise VisionError("no such video file", source=str(p))
    if p.stat().st_size == 0:
        raise VisionError("the video file is empty", source=str(p))
    cap = cv2.VideoCapture(str(p), cv2.CAP_FFMPEG)
    if not cap.isOpened():
        raise VisionError("cannot open the video (not a video file, or a codec FFmpeg "
                          "does not know)", source=str(p),
                          allowed="a video OpenCV/FFmpeg can decode (AVI, MKV, MP4, ...)")
    return cap
