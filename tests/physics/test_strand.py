"""Strand curves of [004 Eqs. 1–7] and their least-squares fit."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from flowtwin.errors import DataError
from flowtwin.physics.strand import (
    StrandModel,
    catenary_z_mm,
    fit_strand_profile,
    parabola_z_mm,
    tractrix_contact_length_mm,
    tractrix_x_mm,
    tractrix_z_mm,
)

H = 0.012   # [004]: layer height / nozzle height in the measurement and simulations
L = 0.06    # [004 Fig. 7]


def test_tractrix_eq5_starts_at_nozzle_and_has_eq1_slope() -> None:
    assert float(tractrix_x_mm(H, H)) == 0.0
    z = np.linspace(0.1 * H, 0.9 * H, 9)
    dz = 1e-7 * H
    slope = (tractrix_x_mm(z + dz, H) - tractrix_x_mm(z - dz, H)) / (2 * dz)
    assert_allclose(slope, -np.sqrt(H ** 2 - z ** 2) / z, rtol=1e-6)      # [004 Eq. 1]


def test_tractrix_tangent_to_bed_has_constant_length_h() -> None:
    # Defining property of the tractrix [004 Eqs. 1–4]: the tangent from any point to
    # the asymptote (the bed) has length H.
    z = np.linspace(0.05 * H, 0.95 * H, 10)
    dxdz = -np.sqrt(H ** 2 - z ** 2) / z
    length = np.hypot(z, z * dxdz)
    assert_allclose(length, H, rtol=1e-12)


def test_tractrix_inverse_round_trip() -> None:
    z = np.geomspace(1e-6 * H, H, 50)
    assert_allclose(tractrix_z_mm(tractrix_x_mm(z, H), H), z, rtol=1e-10)
    assert float(tractrix_z_mm(-1.0, H)) == pytest.approx(H)
    with pytest.raises(DataError, match="0 < z <= H"):
        tractrix_x_mm(2 * H, H)


def test_tractrix_contact_length_matches_fig7_pair() -> None:
    # With H = 0.012 mm the tractrix has sunk to 0.5 % of H after 4.99·H = 0.0599 mm,
    # the L = 0.06 mm that [004 Fig. 7] uses with that H (1 %: L is printed to 2 digits).
    assert float(tractrix_contact_length_mm(H)) == pytest.approx(L, rel=0.01)
    assert float(tractrix_z_mm(tractrix_contact_length_mm(H), H)) == pytest.approx(0.005 * H)


def test_parabola_eq6_and_catenary_eq7() -> None:
    x = np.linspace(0.0, L, 11)
    z = parabola_z_mm(x, H, L)
    assert z[0] == pytest.approx(H)
    assert z[-1] == 0.0
    assert float(parabola_z_mm(2 * L, H, L)) == 0.0                  # on the bed beyond L
    cat = catenary_z_mm(x, a_mm=0.01, b_mm=0.03, length_mm=L, height_mm=H)
    assert cat[0] == pytest.approx(H)
    assert np.all(np.diff(cat) < 0)
    # The catenary tends to the parabola as b → ∞ with a = 2H·b²/L² (cosh ≈ 1 + u²/2).
    b = 100.0 * L
    flat = catenary_z_mm(x, a_mm=2 * H * b ** 2 / L ** 2, b_mm=b, length_mm=L, height_mm=H)
    assert_allclose(flat, z, atol=1e-3 * H)


def _measured_tractrix(noise_fraction: float) -> tuple[np.ndarray, np.ndarray]:
    # [004] sampled 240 points of the strand between z = 0 and z = H; synthesise them
    # from a tractrix and add seeded reading noise.
    rng = np.random.default_rng(2009)
    z = np.linspace(0.02 * H, H, 240)
    x = tractrix_x_mm(z, H)
    return x, z + rng.normal(0.0, noise_fraction * H, z.size)


def test_fit_recovers_tractrix_and_ranks_it_best() -> None:
    x, z = _measured_tractrix(0.01)
    fits = {m: fit_strand_profile(x, z, model=m, height_mm=H) for m in StrandModel}
    tr = fits[StrandModel.TRACTRIX]
    # 1 % noise on 240 points: r recovered to 2 %, shift to 2 % of H.
    assert tr.params["r_mm"] == pytest.approx(H, rel=0.02)
    assert abs(tr.params["shift_mm"]) < 0.02 * H
    assert tr.rms_mm == pytest.approx(0.01 * H, rel=0.2)
    ranked = sorted(fits.values(), key=lambda f: f.rms_mm)
    assert ranked[0].model is StrandModel.TRACTRIX                 # [004 Fig. 3]
    assert fits[StrandModel.PARABOLA].rms_mm > fits[StrandModel.CATENARY].rms_mm
    assert_allclose(tr.z_mm(x), tractrix_z_mm(x - tr.params["shift_mm"], tr.params["r_mm"]))


def test_fit_recovers_parabola_and_catenary_parameters() -> None:
    x = np.linspace(0.0, 1.2 * L, 120)
    par = fit_strand_profile(x, parabola_z_mm(x, H, L), model=StrandModel.PARABOLA,
                             height_mm=H)
    assert par.params["length_mm"] == pytest.approx(L, rel=1e-6)
    assert par.rms_mm < 1e-9 * H
    xs = np.linspace(0.0, L, 120)
    zc = catenary_z_mm(xs, a_mm=0.004, b_mm=0.02, length_mm=L, height_mm=H)
    cat = fit_strand_profile(xs, zc, model=StrandModel.CATENARY, height_mm=H)
    assert cat.rms_mm < 1e-6 * H
    assert_allclose(cat.z_mm(xs), zc, atol=1e-6 * H)


def test_fit_rejects_bad_profiles() -> None:
    with pytest.raises(DataError, match="equal length"):
        fit_strand_profile(np.arange(5.0), np.arange(4.0), model=StrandModel.PARABOLA,
                           height_mm=H)
    with pytest.raises(DataError, match="non-finite"):
        fit_strand_profile(np.array([0.0, 1.0, np.nan]), np.zeros(3),
                           model=StrandModel.PARABOLA, height_mm=H)
