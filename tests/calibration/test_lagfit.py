"""Lag fit (fit-k): known answers from the twin with seeded noise, degenerate data, files."""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

from flowtwin.calibration.csvdata import read_table_text
from flowtwin.calibration.fits.kfit import fit_k, kline_for_machine
from flowtwin.calibration.fits.lagfit import (
    PROFILE_COLUMNS,
    WidthProfile,
    fit_lag,
    profiles_from_table,
    read_width_profiles,
)
from flowtwin.calibration.fits.lagmodel import LagModel, LagParams, lag_model, printed_runs
from flowtwin.calibration.patterns.kline import KLineParams
from flowtwin.calibration.patterns.pattern import Pattern, PrintSettings
from flowtwin.errors import CalibrationError, DataError
from flowtwin.profiles.machine import Machine, load_machine
from flowtwin.profiles.printer import PressureAdvance

#: Width samples every 0.25 mm along the 80 mm line (a microscope stage's step).
X = np.arange(0.0, 80.001, 0.25)
#: Scatter of a width measurement, mm (a 600 dpi scan resolves ~0.01 mm on an edge pair).
NOISE_MM = 0.01


@pytest.fixture(scope="module")
def machine() -> Machine:
    return load_machine("tronvoll2019")


@pytest.fixture(scope="module")
def line(machine: Machine) -> tuple[Pattern, LagModel]:
    """One K-line printed without advance on Tronvoll's printer [001 Table I]."""
    p = kline_for_machine(machine, PrintSettings(), KLineParams(k_start=0.0, k_end=0.0,
                                                                mark_every=0))
    return p, lag_model(p.text().encode(), [p.segments[0].line], machine=machine)


def _measured(model: LagModel, truth: LagParams, seed: int) -> WidthProfile:
    w = model.widths(truth, [X])[0]
    return WidthProfile(X, w + np.random.default_rng(seed).normal(0.0, NOISE_MM, X.size))


def test_known_lag_is_recovered_within_its_uncertainty(line: tuple[Pattern, LagModel]
                                                       ) -> None:
    model = line[1]
    fit = fit_lag(model, [_measured(model, LagParams(0.045), seed=7)])
    # 3σ: a correct estimator with a correct σ misses this 0.3 % of the time
    assert abs(fit.k_s - 0.045) <= 3.0 * fit.k_err_s
    assert fit.k_err_s < 0.05 * 0.045          # a useful measurement, not a shrug
    assert fit.rms_mm == pytest.approx(NOISE_MM, rel=0.15)
    assert fit.n_points + fit.n_excluded == X.size
    assert fit.machine_lag_s == pytest.approx(0.06, abs=0.002)   # docs/spec.md §4 default


def test_reported_uncertainty_matches_the_scatter(line: tuple[Pattern, LagModel]) -> None:
    model = line[1]
    est, err = [], []
    for seed in range(12):
        fit = fit_lag(model, [_measured(model, LagParams(0.06), seed=100 + seed)])
        est.append(fit.k_s)
        err.append(fit.k_err_s)
    e = np.array(est)
    s = np.array(err)
    # 12 draws: the sample standard deviation is known to ±20 % (1σ), so the ratio of the
    # scatter to the reported σ must lie within 0.6–1.6 (2.5σ either way)
    assert 0.6 <= float(np.std(e, ddof=1) / np.mean(s)) <= 1.6
    # within 1σ: expected 68 %; binomial(12, 0.68) gives >= 4 hits with 99.5 % probability
    assert int(np.sum(np.abs(e - 0.06) <= s)) >= 4
    assert abs(float(np.mean(e)) - 0.06) <= 3.0 * float(np.mean(s)) / np.sqrt(12)


def test_dead_time_and_gain_are_recovered(line: tuple[Pattern, LagModel]) -> None:
    model = line[1]
    truth = LagParams(0.05, dead_time_s=0.012, gain=0.96)
    fit = fit_lag(model, [_measured(model, truth, seed=3)], fit_dead_time=True,
                  fit_gain=True)
    assert fit.fitted == ("k_s", "dead_time_s", "gain")
    for name, value in (("k_s", 0.05), ("dead_time_s", 0.012), ("gain", 0.96)):
        assert abs(getattr(fit.params, name) - value) <= 3.0 * fit.stderr[name], name
    corr = fit.correlation()
    assert corr.shape == (3, 3) and np.allclose(np.diag(corr), 1.0)


def test_no_dead_time_is_a_valid_answer(line: tuple[Pattern, LagModel]) -> None:
    model = line[1]
    fit = fit_lag(model, [_measured(model, LagParams(0.05), seed=4)], fit_dead_time=True)
    assert fit.params.dead_time_s <= 3.0 * fit.stderr["dead_time_s"] + 1e-12
    assert abs(fit.k_s - 0.05) <= 3.0 * fit.k_err_s


