"""Strand-shape fits [004]: known answers with seeded noise, model choice, degeneracy."""

from __future__ import annotations

import numpy as np
import pytest

from flowtwin.calibration.csvdata import read_table_text
from flowtwin.calibration.fits.strand_fit import STRAND_COLUMNS, fit_strand, strand_points
from flowtwin.errors import CalibrationError, DataError
from flowtwin.physics.strand import (
    StrandModel,
    parabola_z_mm,
    tractrix_contact_length_mm,
    tractrix_z_mm,
)

#: |estimate − truth| <= 3 reported σ (probability of a miss ~0.3 % for a correct
#: estimator; seeds fixed).
K_SIGMA = 3.0


def test_tractrix_known_answer_within_uncertainty() -> None:
    rng = np.random.default_rng(7)
    r, shift, noise = 0.32, 0.05, 0.003
    x = np.linspace(0.0, 2.0, 40)
    z = np.clip(tractrix_z_mm(x - shift, r) + rng.normal(0.0, noise, x.size), 0.0, None)
    cal = fit_strand(x, z, height_mm=0.3)
    assert cal.fit.model is StrandModel.TRACTRIX          # [004]: the tractrix fits best
    assert abs(cal.fit.params["r_mm"] - r) <= K_SIGMA * cal.stderr["r_mm"]
    assert abs(cal.fit.params["shift_mm"] - shift) <= K_SIGMA * cal.stderr["shift_mm"]
    lag = float(tractrix_contact_length_mm(r)) + shift
    assert abs(cal.lag_mm - lag) <= K_SIGMA * cal.lag_stderr_mm
    assert cal.fit.rms_mm == pytest.approx(noise, rel=0.3)
    assert cal.rms_by_model["tractrix"] < cal.rms_by_model["parabola"]


def test_parabola_known_answer_and_model_choice() -> None:
    rng = np.random.default_rng(2)
    length = 1.2
    x = np.linspace(0.0, 2.0, 40)
    z = parabola_z_mm(x, 0.3, length) + rng.normal(0.0, 0.003, x.size)
    cal = fit_strand(x, z, height_mm=0.3)
    # the catenary bends a little closer to the points, but with two more parameters
    assert cal.fit.model is StrandModel.PARABOLA
    assert cal.bic_by_model["parabola"] < cal.bic_by_model["catenary"]
    assert abs(cal.fit.params["length_mm"] - length) <= K_SIGMA * cal.stderr["length_mm"]
    assert cal.lag_mm == cal.fit.params["length_mm"]


def test_jin_fig7_height_and_lag() -> None:
    # [004 Fig. 7] pairs H = 0.012 with L = 0.06: a noiseless tractrix of tangent length H
    # reaches 0.5 % of H at 4.99·H = 0.060
    x = np.linspace(0.0, 0.1, 30)
    z = tractrix_z_mm(x, 0.012) * (1.0 + 1e-4 * np.sin(7.0 * x / 0.1))   # tiny scatter
    cal = fit_strand(x, z, height_mm=0.012, model=StrandModel.TRACTRIX)
    assert cal.fit.params["r_mm"] == pytest.approx(0.012, rel=1e-3)
    assert cal.lag_mm == pytest.approx(0.060, abs=5e-4)


def test_profile_that_never_reaches_the_bed() -> None:
    x = np.linspace(0.0, 0.6, 20)
    z = parabola_z_mm(x, 0.3, 1.2)          # stops at half the bed contact
    with pytest.raises(CalibrationError, match="does not reach the bed"):
        fit_strand(x, z, height_mm=0.3, model=StrandModel.PARABOLA)


def test_too_few_points() -> None:
    with pytest.raises(DataError, match="at least 4 points"):
        fit_strand([0.0, 0.1, 0.2], [0.3, 0.2, 0.1], height_mm=0.3)


def test_points_from_csv() -> None:
    table = read_table_text("x_mm,z_mm\n0,0.3\n0.5,0.1\n1,0.02\n1.5,0\n", STRAND_COLUMNS)
    x, z = strand_points(table)
    assert x.tolist() == [0.0, 0.5, 1.0, 1.5]
    assert z.tolist() == [0.3, 0.1, 0.02, 0.0]
    with pytest.raises(DataError, match=r"\[z_mm\]"):
        read_table_text("x_mm,z_mm\n0,-0.1\n", STRAND_COLUMNS)
