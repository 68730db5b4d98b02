"""A phone's close-up photo is read at the pitch the reader needs, with the same answer."""

from __future__ import annotations

import numpy as np
import pytest

from flowtwin.calibration.image.analyse import analyse_line_photo
from flowtwin.calibration.image.chevron_read import analyse_chevron_photo
from flowtwin.calibration.image.photosynth import PhotoConditions
from flowtwin.calibration.image.scale import READ_PITCH_PX, SMALL_PIXELS, working_scale

from .test_photo import MACHINE, _chevron, _photo

PARAMS = (("k_start", 0.0), ("k_end", 0.1), ("k_step", 0.01))


def test_a_small_photo_is_read_as_it_is_and_a_close_one_shrunk_to_the_pitch() -> None:
    _, img = _photo("marlin", 0.05, PhotoConditions(tilt_deg=8.0, roll_deg=5.0, seed=1),
                    PARAMS)
    assert working_scale(img[:, :, 1]) == 1.0
    # 27 px/mm: 135 px between lines 5 mm apart (an 11 MP photo of the pattern)
    _, close = _photo("marlin", 0.05, PhotoConditions(px_per_mm=27.0, tilt_deg=8.0,
                                                      roll_deg=5.0, seed=1), PARAMS)
    assert close.shape[0] * close.shape[1] > SMALL_PIXELS
    s = working_scale(close[:, :, 1])
    assert s * 27.0 * 5.0 == pytest.approx(READ_PITCH_PX, rel=0.1)


def test_a_close_photo_gives_the_answer_of_a_normal_one() -> None:
    # the same print photographed at 9 and at 27 px/mm (the reader's work grows with the
    # pixels times the pitch squared: ~80x for this one, read as it is)
    cond = {"normal": 9.0, "close": 27.0}
    res = {}
    for name, px in cond.items():
        pat, img = _photo("marlin", 0.05, PhotoConditions(px_per_mm=px, tilt_deg=8.0,
                                                          roll_deg=5.0, seed=1), PARAMS)
        res[name] = analyse_line_photo(img, pat, machine=MACHINE)
    normal, close = res["normal"], res["close"]
    assert close.k_best_line_s == normal.k_best_line_s == pytest.approx(0.05)
    assert normal.lag is not None and close.lag is not None
    sigma = np.hypot(normal.lag.k_err_s, close.lag.k_err_s)
    assert abs(close.lag.k_s - normal.lag.k_s) < 3.0 * sigma + 0.002
    # the figures in pixels are the photo's own
    assert close.px_per_mm == pytest.approx(3.0 * normal.px_per_mm, rel=0.03)
    assert np.allclose(close.image_lines / 3.0, normal.image_lines, atol=2.0)
    assert any("read at" in n for n in close.notes)
    assert not any("read at" in n for n in normal.notes)


def test_a_close_chevron_photo_gives_the_answer_of_a_normal_one() -> None:
    res = {}
    for name, px in (("normal", 8.0), ("close", 48.0)):  # 48 px/mm: a 12 MP photo
        pat, img = _chevron(0.045, PhotoConditions(px_per_mm=px, tilt_deg=5.0, seed=3))
        res[name] = analyse_chevron_photo(img, pat, machine=MACHINE)
    normal, close = res["normal"], res["close"]
    assert abs(close.k_best_line_s - 0.045) <= 0.01 + 1e-9
    assert close.lag is not None and normal.lag is not None
    assert abs(close.lag.k_s - 0.045) <= 0.15 * 0.045
    assert close.px_per_mm == pytest.approx(6.0 * normal.px_per_mm, rel=0.05)
    assert any("read at" in n for n in close.notes)
