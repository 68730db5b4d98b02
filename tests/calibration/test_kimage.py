"""K from an image of a K-line pattern: known answers on rendered images, bad images."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from flowtwin.calibration.fits.kfit import kline_for_machine
from flowtwin.calibration.image.kimage import analyse_kline_image
from flowtwin.calibration.image.twin_render import ImageConditions, RenderedImage
from flowtwin.calibration.patterns.catalog import generate_pattern
from flowtwin.calibration.patterns.kline import KLineParams
from flowtwin.calibration.patterns.pattern import Pattern, PrintSettings
from flowtwin.errors import CalibrationError, VisionError
from flowtwin.firmware import Firmware
from flowtwin.profiles.machine import Machine
from flowtwin.vision.loader import load_grey

Render = Callable[[float, ImageConditions], RenderedImage]

CASES = {
    # a photo: rotated, tilted, blurred, noisy, unevenly lit
    "photo": (0.045, ImageConditions(px_per_mm=12.0, rotation_deg=5.0, perspective=0.05,
                                     blur_px=1.2, noise_dn=6.0, shading=0.15, seed=3)),
    # scanned face down, turned the other way: the widths must tell front from back
    "mirrored": (0.055, ImageConditions(px_per_mm=12.0, rotation_deg=-3.0, perspective=0.03,
                                        blur_px=1.0, noise_dn=8.0, shading=0.1,
                                        mirrored=True, seed=4)),
    # coarser and softer, upside down
    "soft": (0.065, ImageConditions(px_per_mm=10.0, rotation_deg=178.0, blur_px=1.5,
                                    noise_dn=5.0, seed=5)),
}


@pytest.mark.parametrize("case", list(CASES))
def test_known_lag_from_a_rendered_image(case: str, render_kline7: Render, kline7: Pattern,
                                         tronvoll: Machine) -> None:
    k_true, cond = CASES[case]
    img = render_kline7(k_true, cond)
    res = analyse_kline_image(img.image, kline7, machine=tronvoll)
    assert res.view == ("mirrored" if cond.mirrored else "top") and res.prime_seen
    assert res.lag is not None, res.lag_problem
    # the fitted lag within 3σ of the K the image was rendered with
    assert abs(res.lag.k_s - k_true) <= 3.0 * res.lag.k_err_s
    assert res.lag.k_err_s < 0.01 * k_true
    # the most even line is one of the two neighbours of the true K (0.01 s apart)
    assert abs(res.k_best_line_s - k_true) <= 0.005 + 1e-9
    # zero crossings of the acceleration / deceleration errors: within half a step
    assert res.k_accel_s is not None and res.k_decel_s is not None
    assert abs(res.k_accel_s - k_true) <= 0.005 and abs(res.k_decel_s - k_true) <= 0.005
    scale = np.sqrt(abs(np.linalg.det(img.homography[:2, :2])))
    assert res.px_per_mm == pytest.approx(scale, rel=0.05)


def test_scores_are_lowest_near_the_true_lag(render_kline7: Render, kline7: Pattern,
                                             tronvoll: Machine) -> None:
    img = render_kline7(0.045, CASES["photo"][1])
    res = analyse_kline_image(img.image, kline7, machine=tronvoll, fit=False)
    scores = [r.score for r in res.lines]
    accel = [r.accel_error for r in res.lines]
    assert res.lag is None and res.lag_problem is None
    # K too low: under-extrusion after the step up, over after the step down [001 Fig. 2]
    assert accel[0] < 0.0 < accel[-1] and res.lines[0].decel_error < 0.0
    assert np.argmin(scores) in (2, 3)                 # K = 0.04 or 0.05
    assert all(r.steady_width_mm == pytest.approx(0.48, rel=0.06) for r in res.lines)


def test_known_scan_resolution(render_kline7: Render, kline7: Pattern,
                               tronvoll: Machine) -> None:
    cond = ImageConditions(px_per_mm=600 / 25.4, blur_px=1.0, noise_dn=4.0, seed=6)
    img = render_kline7(0.05, cond)
    res = analyse_kline_image(img.image, kline7, machine=tronvoll, mm_per_px=25.4 / 600)
    assert res.lag is not None
    assert abs(res.lag.k_s - 0.05) <= 3.0 * res.lag.k_err_s
    # the dark level of a blurred 11 px bead is reached in its core: widths within 2 %
    assert res.lines[3].steady_width_mm == pytest.approx(0.481, rel=0.02)


def test_edge_method_is_close(render_kline7: Render, kline7: Pattern,
                              tronvoll: Machine) -> None:
    """The derivative-extrema widths lock to the pixel grid and shrink narrow, blurred
    beads (docs/calibration.md: 4–5 % on these renders): within 10 %, not within σ."""
    img = render_kline7(0.045, CASES["photo"][1])
    res = analyse_kline_image(img.image, kline7, machine=tronvoll, method="edges")
    assert res.lag is not None
    assert res.lag.k_s == pytest.approx(0.045, rel=0.10)


def test_image_files(tmp_path: Path, render_kline7: Render, kline7: Pattern,
                     tronvoll: Machine) -> None:
    img = render_kline7(0.05, ImageConditions(px_per_mm=8.0))
    colour = tmp_path / "scan.png"
    cv2.imwrite(str(colour), cv2.cvtColor(img.image, cv2.COLOR_GRAY2BGR))
    grey, name = load_grey(colour)
    assert np.array_equal(grey, img.image) and name == str(colour)
    not_image = tmp_path / "notes.png"
    not_image.write_text("not an image")
    with pytest.raises(VisionError, match="not a readable image"):
        analyse_kline_image(not_image, kline7, machine=tronvoll)
    with pytest.raises(VisionError, match="no such image file"):
        analyse_kline_image(tmp_path / "missing.png", kline7, machine=tronvoll)


def test_bad_images_never_give_a_k(kline7: Pattern, tronvoll: Machine,
                                   render_kline7: Render) -> None:
    with pytest.raises(VisionError, match="blank"):
        analyse_kline_image(np.full((400, 600), 230, np.uint8), kline7, machine=tronvoll)
    noise = np.random.default_rng(2).integers(0, 256, (400, 600)).astype(np.uint8)
    with pytest.raises(VisionError, match="no printed lines"):
        analyse_kline_image(noise, kline7, machine=tronvoll)
    img = render_kline7(0.05, ImageConditions(px_per_mm=8.0))
    other = kline_for_machine(tronvoll, PrintSettings(),
                              KLineParams(k_start=0.0, k_end=0.1, k_step=0.01))
    with pytest.raises(VisionError, match="found 8 lines, but the pattern has 11 K-lines"):
        analyse_kline_image(img.image, other, machine=tronvoll)
    cut = img.image[: img.image.shape[0] // 2]        # half the lines, no prime line
    with pytest.raises(VisionError):
        analyse_kline_image(cut, kline7, machine=tronvoll)


def test_pattern_must_match_the_machine(kline7: Pattern, tronvoll: Machine) -> None:
    klipper = generate_pattern("kline", PrintSettings(firmware=Firmware.KLIPPER),
                               {"k_start": 0.02, "k_end": 0.08})
    with pytest.raises(CalibrationError, match="another firmware"):
        analyse_kline_image(np.zeros((50, 50), np.uint8), klipper, machine=tronvoll)
    chevron = generate_pattern("chevron", PrintSettings(firmware=Firmware.PRUSA))
    with pytest.raises(CalibrationError, match="reads K-line patterns"):
        analyse_kline_image(np.zeros((50, 50), np.uint8), chevron, machine=tronvoll)
    with pytest.raises(CalibrationError, match="unknown width measurement"):
        analyse_kline_image(np.zeros((50, 50), np.uint8), kline7, method="sobel")


def test_16_bit_images_load_as_vision_loads_them(render_kline7: Render, kline7: Pattern,
                                                  tronvoll: Machine) -> None:
    # one image loader for calibration and vision (flowtwin.vision.loader): a 16-bit scan
    # of the same picture (x·257) reads back as the 8-bit picture and gives the same K
    img = render_kline7(0.05, ImageConditions(px_per_mm=8.0))
    wide = img.image.astype(np.uint16) * 257
    assert np.array_equal(load_grey(wide)[0], img.image)
    a = analyse_kline_image(img.image, kline7, machine=tronvoll)
    b = analyse_kline_image(wide, kline7, machine=tronvoll)
    assert a.lag is not None and b.lag is not None
    assert b.lag.k_s == a.lag.k_s
