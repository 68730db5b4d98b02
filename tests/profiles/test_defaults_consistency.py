"""The built-in profiles carry the documented defaults of :mod:`flowtwin.physics.defaults`
("to be copied into the TOML profiles"), and both transcriptions of [000] agree."""

from __future__ import annotations

import pytest

from flowtwin.physics import defaults as d
from flowtwin.physics.seed_tables import ROLLERS as PHYSICS_ROLLERS
from flowtwin.profiles import (
    ArrheniusViscosity,
    DriveProfile,
    ExponentialViscosity,
    HotendProfile,
    MaterialProfile,
    SetupProfile,
    WlfViscosity,
    load_builtin,
    load_rollers,
)


def _get(name: str, cls: type) -> object:
    profile = load_builtin(name)
    assert isinstance(profile, cls)
    return profile


def test_rollers_agree_with_physics_seed_tables() -> None:
    rollers = load_rollers()
    assert sorted(rollers) == sorted(PHYSICS_ROLLERS)
    for n, theirs in PHYSICS_ROLLERS.items():
        mine = rollers[n]
        assert mine.outer_diameter_mm == theirs.outer_diameter_mm
        assert mine.fp_min_tabulated_N == theirs.f_p_min_n
        assert mine.k_s_pct_N == theirs.k_s_pct_n
        assert mine.k_inf_pct_per_N == theirs.k_inf_pct_per_n
        assert mine.a_pct_per_N == theirs.a_pct_per_n
        # seed_tables writes the vanishing velocity term of #6/#7 as b = c = 0
        assert (mine.b_pct_per_N or 0.0) == theirs.b_pct_per_n
        assert (mine.c_s_per_mm or 0.0) == theirs.c_s_per_mm
        fit = mine.max_feed_force_fit
        assert fit is not None
        assert (fit.c0_N, fit.c1, fit.c2_per_N) == theirs.max_feed_force_coeffs


def test_pla_materials() -> None:
    c = d.PLA_4043D
    for name in ("pla-4043d", "pla-4043d-arrhenius", "pla-4043d-wlf"):
        m = _get(name, MaterialProfile)
        assert isinstance(m, MaterialProfile)
        assert (m.density_g_cm3, m.e_rt_mpa, m.e_hot_mpa, m.glass_transition_c) == (
            c.density_g_cm3, c.e_rt_mpa, c.e_hot_mpa, c.glass_transition_c)
    exp = _get("pla-4043d", MaterialProfile).viscosity  # type: ignore[attr-defined]
    assert isinstance(exp, ExponentialViscosity)
    assert (exp.mu0_pa_s, exp.b_per_c) == (c.mu0_pa_s, c.b_per_c)
    arr = _get("pla-4043d-arrhenius", MaterialProfile).viscosity  # type: ignore[attr-defined]
    assert isinstance(arr, ArrheniusViscosity)
    assert (arr.mu_ref_pa_s, arr.t_ref_c, arr.activation_energy_j_mol) == (
        c.arrhenius_mu_ref_pa_s, c.arrhenius_t_ref_c, c.arrhenius_ea_j_mol)
    wlf = _get("pla-4043d-wlf", MaterialProfile).viscosity  # type: ignore[attr-defined]
    assert isinstance(wlf, WlfViscosity)
    assert (wlf.mu_ref_pa_s, wlf.t_ref_c, wlf.c1, wlf.c2_k) == (
        c.wlf_mu_ref_pa_s, c.wlf_t_ref_c, c.wlf_c1, c.wlf_c2_k)


@pytest.mark.parametrize(("name", "consts", "setup"), [
    ("e3d-v6-0.4", d.E3D_V6_040, d.TRONVOLL_MK25),
    ("rf1000-0.5", d.RF1000_HOTEND_050, d.GREEFF_RF1000),
])
def test_hotends(name: str, consts: d.HotendConstants, setup: d.SetupConstants) -> None:
    h = _get(name, HotendProfile)
    assert isinstance(h, HotendProfile)
    assert (h.nozzle_diameter_mm, h.land_length_mm, h.bore_diameter_mm,
            h.cone_half_angle_deg, h.l_hot_mm, h.back_pressure_length_mm,
            h.back_pressure_exponent) == (
        consts.nozzle_diameter_mm, consts.land_length_mm, consts.bore_diameter_mm,
        consts.cone_half_angle_deg, consts.l_hot_mm, consts.back_pressure_length_mm,
        consts.back_pressure_exponent)
    assert h.l_rt_mm == setup.l_rt_mm


def test_drives() -> None:
    hg = _get("hobb-goblin-80n", DriveProfile)
    assert isinstance(hg, DriveProfile)
    c = d.HOBB_GOBLIN_80N
    assert (hg.roller_id, hg.pinch_force_n, hg.k_p) == (c.roller, c.pinch_force_n, c.k_p)
    rf = _get("rf1000-gear", DriveProfile)
    assert isinstance(rf, DriveProfile) and rf.custom_roller is not None
    c = d.RF1000_GEAR_40N
    r = rf.custom_roller
    assert (rf.pinch_force_n, rf.k_p, r.outer_diameter_mm) == (c.pinch_force_n, c.k_p,
                                                               c.gear_diameter_mm)
    assert (r.k_s_pct_N, r.k_inf_pct_per_N, r.a_pct_per_N, r.b_pct_per_N, r.c_s_per_mm) == (
        c.k_s_pct_n, c.k_inf_pct_per_n, c.a_pct_per_n, c.b_pct_per_n, c.c_s_per_mm)
    fit = r.max_feed_force_fit
    assert fit is not None
    assert (fit.c0_N, fit.c1, fit.c2_per_N) == c.max_feed_force_coeffs


@pytest.mark.parametrize(("name", "consts"), [("tronvoll2019", d.TRONVOLL_MK25),
                                              ("greeff2017", d.GREEFF_RF1000)])
def test_setups(name: str, consts: d.SetupConstants) -> None:
    s = _get(name, SetupProfile)
    assert isinstance(s, SetupProfile)
    assert s.temperature_c == consts.temp_c
    assert s.line_width_mm == consts.line_width_mm
    fil = load_builtin(s.filament)
    assert getattr(fil, "diameter_mm", None) == consts.filament_diameter_mm
