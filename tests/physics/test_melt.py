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
    steady_melt_temperature_c,
    thermal_diffusivity_mm2_s,
)
from flowtwin.physics.melt_capacity import (
    fit_melt_length_factor,
    melt_capacity_mm3_s,
    melt_fourier_at_fraction,
)
from flowtwin.physics.melt_history import (
    MeltState,
    fill_time_for_temperature_s,
    melt_temperature_history,
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


def test_compiled_and_python_series_are_the_same_numbers() -> None:
    # few values run theta_scalar in Python, many run it compiled: bit for bit the same
    fo = np.concatenate(([0.0, 1e-9, 1.999e-3, 2.0e-3, math.inf],
                         np.geomspace(1e-6, 50.0, 400)))
    compiled = bulk_temperature_fraction(fo)
    assert fo.size > 16
    one_by_one = np.array([float(bulk_temperature_fraction(x)) for x in fo])
    np.testing.assert_array_equal(compiled, one_by_one)
    assert compiled[0] == 1.0 and compiled[4] == 0.0


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


KW = {"inlet_c": 25.0, "diffusivity_mm2_s": 0.0578, "heated_length_mm": 24.3,
      "filament_radius_mm": 0.875}


def _steady(q: float) -> float:
    return float(steady_melt_temperature_c(q, wall_c=215.0, inlet_c=25.0,
                                           diffusivity_mm2_s=0.0578, heated_length_mm=24.3))


def _run(q: np.ndarray, dur: np.ndarray, gap: np.ndarray | None = None,
         state: MeltState | None = None, t0: float = 0.0) -> tuple[np.ndarray, MeltState]:
    gap = np.zeros(q.size) if gap is None else gap
    start = t0 + np.concatenate(([0.0], np.cumsum(dur + gap)[:-1]))
    return melt_temperature_history(q, start, dur, np.full(q.size, 215.0), state=state, **KW)


def test_steady_flow_is_the_steady_model_exactly() -> None:
    """After one zone volume at constant flow the slice leaving has had t_res = V/Q."""
    zone = math.pi * 0.875 ** 2 * 24.3
    q = np.full(40, 12.0)
    mean, state = _run(q, np.full(40, 1.0))
    filled = np.arange(40) * 1.0 >= zone / 12.0 + 1e-9
    assert np.all(np.abs(mean[filled] - _steady(12.0)) < 1e-9)
    assert state.end_c == pytest.approx(_steady(12.0), abs=1e-9)
    # before that the fill (fully heated at the start) is still leaving: hotter
    assert np.all(mean[~filled] > _steady(12.0))


def test_a_rest_lets_the_slice_in_the_zone_keep_heating() -> None:
    """At rest the leaving slice's residence grows by the rest: T -> T_w."""
    q = np.array([12.0] * 20 + [0.0])
    dur = np.array([1.0] * 20 + [30.0])
    mean, state = _run(q, dur)
    zone = math.pi * 0.875 ** 2 * 24.3
    residence_end = zone / 12.0 + 30.0
    want = 215.0 - 190.0 * float(bulk_temperature_fraction(0.0578 * residence_end / 0.875 ** 2))
    assert state.end_c == pytest.approx(want, abs=1e-9)
    assert _steady(12.0) < mean[-1] < state.end_c < 215.0


def test_millisecond_bursts_are_averaged_over_the_zone_volume() -> None:
    """Pressure-advance pieces (alternating 3x and 0.5x the flow, same volume) leave the melt
    where the steady flow leaves it: the zone averages over its volume, not per piece."""
    n = 4000
    dur = np.full(n, 0.005)
    even = np.full(n, 8.0)
    bursts = np.where(np.arange(n) % 2 == 0, 13.0, 3.0)   # mean 8.0 mm³/s
    a, _ = _run(even, dur)
    b, _ = _run(bursts, dur)
    tail = slice(n // 2, None)
    assert np.max(np.abs(b[tail] - a[tail])) < 0.02


def test_the_memory_carries_a_split_sequence_exactly() -> None:
    rng = np.random.default_rng(3)
    q = rng.uniform(0.0, 15.0, 300) * (rng.random(300) < 0.8)
    dur = rng.uniform(0.01, 0.5, 300)
    gap = rng.uniform(0.0, 0.2, 300)
    whole, end = _run(q, dur, gap)
    start = np.concatenate(([0.0], np.cumsum(dur + gap)[:-1]))
    first, mid = melt_temperature_history(q[:170], start[:170], dur[:170],
                                          np.full(170, 215.0), **KW)
    second, end2 = melt_temperature_history(q[170:], start[170:], dur[170:],
                                            np.full(130, 215.0), state=mid, **KW)
    np.testing.assert_allclose(np.concatenate((first, second)), whole, rtol=0, atol=1e-9)
    assert end2.end_c == pytest.approx(end.end_c, abs=1e-9)
    # the memory covers the last zone volume (from one breakpoint before it), not the past
    zone = math.pi * 0.875 ** 2 * 24.3
    v = mid.volumes_mm3
    assert v[0] <= v[-1] - zone < v[1] and v.size < 2 * 170


def test_a_fill_at_a_given_temperature() -> None:
    fill = fill_time_for_temperature_s(190.0, wall_c=215.0, inlet_c=25.0,
                                       diffusivity_mm2_s=0.0578, filament_radius_mm=0.875,
                                       at_s=10.0)
    state = MeltState(np.zeros(0), np.zeros(0), fill, 190.0)
    mean, _ = melt_temperature_history(np.array([0.0]), np.array([10.0]), np.array([0.0]),
                                       np.array([215.0]), state=state, **KW)
    assert mean[0] == pytest.approx(190.0, abs=1e-6)


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


@pytest.mark.parametrize("spans", [1, 2, 3, 7, 5000])
def test_the_melt_temperatures_in_spans_on_threads_are_the_one_pass_numbers(spans: int) -> None:
    """Large tables are computed in spans on numba's threads (``PARALLEL_MOVES``): each span
    starts its searches afresh, and every move must still get the one-pass value to the
    bit — on pieces as short as pressure-advance pieces, with rests and a prior memory."""
    from flowtwin.physics._melt_history_kernel import (
        breakpoints,
        mean_temperatures,
        mean_temperatures_parallel,
    )

    rng = np.random.default_rng(11)
    n = 4000
    q = rng.uniform(0.0, 20.0, n) * (rng.random(n) < 0.7)
    dur = rng.choice([0.002, 0.01, 0.3], size=n)
    start = 5.0 + np.concatenate(([0.0], np.cumsum(dur + rng.uniform(0.0, 0.05, n))[:-1]))
    _, prior = _run(np.full(50, 9.0), np.full(50, 0.1))
    vol = q * dur
    base = float(prior.volumes_mm3[-1])
    v_start = base + np.concatenate(([0.0], np.cumsum(vol)[:-1]))
    v_end = v_start + vol
    bt, bv = breakpoints(prior.times_s, prior.volumes_mm3, start, dur, v_start, v_end, vol)
    wall = np.where(np.arange(n) < n // 2, 215.0, 230.0)
    zone = math.pi * 0.875 ** 2 * 24.3
    args = (start, dur, v_start, v_end, wall, bt, bv, zone, prior.fill_time_s, 25.0, 0.0578,
            0.875)
    one, spanned = np.empty(n), np.empty(n)
    mean_temperatures(*args, one)
    mean_temperatures_parallel(*args, spanned, spans)
    np.testing.assert_array_equal(spanned, one)
    assert np.ptp(one) > 20.0  # the melt does vary: the comparison is not of constants
