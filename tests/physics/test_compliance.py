"""Column compliance against [002] and the Bowden tube model (Lubinski helical buckling)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from flowtwin.errors import ProfileError
from flowtwin.physics.compliance import (
    bowden_compliance_mm_per_n,
    compliance_mm_per_n,
    compression_mm,
    helical_buckling_compliance_mm_per_n,
    tube_stretch_compliance_mm_per_n,
)

AREA = np.pi * 1.75 ** 2 / 4


def test_compression_is_sum_of_cold_and_hot_parts_002() -> None:
    # [002]: dl_RT = F/A·l_RT/E_RT, dl_hot = F/A·l_hot/E_hot, dl_total = their sum.
    force = np.array([0.0, 5.0, 20.0])
    dl_rt = force / AREA * 40.0 / 3500.0
    dl_hot = force / AREA * 10.0 / 400.0
    k = compliance_mm_per_n(AREA, 40.0, 3500.0, 10.0, 400.0)
    assert_allclose(compression_mm(force, k), dl_rt + dl_hot, rtol=1e-14)


def test_hot_term_dominates_for_soft_hot_modulus() -> None:
    # [002]: "the term for the room temperature is negligible for the most materials".
    k_total = compliance_mm_per_n(AREA, 40.0, 3500.0, 10.0, 20.0)
    k_cold = compliance_mm_per_n(AREA, 40.0, 3500.0, 0.0, 20.0)
    assert float(k_cold / k_total) < 0.03


def test_tube_stretch_formula() -> None:
    # PTFE 4/2 mm tube, 500 mm long, E = 500 MPa: L/(E·π(16 − 4)/4) mm/N.
    k = tube_stretch_compliance_mm_per_n(500.0, 4.0, 2.0, 500.0)
    assert float(k) == pytest.approx(500.0 / (500.0 * np.pi * 12.0 / 4.0), rel=1e-14)


def test_helical_buckling_matches_helix_geometry() -> None:
    # Independent check of the linearised Lubinski law: build the helix of pitch
    # p = sqrt(8π²EI/F) with radius e and take its exact axial shortening per length,
    # 1 − p/sqrt(p² + (2πe)²). Small helix angles (e ≪ p), so 1 % agreement.
    d, bore, e_mod, length = 1.75, 2.0, 3500.0, 500.0
    e = (bore - d) / 2
    inertia = np.pi * d ** 4 / 64
    forces = np.array([1.0, 5.0, 20.0])
    pitch = np.sqrt(8 * np.pi ** 2 * e_mod * inertia / forces)
    exact = length * (1 - pitch / np.sqrt(pitch ** 2 + (2 * np.pi * e) ** 2))
    k = helical_buckling_compliance_mm_per_n(length, bore, d, e_mod)
    assert_allclose(k * forces, exact, rtol=0.01)
    assert float(helical_buckling_compliance_mm_per_n(length, d, d, e_mod)) == 0.0


def test_bowden_total_is_sum_and_bad_geometry_raises() -> None:
    total = bowden_compliance_mm_per_n(500.0, 4.0, 2.0, 500.0, 1.75, 3500.0)
    parts = tube_stretch_compliance_mm_per_n(500.0, 4.0, 2.0, 500.0) + \
        helical_buckling_compliance_mm_per_n(500.0, 2.0, 1.75, 3500.0)
    assert float(total) == pytest.approx(float(parts), rel=1e-14)
    with pytest.raises(ProfileError, match="tube_outer_diameter_mm"):
        tube_stretch_compliance_mm_per_n(500.0, 2.0, 2.0, 500.0)
    with pytest.raises(ProfileError, match="tube_inner_diameter_mm"):
        helical_buckling_compliance_mm_per_n(500.0, 1.7, 1.75, 3500.0)
    with pytest.raises(ProfileError, match="e_hot_mpa"):
        compliance_mm_per_n(AREA, 40.0, 3500.0, 10.0, 0.0)
