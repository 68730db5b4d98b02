"""Pattern images rendered from the twin: widths, geometry, gaps, degradation."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from flowtwin.calibration.fits.lagmodel import LagParams, lag_model
from flowtwin.calibration.image.beadwidth import area_widths, sample_strip, window_widths
from flowtwin.calibration.image.twin_render import ImageConditions, RenderedImage
from flowtwin.calibration.patterns.pattern import Pattern
from flowtwin.errors import CalibrationError
from flowtwin.profiles.machine import Machine

Render = Callable[[float, ImageConditions], RenderedImage]
SHARP = ImageConditions(px_per_mm=12.0)


def _k_lines(pattern: Pattern, machine: Machine) -> list[int]:
    return [next(s.line for s in pattern.segments if s.group == g)
            for g in range(len(pattern.values))]


def test_bead_widths_are_the_twins(render_kline7: Render, kline7: Pattern,
                                   tronvoll: Machine) -> None:
    img = render_kline7(0.05, SHARP)
    model = lag_model(kline7.text().encode(), _k_lines(kline7, tronvoll), machine=tronvoll)
    line = model.lines[3]
    strip = sample_strip(img.image.astype(np.float32), img.homography,
                         line.vertices_xy_mm[0], line.vertices_xy_mm[-1], step_mm=0.25,
                         half_span_mm=2.0, dv_mm=0.5 / 12.0)
    w = window_widths(area_widths(strip, SHARP.bead_dn), strip.per, min_width_mm=0.1)
    x = strip.positions_mm
    sub = np.linspace(-0.125, 0.125, 9)
    model_w = model.widths(LagParams(0.05), [np.clip((x[:, None] + sub).ravel(), 0, 80)]
                           * 7)[3].reshape(-1, 9).mean(axis=1)
    inner = (x > 1.0) & (x < 79.0)
    # exact coverage rendering, bilinear resampling: well under a tenth of a pixel (8 µm);
    # Marlin's linear advance (the MK2.5's) makes the width step at a speed change, and the
    # resampling spreads a step over one pixel: up to 3 µm there
    np.testing.assert_allclose(w[inner], model_w[inner], atol=0.003)


def test_homography_puts_the_lines_where_they_are_drawn(render_kline7: Render) -> None:
    for cond in (SHARP, ImageConditions(px_per_mm=10.0, rotation_deg=8.0, perspective=0.06,
                                        mirrored=True)):
        img = render_kline7(0.05, cond)
        on = img.to_px([[110.0, 95.0 + 5.0 * i] for i in range(7)])
        between = img.to_px([[110.0, 97.5 + 5.0 * i] for i in range(6)])
        grey = img.image.astype(float)
        assert all(grey[int(round(r)), int(round(c))] < 100 for c, r in on)
        assert all(grey[int(round(r)), int(round(c))] > 200 for c, r in between)


def test_mirrored_image_runs_the_other_way(render_kline7: Render) -> None:
    top = render_kline7(0.05, SHARP).to_px([[70.0, 100.0], [150.0, 100.0]])
    mirrored = render_kline7(0.05, ImageConditions(px_per_mm=12.0, mirrored=True)).to_px(
        [[70.0, 100.0], [150.0, 100.0]])
    assert top[1, 0] > top[0, 0] and mirrored[1, 0] < mirrored[0, 0]


def test_over_compensated_line_has_a_gap(render_kline7: Render) -> None:
    """K_LA = 0.08 s on a printer with K = 0.02 s empties the nozzle after the step down
    [001 'no extruded material when deaccelerating']: the bead is missing there."""
    img = render_kline7(0.02, SHARP)
    y = 95.0 + 5.0 * 6                       # the K = 0.08 line
    along = img.to_px([[70.0 + x, y] for x in np.arange(58.0, 64.0, 0.1)])
    grey = np.array([img.image[int(round(r)), int(round(c))] for c, r in along])
    assert np.max(grey) > 200                # bed visible on the path: a gap
    before = img.to_px([[70.0 + 40.0, y]])[0]
    assert img.image[int(round(before[1])), int(round(before[0]))] < 100


def test_noise_is_seeded(render_kline7: Render) -> None:
    a = render_kline7(0.05, ImageConditions(px_per_mm=6.0, noise_dn=5.0, seed=1))
    b = render_kline7(0.05, ImageConditions(px_per_mm=6.0, noise_dn=5.0, seed=1))
    c = render_kline7(0.05, ImageConditions(px_per_mm=6.0, noise_dn=5.0, seed=2))
    assert np.array_equal(a.image, b.image) and not np.array_equal(a.image, c.image)
    assert a.params == LagParams(0.05)


@pytest.mark.parametrize(("field", "value"), [("px_per_mm", 1.0), ("perspective", 0.8),
                                              ("shading", 1.0), ("blur_px", -1.0)])
def test_bad_conditions(field: str, value: float) -> None:
    with pytest.raises(CalibrationError, match=rf"\[{field}\]"):
        ImageConditions(**{field: value})  # type: ignore[arg-type]
