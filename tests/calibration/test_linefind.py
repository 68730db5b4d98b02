"""Finding and registering the K-lines in rendered images; images that must be refused."""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
import pytest

from flowtwin.calibration.image.linefind import find_lines, local_scale, register_pattern
from flowtwin.calibration.image.twin_render import ImageConditions, RenderedImage
from flowtwin.errors import VisionError

Render = Callable[[float, ImageConditions], RenderedImage]

#: Bed geometry of ``kline7`` (centre 110, 110; 80 mm lines; pitch 5 mm; prime in front).
STARTS = np.array([[70.0, 95.0 + 5.0 * i] for i in range(7)])
ENDS = STARTS + np.array([80.0, 0.0])
PRIME = (np.array([70.0, 90.0]), np.array([150.0, 90.0]))
TICKS = [True, False, False, False, False, True, False]
PHOTO = ImageConditions(px_per_mm=12.0, rotation_deg=5.0, perspective=0.05, blur_px=1.2,
                        noise_dn=6.0, shading=0.15, seed=3)


def test_lines_and_ticks_are_found(render_kline7: Render) -> None:
    img = render_kline7(0.05, PHOTO)
    lines, direction = find_lines(img.image, line_length_mm=80.0)
    assert len(lines) == 8                          # prime line + 7 K-lines
    assert sorted(ln.tick != 0 for ln in lines).count(True) == 2
    assert {ln.tick for ln in lines if ln.tick} in ({1}, {-1})
    # direction of the print in the image: bed +x through the homography, up to sign
    bed_x = img.to_px([[110.0, 110.0], [111.0, 110.0]])
    ref = (bed_x[1] - bed_x[0]) / np.linalg.norm(bed_x[1] - bed_x[0])
    assert abs(float(direction @ ref)) > np.cos(np.radians(2.0))


def test_registration_recovers_the_bed_geometry(render_kline7: Render) -> None:
    img = render_kline7(0.05, PHOTO)
    lines, direction = find_lines(img.image, line_length_mm=80.0)
    regs = register_pattern(lines, direction, starts_mm=STARTS, ends_mm=ENDS, prime_mm=PRIME,
                            ticks=TICKS, view="top")
    assert len(regs) == 1 and regs[0].prime_seen and regs[0].view == "top"
    reg = regs[0]
    probe = np.array([[70.0 + x, 95.0 + 5.0 * i] for i in range(7) for x in (20.0, 60.0)])
    est = cv2.perspectiveTransform(probe.reshape(-1, 1, 2), reg.homography).reshape(-1, 2)
    err_mm = np.linalg.norm(est - img.to_px(probe), axis=1) / reg.px_per_mm
    # the bead's ends are not the path's (the flow starts late or with a blob: the lag
    # fit refines the along-line registration); half a millimetre bounds that here
    assert float(np.max(err_mm)) < 0.5
    true_scale = local_scale(img.homography, np.array([110.0, 110.0]))
    assert reg.px_per_mm == pytest.approx(true_scale, rel=0.01)


def test_a_symmetric_tick_layout_gives_both_readings(render_kline7: Render) -> None:
    """Ticks on K-lines 0 and 5 of 7 behind a prime line read the same both ways."""
    img = render_kline7(0.05, ImageConditions(px_per_mm=10.0, mirrored=True))
    lines, direction = find_lines(img.image, line_length_mm=80.0)
    regs = register_pattern(lines, direction, starts_mm=STARTS, ends_mm=ENDS, prime_mm=PRIME,
                            ticks=TICKS)
    assert sorted(r.view for r in regs) == ["mirrored", "top"]
    one = register_pattern(lines, direction, starts_mm=STARTS, ends_mm=ENDS, prime_mm=PRIME,
                           ticks=TICKS, view="mirrored")
    assert [r.view for r in one] == ["mirrored"]


def test_wrong_line_count_and_missing_ticks(render_kline7: Render) -> None:
    img = render_kline7(0.05, ImageConditions(px_per_mm=10.0))
    lines, direction = find_lines(img.image, line_length_mm=80.0)
    with pytest.raises(VisionError, match="found 8 lines, but the pattern has 5 K-lines"):
        register_pattern(lines, direction, starts_mm=STARTS[:5], ends_mm=ENDS[:5],
                         prime_mm=PRIME, ticks=TICKS[:5])
    with pytest.raises(VisionError, match="tick marks to tell the start"):
        register_pattern(lines, direction, starts_mm=STARTS, ends_mm=ENDS, prime_mm=PRIME,
                         ticks=[False] * 7)
    with pytest.raises(VisionError, match="tick marks do not match"):
        register_pattern(lines, direction, starts_mm=STARTS, ends_mm=ENDS, prime_mm=PRIME,
                         ticks=[True, True] + [False] * 5)


def test_images_without_lines_are_refused() -> None:
    blank = np.full((300, 400), 200, dtype=np.uint8)
    with pytest.raises(VisionError, match="blank"):
        find_lines(blank, line_length_mm=80.0)
    noise = np.random.default_rng(0).integers(0, 256, (300, 400)).astype(np.uint8)
    with pytest.raises(VisionError, match="no printed lines"):
        find_lines(noise, line_length_mm=80.0)
    blob = np.full((300, 400), 220, dtype=np.uint8)
    cv2.circle(blob, (200, 150), 60, 40, -1)
    with pytest.raises(VisionError, match="no printed lines"):
        find_lines(blob, line_length_mm=80.0)
    with pytest.raises(VisionError, match="too small"):
        find_lines(np.zeros((10, 10), dtype=np.uint8), line_length_mm=80.0)
