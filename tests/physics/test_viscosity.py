"""Viscosity laws: the exponential law of [002], Arrhenius and WLF alternatives."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from flowtwin.errors import ProfileError
from flowtwin.physics.defaults import PLA_4043D as PLA
from flowtwin.physics.viscosity import (
    arrhenius_energy_from_two_points,
    exponential_law_from_two_points,
    viscosity_arrhenius_pa_s,
    viscosity_exponential_pa_s,
    viscosity_wlf_pa_s,
)


def test_exponential_law_definition_and_ratio() -> None:
    t = np.array([180.0, 200.0, 240.0])
    assert_allclose(viscosity_exponential_pa_s(t, 3.0e7, 0.05), 3.0e7 * np.exp(-0.05 * t))
    # The ratio over a fixed step is the same at every temperature: exp(−b·ΔT).
    mu = viscosity_exponential_pa_s(t, 3.0e7, 0.05)
    assert_allclose(viscosity_exponential_pa_s(t + 10.0, 3.0e7, 0.05) / mu, np.exp(-0.5))


def test_two_point_helpers_round_trip() -> None:
    mu0, b = exponential_law_from_two_points(190.0, 1000.0, 220.0, 200.0)
    assert_allclose(viscosity_exponential_pa_s([190.0, 220.0], mu0, b), [1000.0, 200.0])
    ea = arrhenius_energy_from_two_points(190.0, 1000.0, 220.0, 200.0)
    assert_allclose(viscosity_arrhenius_pa_s([190.0, 220.0], 1000.0, 190.0, ea),
                    [1000.0, 200.0])
    with pytest.raises(ProfileError, match="falling viscosity"):
        exponential_law_from_two_points(190.0, 200.0, 220.0, 1000.0)


def test_default_pla_matches_001_range() -> None:
    # [001]: PLA "approximately 200 to 1000 Pa·s at 220 °C–190 °C". Stored constants are
    # rounded to 5 significant digits, hence 1e-3.
    mu = viscosity_exponential_pa_s([190.0, 220.0], PLA.mu0_pa_s, PLA.b_per_c)
    assert_allclose(mu, [1000.0, 200.0], rtol=1e-3)
    mu_a = viscosity_arrhenius_pa_s([190.0, 220.0], PLA.arrhenius_mu_ref_pa_s,
                                    PLA.arrhenius_t_ref_c, PLA.arrhenius_ea_j_mol)
    assert_allclose(mu_a, [1000.0, 200.0], rtol=1e-3)


def test_wlf_law() -> None:
    assert float(viscosity_wlf_pa_s(100.0, 5.0e4, 100.0, 17.44, 51.6)) == pytest.approx(5.0e4)
    mu = viscosity_wlf_pa_s([190.0, 215.0, 220.0], PLA.wlf_mu_ref_pa_s, PLA.wlf_t_ref_c,
                            PLA.wlf_c1, PLA.wlf_c2_k)
    expo = viscosity_exponential_pa_s(215.0, PLA.mu0_pa_s, PLA.b_per_c)
    assert mu[1] == pytest.approx(float(expo), rel=1e-3)
    # With the universal constants about T_g the 190/220 °C ratio is 4.6, against the
    # factor 5 of [001]'s range: within 10 %.
    assert mu[0] / mu[2] == pytest.approx(5.0, rel=0.1)
    with pytest.raises(ProfileError, match="WLF singularity"):
        viscosity_wlf_pa_s(0.0, 1.0, 55.0, 17.44, 51.6)


def test_arrhenius_at_reference_and_monotone() -> None:
    t = np.linspace(180.0, 240.0, 13)
    mu = viscosity_arrhenius_pa_s(t, 500.0, 200.0, 1.0e5)
    assert mu[4] == pytest.approx(500.0)
    assert np.all(np.diff(mu) < 0)
