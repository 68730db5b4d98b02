"""fit-slip: the test stand's evaluation of a records file as a drive-profile fragment."""

from __future__ import annotations

import tomllib
from dataclasses import replace
from pathlib import Path

import pytest

from flowtwin.calibration.fits.slipfit import fit_slip_records
from flowtwin.errors import CalibrationError, DataError
from flowtwin.profiles import load_rollers
from flowtwin.profiles.toml_io import profile_from_toml
from flowtwin.teststand import (
    DriveUnderTest,
    Instrument,
    Procedure,
    SlipLaw,
    analyse_campaign,
    analyse_records,
    read_records_csv,
    simulate_campaign,
    write_records_csv,
)

#: A small campaign (6 pinch forces × 6 speeds × 2 repeats at 25 samples/s): enough for
#: Eq. 6 and Eq. 8, a tenth of [000 §3]'s grid.
PROCEDURE = Procedure(pinch_forces_n=(40.0, 60.0, 80.0, 100.0, 120.0, 140.0),
                      speeds_mm_s=(0.5, 1.0, 2.0, 5.0, 10.0, 15.0), repeats=2)
INSTRUMENT = Instrument(sample_rate_hz=25.0)
K_P = 0.0063          # [000 Fig. 9a]: 0.63 % on the stand


def _records(tmp: Path, law: SlipLaw, seed: int, roller_id: str | None = None,
             procedure: Procedure = PROCEDURE) -> Path:
    drive = DriveUnderTest.from_roller(load_rollers()[3], law=law, k_p=K_P,
                                       roller_id=roller_id)
    path = tmp / f"{law.value}-{seed}-{roller_id}.csv"
    write_records_csv(path, simulate_campaign(drive, seed=seed, procedure=procedure,
                                              instrument=INSTRUMENT))
    return path


@pytest.fixture(scope="module")
def pinch_records(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Roller #3 with the pinch-force law of [000 Eq. 6] (k_s 96 %·N, k_∞ 0.32 %/N)."""
    return _records(tmp_path_factory.mktemp("stand"), SlipLaw.PINCH, seed=1)


def test_fit_is_the_test_stands_and_recovers_the_roller(pinch_records: Path) -> None:
    cal = fit_slip_records(pinch_records)
    reference = analyse_campaign(analyse_records(read_records_csv(pinch_records)))
    values, errors = cal.overrides()
    assert reference.pinch_law is not None
    # wired, not re-fitted: the numbers are the test stand's own
    assert values["k_s_pct_N"] == pytest.approx(100 * reference.pinch_law.k_s_n, rel=1e-12)
    assert errors["k_inf_pct_per_N"] == pytest.approx(
        100 * reference.pinch_law.k_inf_err_per_n, rel=1e-12)
    # and they recover what the virtual stand simulated (3σ)
    assert abs(values["k_s_pct_N"] - 96.0) <= 3 * errors["k_s_pct_N"]
    assert abs(values["k_inf_pct_per_N"] - 0.32) <= 3 * errors["k_inf_pct_per_N"]
    assert abs(cal.k_p_pct - 100 * K_P) <= 3 * cal.k_p_err_pct
    assert "a_pct_per_N" not in values         # Eq. 6 law: no velocity dependence found


def test_fragment_is_a_drive_profile(pinch_records: Path) -> None:
    cal = fit_slip_records(pinch_records)
    text = cal.fragment()
    parsed = tomllib.loads(text)
    assert parsed["k_p_pct"] == pytest.approx(cal.k_p_pct, abs=1e-6)
    assert set(parsed["slip_overrides"]) == {"k_s_pct_N", "k_inf_pct_per_N"}
    assert "maximum feed force" in text and "± " in text
    base = (Path(__file__).resolve().parents[2] / "src/flowtwin/data/drives/"
            "hobb-goblin-80n.toml").read_text()
    base = "\n".join(ln for ln in base.splitlines() if not ln.startswith("k_p_pct"))
    drive = profile_from_toml(base + "\n" + text, "drive")
    roller = drive.resolve_roller(load_rollers())   # type: ignore[union-attr]
    assert roller.k_s_pct_N == pytest.approx(parsed["slip_overrides"]["k_s_pct_N"])
    assert drive.k_p == pytest.approx(parsed["k_p_pct"] / 100)   # type: ignore[union-attr]


def test_velocity_law_and_an_undetermined_k_s(tmp_path: Path) -> None:
    """With the velocity law [000 Eq. 8] the slip gradient does not depend on the pinch
    force: k_s is zero within its error, which the fragment must not hide."""
    path = _records(tmp_path, SlipLaw.VELOCITY, seed=1)
    cal = fit_slip_records(path)
    values, errors = cal.overrides()
    assert abs(values["a_pct_per_N"] - 0.24) <= 3 * errors["a_pct_per_N"]
    assert abs(values["c_s_per_mm"] - 0.32) <= 3 * errors["c_s_per_mm"]
    assert abs(values["k_s_pct_N"]) <= 3 * errors["k_s_pct_N"]
    # this seed: k_s = 1.0 ± 3.5 %·N, positive but not determined -> said in the fragment
    assert 0.0 < values["k_s_pct_N"] < errors["k_s_pct_N"]
    assert "do not determine k_s_pct_N" in cal.fragment()
    # the same scatter may give a negative k_s, which no drive profile takes
    pl = cal.analysis.pinch_law
    assert pl is not None
    negative = replace(cal, analysis=replace(cal.analysis, pinch_law=replace(
        pl, k_s_n=-pl.k_s_n)))
    with pytest.raises(CalibrationError,
                       match=r"\[k_s_pct_N\]: the fitted slip law is not a valid drive"):
        negative.fragment()


def test_rollers_in_one_file(tmp_path: Path, pinch_records: Path) -> None:
    other = _records(tmp_path, SlipLaw.PINCH, seed=2, roller_id="B7",
                     procedure=Procedure(pinch_forces_n=(40.0, 80.0, 120.0),
                                         speeds_mm_s=(1.0, 5.0), repeats=1))
    both = tmp_path / "both.csv"
    both.write_text(pinch_records.read_text() + "".join(
        ln + "\n" for ln in other.read_text().splitlines()
        if ln and not ln.startswith("#") and not ln.startswith("roller_id")))
    with pytest.raises(DataError, match="several rollers"):
        fit_slip_records(both)
    with pytest.raises(DataError, match="no records of that roller"):
        fit_slip_records(both, roller_id="9")
    assert fit_slip_records(both, roller_id="B7").analysis.roller_id == "B7"
