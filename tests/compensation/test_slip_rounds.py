"""The slip feed-forward's rounds: where the first round starts, when it stops."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from flowtwin.compensation import SlipOptions, compensate
from flowtwin.compensation import slip_stage as stages_module
from flowtwin.compensation.slip import slip_change
from flowtwin.errors import ProfileError


def test_slip_change_is_the_e_weighted_rms_over_printing_pieces() -> None:
    used = np.array([0.02, 0.02, 0.5, 0.01])
    predicted = np.array([0.03, 0.00, 0.1, np.nan])
    printing = np.array([True, True, False, True])
    base = np.array([100, 300, 50, 600])
    opts = SlipOptions()
    # the third piece does not print; NaN reads as 0; both slips clipped to max_slip
    want = np.sqrt((100 * 0.01 ** 2 + 300 * 0.02 ** 2 + 600 * 0.01 ** 2) / 1000)
    assert slip_change(used, predicted, printing, base, opts) == pytest.approx(want, rel=1e-12)
    clipped = slip_change(np.array([0.9]), np.array([0.3]), np.array([True]),
                          np.array([1]), opts)
    assert clipped == 0.0  # 0.9 is corrected for as max_slip = 0.3
    assert slip_change(used, predicted, np.zeros(4, bool), base, opts) == 0.0


def test_rounds_stop_at_the_tolerance_or_the_limit(example: Path, tmp_path: Path) -> None:
    every = compensate(example, tmp_path / "a.gcode", advance=True,
                       slip=SlipOptions(iterations=3, tolerance=0.0))
    assert every.slip_rounds == 3
    assert every.slip_change < 1e-4  # a fixed point: three rounds agree to 0.01 % of flow
    default = compensate(example, tmp_path / "b.gcode", advance=True, slip=True)
    assert 1 <= default.slip_rounds <= SlipOptions().iterations
    assert (default.slip_change <= SlipOptions().tolerance
            or default.slip_rounds == SlipOptions().iterations)
    # the file written is the last round's: its flow error is the report's
    assert default.after.rms_flow_error == pytest.approx(every.after.rms_flow_error, rel=0.02)
    with pytest.raises(ProfileError, match="tolerance"):
        SlipOptions(tolerance=-1e-3)


def test_the_first_round_from_the_slip_at_the_intended_feed_lands_nearer(
        example: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    one = SlipOptions(iterations=1)
    steady = compensate(example, tmp_path / "a.gcode", advance=True, slip=one)
    monkeypatch.setattr(stages_module, "steady_slip_at_intended_feed",
                        lambda slip, k_p: slip)  # correct for the slip at the uncorrected feed
    plain = compensate(example, tmp_path / "b.gcode", advance=True, slip=one)
    assert steady.slip_rounds == plain.slip_rounds == 1
    assert steady.slip_change < plain.slip_change / 1.5


def test_rounds_that_do_not_converge_keep_the_best_score_and_say_so(
        example: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    reports = [compensate(example, tmp_path / f"r{k}.gcode", advance=True,
                          slip=SlipOptions(iterations=k, tolerance=0.0)) for k in (1, 2, 3)]
    rms = [r.after.rms_flow_error for r in reports]
    assert len(set(rms)) == 3  # three different drafts
    kept = 1 + rms.index(min(rms))
    monkeypatch.setattr(stages_module, "slip_change", lambda *a: 0.5)  # never converges
    real = stages_module.flow_figures
    seen = 0

    def rounds_without_a_window_peak(*a, **k):  # type: ignore[no-untyped-def]
        nonlocal seen
        seen += 1  # the first call measures the draft the stage starts from
        f = real(*a, **k)
        return f if seen == 1 else replace(f, peak_overextrusion_window=0.0)

    monkeypatch.setattr(stages_module, "flow_figures", rounds_without_a_window_peak)
    out = tmp_path / "kept.gcode"
    report = compensate(example, out, advance=True, slip=SlipOptions(iterations=3))
    assert report.slip_rounds == 3
    assert "slip" in report.transformations
    # with no windowed peak, the score orders the rounds by their RMS flow error
    assert report.after.rms_flow_error == rms[kept - 1]
    assert out.read_bytes() == (tmp_path / f"r{kept}.gcode").read_bytes()
    assert any("did not reach its fixed point in 3 rounds" in w and f"round {kept}" in w
               for w in report.warnings)


def test_rounds_that_do_not_converge_are_refused_when_a_figure_rises(
        example: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from flowtwin.compensation import metrics

    plain = compensate(example, tmp_path / "adv.gcode", advance=True)
    monkeypatch.setattr(stages_module, "slip_change", lambda *a: 0.5)  # never converges
    real = metrics.flow_figures
    calls = []

    def worse_window_after_the_start(*a, **k):  # type: ignore[no-untyped-def]
        f = real(*a, **k)
        if k.get("window_mm") is not None:
            calls.append(1)
            if len(calls) > 1:  # every round: a windowed peak above the start's
                f = replace(f, peak_overextrusion_window=f.peak_overextrusion_window + 1.0)
        return f

    monkeypatch.setattr(stages_module, "flow_figures", worse_window_after_the_start)
    out = tmp_path / "refused.gcode"
    report = compensate(example, out, advance=True, slip=SlipOptions(iterations=2))
    assert len(calls) == 3  # the start and two rounds
    assert "slip" not in report.transformations
    assert any("windowed peak over-extrusion" in w and "not used" in w
               for w in report.warnings)
    assert out.read_bytes() == (tmp_path / "adv.gcode").read_bytes()
    assert report.after.rms_flow_error == plain.after.rms_flow_error