def test_a_line_at_one_speed_does_not_determine_the_lag(machine: Machine,
                                                        line: tuple[Pattern, LagModel]
                                                        ) -> None:
    p = line[0]
    text = p.text().encode()
    prime = lag_model(text, [printed_runs(lag_model(text, None, machine=machine).plan)[0]],
                      machine=machine)
    assert np.ptp(prime.lines[0].cruise_mm_s) == 0.0          # the prime line: 20 mm/s
    w = prime.widths(LagParams(0.05), [X])[0]
    noisy = WidthProfile(X, w + np.random.default_rng(1).normal(0.0, NOISE_MM, X.size))
    # the start transient lasts a few lags (K·v = 1–4 mm each for K = 0.05–0.2 s at
    # 20 mm/s); 15 mm past the start the widths can at most say "K is not large", and the
    # fit must say so instead of returning a number
    with pytest.raises(CalibrationError, match=r"do not (depend|determine)|bound of k_s"):
        fit_lag(prime, [noisy], end_margin_mm=15.0)


def test_bad_profiles(line: tuple[Pattern, LagModel]) -> None:
    model = line[1]
    with pytest.raises(CalibrationError, match="usable width samples"):
        fit_lag(model, [WidthProfile(np.array([0.1, 0.2, 79.9]), np.array([0.5, 0.5, 0.5]))])
    with pytest.raises(DataError, match="beyond the end of the test line"):
        fit_lag(model, [WidthProfile(np.array([10.0, 81.0]), np.array([0.5, 0.5]))])
    with pytest.raises(CalibrationError, match="one width profile per test line"):
        fit_lag(model, [])
    with pytest.raises(DataError, match="equal length"):
        WidthProfile(np.zeros(3), np.zeros(4))


def test_fragment_and_adaptive_row(line: tuple[Pattern, LagModel]) -> None:
    model = line[1]
    fit = fit_lag(model, [_measured(model, LagParams(0.05), seed=5)], fit_gain=True)
    text = fit.fragment(header=["test"])
    table = tomllib.loads(text)["pressure_advance"]
    assert table["k_s"] == pytest.approx(fit.k_s, abs=1e-6)
    assert PressureAdvance.model_validate(table).k_s == table["k_s"]
    assert "flow gain" in text and "± " in text
    # the gain's comment says which way it points: the measured widths 1.3x the twin's
    wide = fit_lag(model, [_measured(model, LagParams(0.05, gain=1.3), seed=5)],
                   fit_gain=True)
    assert wide.params.gain == pytest.approx(1.3, rel=0.02)
    assert "(> 1: beads wider than the twin's" in wide.fragment()
    assert ("(< 1: under-extrusion" in text) == (fit.params.gain < 1.0)
    row = fit.measurement_row()
    assert row["k_s"] == fit.k_s and row["k_err_s"] == fit.k_err_s
    assert row["accel_mm_s2"] == 1000.0          # Prusa MK2.5 printing acceleration
    assert row["flow_mm3_s"] == pytest.approx(model.lines[0].flow_mm3_s)


def test_profile_file_with_several_lines(tmp_path: Path) -> None:
    text = ("# two lines\nposition_mm,width_mm,gcode_line\n1,0.5,34\n2,0.49,34\n3,0.48,34\n"
            "1,0.5,45\n2,0.5,45\n")
    profs = profiles_from_table(read_table_text(text, PROFILE_COLUMNS))
    assert list(profs) == [34, 45]
    assert profs[34].widths_mm.tolist() == [0.5, 0.49, 0.48]
    with pytest.raises(DataError, match="whole line number"):
        profiles_from_table(read_table_text("position_mm,width_mm,gcode_line\n1,0.5,3.5\n",
                                            PROFILE_COLUMNS))
    bad = tmp_path / "p.csv"
    bad.write_text("position_mm,width_um\n1,480\n2,480\n3,480\n")
    with pytest.raises(DataError, match=r"p\.csv:1 \[width_um\]: unknown column"):
        read_width_profiles(bad)


def test_fit_k_from_the_gcode_or_the_kline_options(machine: Machine,
                                                   line: tuple[Pattern, LagModel]) -> None:
    p, model = line
    prof = _measured(model, LagParams(0.05), seed=9)
    by_file, _ = fit_k({p.segments[0].line: prof}, gcode=p.text().encode(), machine=machine)
    by_options, m2 = fit_k([prof], k_la_s=0.0, machine=machine)
    # the same G-code either way: the same answer
    assert by_file.k_s == pytest.approx(by_options.k_s, rel=1e-9)
    assert m2.lines[0].advance_k_s == 0.0
    with pytest.raises(CalibrationError, match="need the G-code file"):
        fit_k([prof], gcode_lines=[34], machine=machine)
    with pytest.raises(CalibrationError, match="names its G-code lines"):
        fit_k({34: prof}, gcode=p.text().encode(), gcode_lines=[34], machine=machine)
    with pytest.raises(CalibrationError, match="first move"):
        fit_k([prof], gcode=p.text().encode(), machine=machine)
