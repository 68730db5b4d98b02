"""Melt-zone heat transfer against its sources: the cylinder series (Carslaw & Jaeger 1959
§7.4) checked by an independent finite-volume solution, the Fourier number of the
residence (Mackay et al. 2017), the relaxation, the melt capacity and the fitted factor."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.special import jn_zeros

from flowtwin.errors import ProfileError
from flowtwin.physics import defaults
from flowtwin.physics.melt import (
    J0_ZEROS,
    bulk_temperature_fraction,
    melt_fourier_number,
    melt_relaxation,
    melt_temperature_per_move,
    melt_time_constant_s,
    steady_melt_temperature_c,
    thermal_diffusivity_mm2_s,
)
from flowtwin.physics.melt_capacity import (
    fit_melt_length_factor,
    melt_capacity_mm3_s,
    melt_fourier_at_fraction,
)
from flowtwin.physics.viscosity import viscosity_exponential_pa_s


def _finite_volume_theta(fo_end: float, n: int = 400, steps: int = 40000) -> float:
    """Bulk θ of a cylinder (radius 1, α = 1) whose surface is held at 0 from θ = 1:
    cell-centred finite volumes in r, Crank–Nicolson in time; independent of the series."""
    dr = 1.0 / n
    rc = (np.arange(n) + 0.5) * dr
    rf = np.arange(n + 1) * dr
    vol = rc * dr
    a = np.zeros((n, n))
    for i in range(n):
        if i > 0:
            a[i, i - 1] += rf[i] / dr / vol[i]
            a[i, i] -= rf[i] / dr / vol[i]
        if i < n - 1:
            a[i, i + 1] += rf[i + 1] / dr / vol[i]
            a[i, i] -= rf[i + 1] / dr / vol[i]
        else:  # wall at 0, half a cell away
            a[i, i] -= rf[n] / (dr / 2.0) / vol[i]
    dt = fo_end / steps
    eye = np.eye(n)
    step = np.linalg.solve(eye - 0.5 * dt * a, eye + 0.5 * dt * a)
    theta = np.ones(n)
    for _ in range(steps):
        theta = step @ theta
    return float(np.sum(theta * vol) / np.sum(vol))


def test_j0_zeros_are_scipys() -> None:
    assert np.array(J0_ZEROS) == pytest.approx(jn_zeros(0, 40), rel=1e-15)


def test_series_sums_to_one_at_the_start_and_decays_on_the_first_mode() -> None:
    # Σ 4/λ_n² = 1 (θ_b(0) = 1); long times: θ_b → 4/λ_1²·exp(−λ_1² Fo)
    assert float(bulk_temperature_fraction(0.0)) == 1.0
    fo = 1.0
    assert float(bulk_temperature_fraction(fo)) == pytest.approx(
        4.0 / J0_ZEROS[0] ** 2 * math.exp(-J0_ZEROS[0] ** 2 * fo), rel=1e-12)
    assert float(bulk_temperature_fraction(math.inf)) == 0.0


def test_short_time_expansion_joins_the_series() -> None:
    lam = jn_zeros(0, 20000)
    for fo in (2.0e-4, 1.0e-3, 1.999e-3, 2.0e-3, 5.0e-3):
        exact = float(np.sum(4.0 / lam ** 2 * np.exp(-lam ** 2 * fo)))
        assert float(bulk_temperature_fraction(fo)) == pytest.approx(exact, abs=1e-6)


@pytest.mark.parametrize("fo", [0.02, 0.1, 0.4])
def test_series_against_finite_volume_solution(fo: float) -> None:
    assert float(bulk_temperature_fraction(fo)) == pytest.approx(_finite_volume_theta(fo),
                                                                 abs=2e-4)


def test_fourier_number_of_the_residence() -> None:
    # Fo = α t/R², t = πR²L/Q: the radius cancels
    alpha, length, q, r = 0.06, 12.0, 8.0, 0.875
    t_res = math.pi * r * r * length / q
    assert float(melt_fourier_number(q, diffusivity_mm2_s=alpha, heated_length_mm=length)) \
        == pytest.approx(alpha * t_res / r ** 2, rel=1e-14)
    assert float(melt_fourier_number(0.0, diffusivity_mm2_s=alpha,
                                     heated_length_mm=length)) == math.inf


def test_diffusivity_units() -> None:
    # 0.13 W/(m·K) / (1250 kg/m³ · 1800 J/(kg·K)) = 5.78e-8 m²/s = 0.0578 mm²/s
    assert float(thermal_diffusivity_mm2_s(0.13, 1.25, 1800.0)) == pytest.approx(0.057778,
                                                                                rel=1e-4)


def test_melt_temperature_falls_with_flow_and_recovers_at_rest() -> None:
    kw = {"wall_c": 215.0, "inlet_c": 25.0, "diffusivity_mm2_s": 0.0578,
          "heated_length_mm": 24.3}
    t = steady_melt_temperature_c(np.array([0.0, 2.0, 5.0, 10.0, 20.0]), **kw)
    assert t[0] == 215.0
    assert np.all(np.diff(t) < 0.0)
    assert 25.0 < t[-1] < 215.0


def test_time_constant_limits() -> None:
    alpha, length, r = 0.0578, 24.3, 0.875
    rest = float(melt_time_constant_s(0.0, diffusivity_mm2_s=alpha, heated_length_mm=length,
                                      filament_radius_mm=r))
    assert rest == pytest.approx(r * r / (J0_ZEROS[0] ** 2 * alpha), rel=1e-12)
    q = 1e6
    fast = float(melt_time_constant_s(q, diffusivity_mm2_s=alpha, heated_length_mm=length,
                                      filament_radius_mm=r))
    assert fast == pytest.approx(math.pi * r * r * length / q, rel=1e-4)


def test_relaxation_mean_is_the_integral() -> None:
    end, mean = melt_relaxation(200.0, 180.0, 0.7, 0.3)
    ts = np.linspace(0.0, 0.7, 200001)
    curve = 180.0 + 20.0 * np.exp(-ts / 0.3)
    assert float(end) == pytest.approx(curve[-1], rel=1e-14)
    assert float(mean) == pytest.approx(np.trapezoid(curve, ts) / 0.7, rel=1e-9)


def test_per_move_history_reaches_the_steady_state_and_is_exact_per_step() -> None:
    kw = {"inlet_c": 25.0, "diffusivity_mm2_s": 0.0578, "heated_length_mm": 24.3,
          "filament_radius_mm": 0.875}
    n = 50
    q = np.full(n, 12.0)
    dur = np.full(n, 1.0)
    gap = np.zeros(n)
    wall = np.full(n, 215.0)
    mean, end = melt_temperature_per_move(q, dur, gap, wall, **kw)
    steady = float(steady_melt_temperature_c(12.0, wall_c=215.0, inlet_c=25.0,
                                             diffusivity_mm2_s=0.0578, heated_length_mm=24.3))
    assert end == pytest.approx(steady, abs=1e-9)
    tau = float(melt_time_constant_s(12.0, diffusivity_mm2_s=0.0578, heated_length_mm=24.3,
                                     filament_radius_mm=0.875))
    e1, m1 = melt_relaxation(215.0, steady, 1.0, tau)
    assert mean[0] == pytest.approx(float(m1), rel=1e-14)
    # a rest after the moves brings the melt back towards the wall
    _, end2 = melt_temperature_per_move(q[:1], dur[:1], np.array([100.0]), wall[:1], **kw)
    assert end2 == pytest.approx(215.0, abs=1e-6)
    assert float(e1) < 215.0


def test_inverse_of_the_series() -> None:
    for theta in (0.9, 0.5, 0.068, 1e-3):
        fo = melt_fourier_at_fraction(theta)
        assert float(bulk_temperature_fraction(fo)) == pytest.approx(theta, rel=1e-10)
    with pytest.raises(ProfileError):
        melt_fourier_at_fraction(1.5)


def _pla(t: float) -> float:
    return float(viscosity_exponential_pa_s(t, 2.6718e7, 0.053648))


def test_melt_capacity_doubles_the_viscosity_and_scales_with_length() -> None:
    kw = {"set_c": 215.0, "inlet_c": 25.0, "diffusivity_mm2_s": 0.0578}
    q = melt_capacity_mm3_s(_pla, heated_length_mm=20.0, **kw)
    t = float(steady_melt_temperature_c(q, wall_c=215.0, inlet_c=25.0,
                                        diffusivity_mm2_s=0.0578, heated_length_mm=20.0))
    assert _pla(t) / _pla(215.0) == pytest.approx(2.0, rel=1e-9)
    assert melt_capacity_mm3_s(_pla, heated_length_mm=40.0, **kw) == pytest.approx(2.0 * q,
                                                                                   rel=1e-12)


def test_stored_melt_length_factor_is_the_fit() -> None:
    """MELT_LENGTH_FACTOR re-derived from its fit point (the V6's 11 mm³/s at 215 °C)."""
    alpha = float(thermal_diffusivity_mm2_s(defaults.PLA_THERMAL_CONDUCTIVITY_W_MK,
                                            defaults.PLA_4043D.density_g_cm3,
                                            defaults.PLA_HEAT_CAPACITY_J_KGK))
    name, q_pub, temp, _source = defaults.MELT_FIT_REFERENCE
    assert name == "e3d-v6-0.4"
    factor = fit_melt_length_factor(_pla, measured_mm3_s=q_pub, set_c=temp,
                                    inlet_c=defaults.MELT_INLET_C, diffusivity_mm2_s=alpha,
                                    heated_length_mm=defaults.V6_HEATED_LENGTH_MM)
    assert defaults.MELT_LENGTH_FACTOR == pytest.approx(factor, rel=1e-3)
