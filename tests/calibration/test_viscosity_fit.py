"""Viscosity-law fits: known answers from the forward model with seeded noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from flowtwin.calibration.csvdata import read_table_text
from flowtwin.calibration.fits.viscosity_fit import (
    VISCOSITY_COLUMNS,
    ViscositySweep,
    apparent_viscosity_pa_s,
    fit_viscosity_law,
    sweep_from_table,
)
from flowtwin.errors import CalibrationError, DataError
from flowtwin.physics.drive import slip, slip_velocity
from flowtwin.physics.nozzle import feed_force_n, hydraulic_resistance_mpa_s_per_mm3
from flowtwin.physics.units import circle_area_mm2, pa_s_to_mpa_s
from flowtwin.physics.viscosity import (
    arrhenius_energy_from_two_points,
    viscosity_arrhenius_pa_s,
    viscosity_exponential_pa_s,
    viscosity_wlf_pa_s,
)
from flowtwin.profiles import load_builtin, load_rollers
from flowtwin.profiles.drive import DriveProfile
from flowtwin.profiles.hotend import HotendProfile
from flowtwin.profiles.material import ExponentialViscosity, MaterialProfile

#: A sweep as a user would run it: 190-230 °C in 5 °C steps, 3 repeats each.
TEMPS = np.repeat(np.arange(190.0, 231.0, 5.0), 3)
#: The known-answer tests accept |estimate − truth| <= 3 reported σ: for a correct
#: estimator a 3σ miss has probability ~0.3 % per parameter, and the seeds are fixed.
K_SIGMA = 3.0


def _noisy(mu: np.ndarray, rel: float, seed: int) -> np.ndarray:
    return mu * np.exp(np.random.default_rng(seed).normal(0.0, rel, mu.shape))


def test_exponential_law_through_tronvolls_two_points() -> None:
    # [001] quotes 1000 Pa·s at 190 °C and 200 Pa·s at 220 °C for PLA; the exponential law
    # [002] through them has b = ln 5 / 30 and μ0 = 200·exp(220·b) (the pla-4043d profile)
    t = np.array([190.0, 200.0, 210.0, 220.0])
    b = math.log(5.0) / 30.0
    mu = 1000.0 * np.exp(-b * (t - 190.0))
    fit = fit_viscosity_law(ViscositySweep(t, mu, "viscosity"), law="exponential")
    assert fit.params["b_per_c"] == pytest.approx(b, rel=1e-9)
    assert fit.params["mu0_pa_s"] == pytest.approx(200.0 * math.exp(220.0 * b), rel=1e-9)
    material = load_builtin("pla-4043d", "material")
    assert isinstance(material, MaterialProfile)
    assert isinstance(material.viscosity, ExponentialViscosity)
    assert fit.params["b_per_c"] == pytest.approx(material.viscosity.b_per_c, rel=1e-4)
    assert fit.stderr["b_per_c"] < 1e-9             # exact data: no scatter


def test_arrhenius_law_through_the_same_points() -> None:
    t = np.array([190.0, 200.0, 210.0, 220.0])
    ea = arrhenius_energy_from_two_points(190.0, 1000.0, 220.0, 200.0)
    mu = viscosity_arrhenius_pa_s(t, 1000.0, 190.0, ea)
    fit = fit_viscosity_law(ViscositySweep(t, mu, "viscosity"), law="arrhenius",
                            t_ref_c=190.0)
    assert fit.params["activation_energy_j_mol"] == pytest.approx(ea, rel=1e-9)
    assert fit.params["activation_energy_j_mol"] == pytest.approx(101880.0, rel=1e-4)
    assert fit.params["mu_ref_pa_s"] == pytest.approx(1000.0, rel=1e-9)


def _forces(mu_pa_s: np.ndarray, flow: float, hotend: HotendProfile, d_fil: float
            ) -> np.ndarray:
    """Forward model: F = R_hyd(μ)·Q·A_fil (cone + capillary, free extrusion)."""
    r = hydraulic_resistance_mpa_s_per_mm3(
        pa_s_to_mpa_s(mu_pa_s), capillary_length_mm=hotend.land_length_mm,
        nozzle_radius_mm=hotend.nozzle_radius_mm,
        bore_radius_mm=hotend.bore_diameter_mm / 2.0,
        cone_half_angle_deg=hotend.cone_half_angle_deg)
    return feed_force_n(r * flow, circle_area_mm2(d_fil))


def _hotend() -> HotendProfile:
    hotend = load_builtin("e3d-v6-0.4", "hotend")
    assert isinstance(hotend, HotendProfile)
    return hotend


def test_apparent_viscosity_inverts_the_nozzle_model() -> None:
    mu = np.array([200.0, 261.5, 1000.0])
    force = _forces(mu, 5.0, _hotend(), 1.75)
    # magnitude check against [001 Eq. 4]'s 0.28-1.4 N on the outlet area, times
    # (d_in/d_out)² for the filament face, plus the cone: a few N
    assert 1.0 < force[1] < 20.0
    assert apparent_viscosity_pa_s(force, 5.0, hotend=_hotend(), filament_diameter_mm=1.75) \
        == pytest.approx(mu, rel=1e-12)


def test_exponential_from_feed_force_recovers_the_law() -> None:
    mu0, b = 2.6718e7, 0.053648
    force = _forces(_noisy(viscosity_exponential_pa_s(TEMPS, mu0, b), 0.03, seed=11),
                    5.0, _hotend(), 1.75)
    text = "temp_c,feed_force_n,flow_mm3_s\n" + "".join(
        f"{t},{float(f)!r},5\n" for t, f in zip(TEMPS, force, strict=True))
    sweep = sweep_from_table(read_table_text(text, VISCOSITY_COLUMNS), hotend=_hotend(),
                             filament_diameter_mm=1.75)
    assert sweep.basis == "feed_force"
    fit = fit_viscosity_law(sweep, law="exponential")
    assert abs(fit.params["b_per_c"] - b) <= K_SIGMA * fit.stderr["b_per_c"]
    assert abs(fit.params["mu0_pa_s"] - mu0) <= K_SIGMA * fit.stderr["mu0_pa_s"]
    # the 3 % noise of ln μ shows as ~0.013 in log10
    assert fit.rms_log10 == pytest.approx(0.03 / math.log(10.0), rel=0.3)
    assert (fit.t_min_c, fit.t_max_c, fit.n_points) == (190.0, 230.0, 27)


def test_reported_uncertainty_has_the_right_coverage() -> None:
    # Over many seeded sweeps the 1σ interval must contain the true b about 68 % of the
    # time (t distribution with 25 dof: 67.3 %). 300 trials: binomial σ = 2.7 %; accept
    # ±9 % (3.3σ).
    b = 0.053648
    hits = 0
    trials = 300
    for seed in range(trials):
        mu = _noisy(viscosity_exponential_pa_s(TEMPS, 2.6718e7, b), 0.05, seed=1000 + seed)
        fit = fit_viscosity_law(ViscositySweep(TEMPS, mu, "viscosity"))
        hits += abs(fit.params["b_per_c"] - b) <= fit.stderr["b_per_c"]
    assert hits / trials == pytest.approx(0.673, abs=0.09)


def test_arrhenius_recovers_the_law_within_uncertainty() -> None:
    ea, mu_ref = 101880.0, 400.0
    mu = _noisy(viscosity_arrhenius_pa_s(TEMPS, mu_ref, 210.0, ea), 0.04, seed=5)
    fit = fit_viscosity_law(ViscositySweep(TEMPS, mu, "viscosity"), law="arrhenius")
    assert fit.fixed == {"t_ref_c": 210.0}                 # mean of the data
    assert abs(fit.params["activation_energy_j_mol"] - ea) <= \
        K_SIGMA * fit.stderr["activation_energy_j_mol"]
    assert abs(fit.params["mu_ref_pa_s"] - mu_ref) <= K_SIGMA * fit.stderr["mu_ref_pa_s"]


def test_wlf_with_fixed_c2_recovers_mu_ref_and_c1() -> None:
    # the pla-4043d-wlf profile: universal constants about T_g = 55 °C
    mu = _noisy(viscosity_wlf_pa_s(TEMPS, 4.024e15, 55.0, 17.44, 51.6), 0.03, seed=8)
    fit = fit_viscosity_law(ViscositySweep(TEMPS, mu, "viscosity"), law="wlf",
                            t_ref_c=55.0, wlf_c2_k=51.6)
    assert fit.fixed == {"t_ref_c": 55.0, "c2_k": 51.6}
    assert abs(fit.params["c1"] - 17.44) <= K_SIGMA * fit.stderr["c1"]
    log_err = fit.stderr["mu_ref_pa_s"] / fit.params["mu_ref_pa_s"]   # σ of ln μ_ref
    assert abs(math.log(fit.params["mu_ref_pa_s"] / 4.024e15)) <= K_SIGMA * log_err


def test_wlf_three_parameters_with_curvature_resolved() -> None:
    # a wide sweep (170-260 °C) about T_ref = 200 °C with 0.5 % scatter resolves C2
    t = np.repeat(np.arange(170.0, 261.0, 10.0), 2)
    c1, c2 = 5.0, 150.0
    mu = _noisy(viscosity_wlf_pa_s(t, 500.0, 200.0, c1, c2), 0.005, seed=3)
    fit = fit_viscosity_law(ViscositySweep(t, mu, "viscosity"), law="wlf", t_ref_c=200.0)
    for name, truth in (("c1", c1), ("c2_k", c2)):
        assert abs(fit.params[name] - truth) <= K_SIGMA * fit.stderr[name]
    assert fit.profile_table()["law"] == "wlf"


def test_wlf_cannot_separate_c1_and_c2_on_exponential_data() -> None:
    mu = _noisy(viscosity_exponential_pa_s(TEMPS, 2.6718e7, 0.053648), 0.03, seed=1)
    with pytest.raises(CalibrationError, match=r"does not determine|degenerate|bound"):
        fit_viscosity_law(ViscositySweep(TEMPS, mu, "viscosity"), law="wlf")


def test_slip_sweep_with_the_velocity_law_of_roller_3() -> None:
    # hobb-goblin-80n: roller #3 at 80 N, inside Eq. 8's 80-130 N range
    drive = load_builtin("hobb-goblin-80n", "drive")
    assert isinstance(drive, DriveProfile)
    roller = drive.resolve_roller(load_rollers())
    assert roller.velocity_dependent
    mu0, b, flow, d_fil = 2.6718e7, 0.053648, 4.0, 1.75
    force = _forces(_noisy(viscosity_exponential_pa_s(TEMPS, mu0, b), 0.03, seed=21),
                    flow, _hotend(), d_fil)
    v_fil = flow / float(circle_area_mm2(d_fil))
    assert roller.a_per_n is not None and roller.b_per_n is not None
    assert roller.c_s_per_mm is not None
    s = slip_velocity(force, v_fil, k_p=drive.k_p, a_per_n=roller.a_per_n,
                      b_per_n=roller.b_per_n, c_s_per_mm=roller.c_s_per_mm)
    text = "temp_c,slip_pct,flow_mm3_s\n" + "".join(
        f"{t},{100 * float(v)!r},{flow}\n" for t, v in zip(TEMPS, s, strict=True))
    sweep = sweep_from_table(read_table_text(text, VISCOSITY_COLUMNS), hotend=_hotend(),
                             filament_diameter_mm=d_fil, drive=drive, roller=roller)
    assert sweep.basis == "slip"
    fit = fit_viscosity_law(sweep)
    assert abs(fit.params["b_per_c"] - b) <= K_SIGMA * fit.stderr["b_per_c"]


def test_slip_sweep_with_the_pinch_force_law() -> None:
    # 50 N is outside Eq. 8's range: the inversion uses Eq. 6
    drive = DriveProfile.model_validate({"name": "weak", "roller_id": 1, "pinch_force_n": 50.0,
                                         "rotation_distance_mm": 25.0, "k_p_pct": 0.5})
    roller = drive.resolve_roller(load_rollers())
    force = _forces(viscosity_exponential_pa_s(TEMPS, 2.6718e7, 0.053648), 3.0, _hotend(),
                    1.75)
    s = slip(force, 50.0, k_p=drive.k_p, k_s_n=roller.k_s_n, k_inf_per_n=roller.k_inf_per_n)
    sweep = sweep_from_table(read_table_text(
        "temp_c,slip_pct,flow_mm3_s\n" + "".join(f"{t},{100 * float(v)!r},3\n" for t, v in zip(
            TEMPS, s, strict=True)), VISCOSITY_COLUMNS), hotend=_hotend(),
        drive=drive, roller=roller)
    assert sweep.visc_pa_s == pytest.approx(viscosity_exponential_pa_s(TEMPS, 2.6718e7,
                                                                       0.053648), rel=1e-9)


def test_slip_below_the_offset_is_located() -> None:
    drive = DriveProfile.model_validate({"name": "d", "roller_id": 1, "pinch_force_n": 50.0,
                                         "rotation_distance_mm": 25.0, "k_p_pct": 2.0})
    table = read_table_text("temp_c,slip_pct,flow_mm3_s\n200,5,3\n210,1.5,3\n", VISCOSITY_COLUMNS,
                            source="s.csv")
    with pytest.raises(CalibrationError, match=r"s\.csv:3 \[slip_pct\].*k_p = 2 %"):
        sweep_from_table(table, hotend=_hotend(), drive=drive,
                         roller=drive.resolve_roller(load_rollers()))


@pytest.mark.parametrize(("header", "error", "pattern"), [
    ("temp_c,viscosity_pa_s,feed_force_n", DataError, "exactly one of"),
    ("temp_c", DataError, "exactly one of"),
    ("temp_c,feed_force_n", DataError, r"\[flow_mm3_s\]: feed_force_n needs the flow"),
])
def test_sweep_needs_one_quantity(header: str, error: type[Exception], pattern: str) -> None:
    ncol = header.count(",") + 1
    table = read_table_text(header + "\n" + ",".join(["5"] * ncol) + "\n", VISCOSITY_COLUMNS)
    with pytest.raises(error, match=pattern):
        sweep_from_table(table, hotend=_hotend())


def test_slip_needs_the_drive() -> None:
    table = read_table_text("temp_c,slip_pct,flow_mm3_s\n200,5,3\n", VISCOSITY_COLUMNS)
    with pytest.raises(CalibrationError, match=r"\[drive\]"):
        sweep_from_table(table, hotend=_hotend())


@pytest.mark.parametrize(("t", "mu", "pattern"), [
    ([200.0, 200.0, 200.0], [300.0, 310.0, 290.0], "distinct temperatures"),
    ([190.0, 220.0], [1000.0, 200.0], "at least 3 points"),
    ([190.0, 200.0, 210.0, 220.0], [200.0, 300.0, 450.0, 700.0], "does not fall"),
])
def test_degenerate_sweeps_fail_with_a_reason(t: list[float], mu: list[float],
                                              pattern: str) -> None:
    with pytest.raises(CalibrationError, match=pattern):
        fit_viscosity_law(ViscositySweep(np.array(t), np.array(mu), "viscosity"))


def test_fitted_table_must_be_a_valid_profile() -> None:
    # b = 2 /°C puts μ0 = μ(200 °C)·e^400 beyond what a material profile accepts (1e30)
    t = np.array([200.0, 201.0, 202.0, 203.0])
    fit = fit_viscosity_law(ViscositySweep(t, 1e3 * np.exp(-2.0 * (t - 200.0)), "viscosity"))
    with pytest.raises(CalibrationError,
                       match=r"\[mu0_pa_s\].*not a valid material profile.*less than or equal"):
        fit.profile_table()


def test_profile_table_drops_into_a_material_profile() -> None:
    mu = _noisy(viscosity_exponential_pa_s(TEMPS, 2.6718e7, 0.053648), 0.02, seed=4)
    fit = fit_viscosity_law(ViscositySweep(TEMPS, mu, "viscosity"))
    base = load_builtin("pla-4043d", "material")
    assert isinstance(base, MaterialProfile)
    data = base.model_dump()
    data["viscosity"] = fit.profile_table()
    material = MaterialProfile.model_validate(data)
    assert material.viscosity.law == "exponential"
    assert fit.viscosity_pa_s(215.0) == pytest.approx(
        viscosity_exponential_pa_s(215.0, fit.params["mu0_pa_s"], fit.params["b_per_c"]))
