"""The answer checks of ``from-image`` (:func:`flowtwin.calibration.image.quality.answer_reason`):
never a confident K from a photo whose best line lies at an end of the printed range,
whose best line and twin's lag disagree far beyond their uncertainties, or whose best line
only the smallest score supports.

Every image here comes from the independent renderer
(:mod:`flowtwin.calibration.image.photosynth`), whose true lag is known; the real photos the
checks were written for are not in the repository (docs/calibration.md, "Session 10").
"""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from flowtwin.calibration.fits.kfit import pattern_firmware
from flowtwin.calibration.image.analyse import analyse_line_photo
from flowtwin.calibration.image.chevron_read import analyse_chevron_photo
from flowtwin.calibration.image.layouts import (
    layout_params,
    layout_settings,
    line_layout_pattern,
)
from flowtwin.calibration.image.photosynth import (
    PhotoConditions,
    render_photo,
    scene_from_pattern,
)
from flowtwin.calibration.image.quality import (
    MAX_DISAGREEMENT,
    answer_reason,
    disagreement,
    range_end_reason,
)
from flowtwin.calibration.patterns.chevron import ChevronParams, chevron_pattern
from flowtwin.calibration.patterns.pattern import Pattern, PrintSettings
from flowtwin.cli.main import main
from flowtwin.errors import VisionError
from flowtwin.profiles.machine import load_machine

MACHINE = load_machine("tronvoll2019")
ACCEL = 1000.0
#: The conditions of the ``marlin`` known-answer render (tests/calibration/test_photo.py).
COND = PhotoConditions(tilt_deg=8.0, roll_deg=5.0, seed=1)


def _marlin(**params: float) -> Pattern:
    base = PrintSettings(firmware=pattern_firmware(MACHINE), accel_mm_s2=ACCEL)
    s = layout_settings("marlin", base, accel_given=True)
    return line_layout_pattern("marlin", s, layout_params("marlin", params))


@functools.lru_cache(maxsize=4)
def _render(lag: float, k_start: float, k_end: float) -> tuple[Pattern, np.ndarray]:
    pat = _marlin(k_start=k_start, k_end=k_end, k_step=0.01)
    marks, tests = scene_from_pattern(pat, lag_s=lag, accel_mm_s2=ACCEL)
    return pat, render_photo(pat, marks, tests, COND).image


# --- the rules on numbers -----------------------------------------------------------------------

def test_range_end_reason_only_at_the_ends_of_the_lines_measured() -> None:
    k = np.arange(11) * 0.01
    every = list(range(11))
    first = range_end_reason(k, 0, every)
    assert first is not None and "first" in first and "K <= 0 s" in first
    last = range_end_reason(k, 10, every)
    assert last is not None and "last" in last and "K >= 0.1 s" in last
    assert range_end_reason(k, 5, every) is None
    # the last line not measured: the best of the measured lines is the last of them
    assert range_end_reason(k, 9, every[:-1]) is not None
    assert range_end_reason(k, 8, every[:-1]) is None


def test_disagreement_in_units_of_half_a_step_and_sigma() -> None:
    # Ellis' chevrons as read in session 9: best 0.0, lag 0.0486 +- 0.0012, step 0.005
    z = disagreement(0.0, 0.005, 0.0486, 0.0012)
    assert z == pytest.approx(0.0486 / math.hypot(0.0025, 0.0012))
    assert z > MAX_DISAGREEMENT
    k = np.arange(17) * 0.005
    check = answer_reason(k, 9, list(range(17)), k_lag_s=0.0486, k_lag_err_s=0.0012)
    assert check.check is None and check.z < 1.5          # best 0.045: they agree
    check = answer_reason(k, 3, list(range(17)), k_lag_s=0.0486, k_lag_err_s=0.0012)
    assert check.check == "disagreement" and check.reason is not None
    assert "disagree" in check.reason and check.values["z"] == pytest.approx(check.z, abs=0.05)
    # a dead time fitted with the lag: the best K is not the lag alone, not compared
    check = answer_reason(k, 3, list(range(17)), k_lag_s=0.0486, k_lag_err_s=0.0012,
                          dead_time=True)
    assert check.check is None and math.isnan(check.z)
    # no lag fit: only the range check
    check = answer_reason(k, 0, list(range(17)), k_lag_s=None, k_lag_err_s=None)
    assert check.check == "range-end" and check.values["lag_k_s"] is None


