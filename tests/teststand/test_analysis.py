"""Per-record evaluation: maximum feed force and slip regression [000 §4, Fig. 9]."""

from __future__ import annotations

import numpy as np
import pytest

from flowtwin.errors import CalibrationError
from flowtwin.profiles import load_rollers
from flowtwin.teststand import (
    DriveUnderTest,
    Instrument,
    Record,
    RecordKey,
    SlipLaw,
    analyse_record,
    analyse_records,
    loading_phase,
    simulate_record,
    slip_regression,
)


def _exact_record(gradient: float, k_p: float, fmax: float, v: float = 2.0) -> Record:
    """A noise-free record: ramp at 4 N/s to fmax, then collapse to 0 and stand."""
    t = np.arange(0.0, fmax / 4.0 + 2.0, 0.02)
    force = np.where(4.0 * t <= fmax, 4.0 * t, 0.0)
    speed = np.where(4.0 * t <= fmax, v * (1.0 - k_p - gradient * force), 0.0)
    return Record(RecordKey("t", 80.0, v, 0), t, speed, force, np.full_like(t, 80.0))


def test_noise_free_record_gives_the_law_exactly() -> None:
    rec = _exact_record(gradient=0.0033, k_p=0.0063, fmax=90.0)
    res = analyse_record(rec, force_sigma_n=0.0)
    assert res.slip is not None
    assert res.slip.gradient_per_n == pytest.approx(0.0033, rel=1e-9)
    assert res.slip.offset == pytest.approx(0.0063, abs=1e-12)
    assert res.slip.r_squared == pytest.approx(1.0, abs=1e-12)
    # smoothed maximum: the 5-sample average just before the collapse lies 2 samples
    # (0.16 N) below the peak
    assert res.max_feed_force_n == pytest.approx(90.0 - 0.16, abs=0.1)
    end, _ = loading_phase(rec)
    assert 4.0 * rec.t_s[end] == pytest.approx(90.0, abs=0.2)


def test_errors_in_variables_correction_removes_the_attenuation() -> None:
    """Low pinch force: ~10 N of force range against 1 N load-cell noise. Plain least squares
    shrinks the slope by n·σ²/Sxx (~10 %); the corrected slope is unbiased."""
    drive = DriveUnderTest.from_roller(load_rollers()[3], law=SlipLaw.PINCH, k_p=0.0063)
    rng = np.random.default_rng(42)
    corrected, ols = [], []
    for _ in range(60):
        rec = simulate_record(drive, pinch_force_n=10.0, speed_mm_s=5.0, repeat=0, rng=rng)
        res = analyse_record(rec)
        assert res.slip is not None
        corrected.append(res.slip.gradient_per_n)
        ols.append(res.slip.ols_gradient_per_n)
    true = float(drive.slip_gradient_per_n(10.0, 5.0))
    sem = float(np.std(corrected) / np.sqrt(len(corrected)))
    assert float(np.mean(corrected)) == pytest.approx(true, abs=4 * sem)
    assert float(np.mean(ols)) < true - 8 * sem  # the bias the correction removes


def test_slip_of_the_papers_fig9a_set_point() -> None:
    """Roller #3, 80 N, 1 mm/s [000 Fig. 9a]: s' = 0.33 %/N, offset 0.63 %."""
    drive = DriveUnderTest.from_roller(load_rollers()[3], law=SlipLaw.PINCH, k_p=0.0063)
    rec = simulate_record(drive, pinch_force_n=80.0, speed_mm_s=1.0, repeat=0,
                          rng=np.random.default_rng(9))
    res = analyse_record(rec)
    assert res.slip is not None
    # 4 standard errors of the regression
    assert 100 * res.slip.gradient_per_n == pytest.approx(
        0.335, abs=4 * 100 * res.slip.stderr_per_n)
    assert 100 * res.slip.offset == pytest.approx(0.63, abs=0.2)
    assert res.slip.r_squared > 0.9  # "good coefficients of determination" [000 Fig. 9b]


def test_short_or_flat_records_raise_with_the_reason() -> None:
    t = np.arange(5, dtype=np.float64) * 0.02
    short = Record(RecordKey("t", 80.0, 1.0, 0), t, np.ones(5), 4.0 * t, np.full(5, 80.0),
                   source="stand.csv", first_line=17)
    with pytest.raises(CalibrationError, match="too short") as info:
        analyse_record(short)
    assert info.value.source == "stand.csv" and info.value.line == 17
    t = np.arange(50, dtype=np.float64) * 0.02
    flat = Record(RecordKey("t", 80.0, 1.0, 0), t, np.ones(50), np.full(50, 3.0),
                  np.full(50, 80.0))
    with pytest.raises(CalibrationError, match="does not vary"):
        slip_regression(flat, 49)
    force = np.random.default_rng(1).normal(size=50) + np.linspace(0.0, 0.5, 50)
    noisy = Record(RecordKey("t", 10.0, 1.0, 0), t, np.ones(50), force.astype(np.float64),
                   np.full(50, 10.0))
    with pytest.raises(CalibrationError, match="too small next to the load-cell noise"):
        analyse_record(noisy)
    # in a batch such records are kept, with the reason, and without a slope
    (res,) = analyse_records([noisy])
    assert res.slip is None and "load-cell noise" in (res.slip_problem or "")
    with pytest.raises(CalibrationError, match="no slip gradient"):
        _ = res.slip_gradient_per_n


def test_instrument_noise_controls_r_squared() -> None:
    """R² falls with the encoder noise relative to the speed (Fig. 9b's spread)."""
    drive = DriveUnderTest.from_roller(load_rollers()[3], law=SlipLaw.PINCH)
    r2 = {}
    for v in (0.5, 15.0):
        rec = simulate_record(drive, pinch_force_n=80.0, speed_mm_s=v, repeat=0,
                              rng=np.random.default_rng(2), instrument=Instrument())
        res = analyse_record(rec)
        assert res.slip is not None
        r2[v] = res.slip.r_squared
    assert r2[15.0] > 0.99 > r2[0.5] > 0.5
