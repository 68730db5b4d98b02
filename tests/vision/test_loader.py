"""Image loading: 16-bit scaled by 1/257 (x·255/65535) and rounded, colour to grey, errors."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from flowtwin.errors import VisionError
from flowtwin.vision import load_grey, open_source, read_grey_image, to_grey_u8
from flowtwin.vision.synth import timestamps_text


def test_16_bit_is_scaled_by_257_and_rounded() -> None:
    # x·255/65535 = x/257, rounded: full scale stays full scale, 257·k gives exactly k,
    # and each value goes to the nearer level
    x = np.array([[0, 128, 129, 257, 385, 386, 257 * 100, 65406, 65407, 65535]],
                 dtype=np.uint16)
    got = to_grey_u8(x)
    assert got.dtype == np.uint8 and got.shape == x.shape
    assert got.tolist() == [[0, 0, 1, 1, 1, 2, 100, 254, 255, 255]]
    # a shift by 8 bits (floor(x/256)) would give 0 for 129 = 0.502 of a level
    assert (np.array([129], np.uint16) >> 8)[0] == 0
    # agrees with the exact formula everywhere
    every = np.arange(65536, dtype=np.uint16).reshape(256, 256)
    exact = np.floor(every.astype(np.float64) * 255.0 / 65535.0 + 0.5)
    assert np.array_equal(to_grey_u8(every), exact.astype(np.uint8))


def test_colour_and_16_bit_colour_to_grey(tmp_path: Path) -> None:
    bgr = np.zeros((4, 5, 3), np.uint8)
    bgr[..., 0], bgr[..., 1], bgr[..., 2] = 200, 100, 50          # B, G, R
    grey = to_grey_u8(bgr)
    # OpenCV's luma: 0.299 R + 0.587 G + 0.114 B = 96.4
    assert np.all(grey == 96)
    wide = (bgr.astype(np.uint16) * 257)
    assert np.array_equal(to_grey_u8(wide), grey)
    bgra = np.concatenate([bgr, np.full((4, 5, 1), 7, np.uint8)], axis=2)
    assert np.array_equal(to_grey_u8(bgra), grey)
    assert np.array_equal(to_grey_u8(grey[:, :, None]), grey)
    # a 16-bit PNG through the file reader and through an image-folder source
    folder = tmp_path / "frames"
    folder.mkdir()
    ramp = (np.arange(40 * 60, dtype=np.uint32).reshape(40, 60) * 27).astype(np.uint16)
    for k in range(3):
        assert cv2.imwrite(str(folder / f"f{k}.png"), ramp)
    (folder / "timestamps.txt").write_text(timestamps_text([0.0, 0.04, 0.08]))
    read = read_grey_image(folder / "f0.png")
    assert np.array_equal(read, to_grey_u8(ramp))
    assert load_grey(folder / "f1.png")[1].endswith("f1.png")
    with open_source(folder) as src:
        frames = list(src)
    assert len(frames) == 3 and np.array_equal(frames[2].image, to_grey_u8(ramp))


def test_unsupported_inputs_are_errors(tmp_path: Path) -> None:
    with pytest.raises(VisionError, match=r"unsupported pixel type.*float32"):
        to_grey_u8(np.zeros((3, 3), np.float32))
    with pytest.raises(VisionError, match="unsupported image layout"):
        to_grey_u8(np.zeros((3, 3, 2), np.uint8))
    with pytest.raises(VisionError, match="no such image file"):
        read_grey_image(tmp_path / "missing.png")
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not a png")
    with pytest.raises(VisionError, match=r"bad\.png: not a readable image"):
        read_grey_image(bad)