def test_a_best_line_only_the_score_supports_is_refused_when_the_lag_fit_failed() -> None:
    """The inpainted QIDI photo of session 13 (docs/calibration.md, "Session 17"), as
    numbers: 11 lines 0.01–0.05 s, best by the smallest score at 0.022 s, the errors'
    crossing outside the range, the lag fit failed."""
    k = 0.01 + 0.004 * np.arange(11)
    every = list(range(11))
    failed = "only 0 usable width samples for 4 parameter(s)"
    check = answer_reason(k, 3, every, k_lag_s=None, k_lag_err_s=None, best_by="score",
                          lag_problem=failed)
    assert check.check == "unsupported" and check.reason is not None
    assert "only the smallest score picks the best line (K 0.022 s)" in check.reason
    assert failed in check.reason and check.values["best_k_s"] == pytest.approx(0.022)
    # a second witness is enough: the errors' crossing, or a lag fit that agrees
    assert answer_reason(k, 3, every, k_lag_s=None, k_lag_err_s=None, best_by="errors",
                         lag_problem=failed).check is None
    assert answer_reason(k, 3, every, k_lag_s=0.023, k_lag_err_s=0.001,
                         best_by="score").check is None
    # no lag fit asked for (API ``fit=False``): not refused for it
    assert answer_reason(k, 3, every, k_lag_s=None, k_lag_err_s=None,
                         best_by="score").check is None
    # the range end is said first; chevrons are named as such
    assert answer_reason(k, 0, every, k_lag_s=None, k_lag_err_s=None, best_by="score",
                         lag_problem=failed).check == "range-end"
    chev = answer_reason(k, 3, every, k_lag_s=None, k_lag_err_s=None, best_by="score",
                         lag_problem=failed, item="chevron")
    assert chev.reason is not None and "best chevron" in chev.reason


# --- best line at an end of the range, on renders -------------------------------------------------

@pytest.mark.parametrize("lag, k_start, k_end, which", [
    (0.03, 0.06, 0.1, "first"),      # the lag below the printed range
    (0.07, 0.0, 0.04, "last"),       # and above it
])
def test_best_line_at_an_end_of_the_range_is_refused(lag: float, k_start: float, k_end: float,
                                                     which: str) -> None:
    pat, img = _render(lag, k_start, k_end)
    with pytest.raises(VisionError, match=f"the best line is the {which} of the range") as exc:
        analyse_line_photo(img, pat, machine=MACHINE)
    assert "print the pattern again with a range that brackets it" in exc.value.message
    assert exc.value.field == "k_best_line_s"
    assert isinstance(exc.value.value, dict)
    assert exc.value.value["best_k_s"] == pytest.approx(k_start if which == "first" else k_end)


def test_a_range_that_brackets_the_lag_is_read_and_the_answers_agree() -> None:
    """The same scene and camera with a range around the lag: read, best line within a
    step, and the best line and the lag agree well inside the threshold."""
    pat, img = _render(0.05, 0.0, 0.1)
    res = analyse_line_photo(img, pat, machine=MACHINE)
    assert abs(res.k_best_line_s - 0.05) <= 0.01 + 1e-9
    assert res.lag is not None
    assert math.isfinite(res.disagreement) and res.disagreement < 0.5 * MAX_DISAGREEMENT
    assert res.summary()["disagreement"] == pytest.approx(res.disagreement)


# --- best line and lag disagree, on a render ---------------------------------------------

def test_best_chevron_and_lag_that_disagree_are_refused() -> None:
    """A chevron photo seen from above read as a mirrored scan (``view="mirrored"``): the
    arms are swapped, so each apex's walls are taken to run the other way; the chevrons'
    signed errors and the twin's bands then describe another print, and the best chevron
    (0.05 s) and the lag the twin fits (0.083 s) disagree: refused. Read as seen from
    above, the same photo is read and both answers agree with the truth (0.045 s)."""
    base = PrintSettings(firmware=pattern_firmware(MACHINE), accel_mm_s2=ACCEL)
    pat = chevron_pattern(base, ChevronParams(k_start=0.0, k_end=0.1, k_step=0.01))
    marks, tests = scene_from_pattern(pat, lag_s=0.045, accel_mm_s2=ACCEL,
                                      corner_speed_mm_s=10.0 / math.sqrt(2.0))
    img = render_photo(pat, marks, tests, PhotoConditions(px_per_mm=8.0, tilt_deg=5.0,
                                                          seed=3)).image
    with pytest.raises(VisionError, match="disagree") as exc:
        analyse_chevron_photo(img, pat, machine=MACHINE, view="mirrored")
    assert isinstance(exc.value.value, dict) and exc.value.value["z"] > MAX_DISAGREEMENT
    res = analyse_chevron_photo(img, pat, machine=MACHINE, view="top")
    assert res.disagreement < 0.5 * MAX_DISAGREEMENT
    assert abs(res.k_best_line_s - 0.045) <= 0.01


# --- CLI ---------------------------------------------------------------------------------------

def test_cli_refuses_with_the_reason_exit_2_and_json(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    _, img = _render(0.03, 0.06, 0.1)
    photo = tmp_path / "lines.png"
    assert cv2.imwrite(str(photo), img)
    frag = tmp_path / "pa.toml"
    argv = ["calibrate", "from-image", str(photo), "--pattern", "marlin", "--k-start", "0.06",
            "--k-end", "0.1", "--k-step", "0.01", "--accel", str(ACCEL), "-o", str(frag)]
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    cap = capsys.readouterr()
    assert "the best line is the first of the range" in cap.err and "Traceback" not in cap.err
    assert not frag.exists()
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--json"])
    assert exc.value.code == 2
    cap = capsys.readouterr()
    out = json.loads(cap.out)
    assert out["refused"].startswith("the best line is the first of the range")
    assert out["answers"]["best_k_s"] == pytest.approx(0.06)
    assert "Traceback" not in cap.err and not frag.exists()
