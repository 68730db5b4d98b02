"""The built-in library: every profile loads, names are consistent, seed values are kept."""

from __future__ import annotations

import math
from importlib import resources

import pytest

from flowtwin.errors import ProfileError
from flowtwin.profiles import (
    KIND_MODELS,
    DriveProfile,
    ExponentialViscosity,
    FilamentProfile,
    HotendProfile,
    MaterialProfile,
    PrinterProfile,
    SetupProfile,
    kind_of,
    library_entries,
    library_names,
    load_builtin,
)

REQUIRED = {
    "roller-1", "roller-2", "roller-3", "roller-4", "roller-5", "roller-6", "roller-7",
    "pla-4043d", "pla-4043d-1.75", "e3d-v6-0.4", "tronvoll2019", "greeff2017",
    "generic-klipper", "generic-marlin",
}


def test_library_has_the_required_profiles() -> None:
    names = library_names()
    assert REQUIRED <= set(names)
    assert len(names) == len(set(names))


@pytest.mark.parametrize("entry", library_entries(), ids=lambda e: e.name)
def test_every_builtin_loads_and_validates(entry) -> None:  # type: ignore[no-untyped-def]
    profile = load_builtin(entry.name)
    assert kind_of(profile) == entry.kind
    assert isinstance(profile, KIND_MODELS[entry.kind])
    assert entry.description
    # re-validating the dumped data gives the same object (the data file is canonical)
    assert type(profile).model_validate(profile.model_dump()) == profile


def test_data_files_declare_their_kind() -> None:
    root = resources.files("flowtwin") / "data"
    for folder in ("printers", "drives", "hotends", "materials", "filaments", "setups"):
        for item in (root / folder).iterdir():
            if item.name.endswith(".toml"):
                assert f'kind = "{folder[:-1]}"' in item.read_text(encoding="utf-8"), item.name


def test_unknown_name_suggests_the_closest() -> None:
    with pytest.raises(ProfileError, match=r"unknown built-in profile \(did you mean "
                                           r"'generic-klipper'\?\); got 'generic-klippr'"):
        load_builtin("generic-klippr")


def test_wrong_kind_is_refused() -> None:
    with pytest.raises(ProfileError, match=r"'pla-4043d' is a material, not a printer"):
        load_builtin("pla-4043d", "printer")


def test_pla_4043d_seed_values() -> None:
    """[000 §3], [001 Eq. 3]: 1.752 ± 0.003 mm, roundness 0.011 mm, 1.25 g/cm³."""
    fil = load_builtin("pla-4043d-1.75")
    mat = load_builtin("pla-4043d")
    assert isinstance(fil, FilamentProfile) and isinstance(mat, MaterialProfile)
    assert (fil.diameter_mm, fil.tolerance_mm, fil.roundness_mm) == (1.752, 0.003, 0.011)
    assert mat.density_g_cm3 == 1.25
    assert mat.glass_transition_c == 55.0  # [003 §3.2]


def test_provisional_pla_viscosity_spans_tronvolls_range() -> None:
    """[001 Eq. 4 discussion]: PLA 200 to 1000 Pa·s at 220-190 °C. The provisional law
    μ0·exp(−b·T) [002] was put through those two points; 0.1 %: the TOML keeps 6 digits."""
    mat = load_builtin("pla-4043d")
    assert isinstance(mat, MaterialProfile)
    law = mat.viscosity
    assert isinstance(law, ExponentialViscosity)

    def mu_pa_s(t_c: float) -> float:
        return law.mu0_pa_s * math.exp(-law.b_per_c * t_c)

    assert mu_pa_s(220.0) == pytest.approx(200.0, rel=1e-3)
    assert mu_pa_s(190.0) == pytest.approx(1000.0, rel=1e-3)
    assert law.contains(215.0)
    assert law.mu0_mpa_s == pytest.approx(law.mu0_pa_s * 1e-6)


def test_e3d_v6_nozzle() -> None:
    """[001]: 0.4 mm nozzle, 0.6 mm outlet length."""
    hot = load_builtin("e3d-v6-0.4")
    assert isinstance(hot, HotendProfile)
    assert (hot.nozzle_diameter_mm, hot.land_length_mm) == (0.4, 0.6)
    assert hot.bowden is None
    # 30° half angle from a 2 mm bore to 0.4 mm: 0.8 mm radial / tan 30° = 1.3856 mm
    assert (hot.bore_diameter_mm, hot.cone_half_angle_deg) == (2.0, 30.0)
    assert hot.cone_length_mm == pytest.approx(1.3856, abs=1e-4)


def test_tronvoll_setup_matches_table_i() -> None:
    """[001 Table I]: Prusa i3 MK2.5, 0.40 mm nozzle, 0.48 mm line width, 215 °C."""
    s = load_builtin("tronvoll2019")
    assert isinstance(s, SetupProfile)
    assert (s.temperature_c, s.line_width_mm, s.layer_height_mm) == (215.0, 0.48, 0.2)
    printer = load_builtin(s.printer)
    drive = load_builtin(s.drive)
    assert isinstance(printer, PrinterProfile) and isinstance(drive, DriveProfile)
    # 8-bit Prusa-Firmware: Marlin's planner and Linear Advance (M900), as [001] used
    assert printer.firmware == "marlin"
    assert printer.extruder.nozzle_diameter_mm == 0.4
    # docs/spec.md §4: roller #3 at 80 N; rotation distance π·7.98 mm ([000 Eq. 1] v = ω·r)
    assert (drive.roller_id, drive.pinch_force_n) == (3, 80.0)
    assert drive.rotation_distance_mm == pytest.approx(math.pi * 7.98, abs=1e-4)


def test_greeff_setup_matches_the_paper() -> None:
    """[003]: RF1000, 8 mm 24-tooth gear, 280 steps/mm, 0.5 mm nozzle, 2.85 mm PLA, 215 °C."""
    s = load_builtin("greeff2017")
    assert isinstance(s, SetupProfile)
    assert s.temperature_c == 215.0
    drive = load_builtin(s.drive)
    hot = load_builtin(s.hotend)
    fil = load_builtin(s.filament)
    assert isinstance(drive, DriveProfile) and drive.custom_roller is not None
    assert (drive.custom_roller.outer_diameter_mm, drive.custom_roller.teeth) == (8.0, 24)
    # 280 steps/mm at 200 full steps x 32 microsteps per turn
    assert 200 * 32 / drive.rotation_distance_mm == pytest.approx(280.0, rel=1e-4)
    assert isinstance(hot, HotendProfile) and hot.nozzle_diameter_mm == 0.5
    assert isinstance(fil, FilamentProfile) and fil.diameter_mm == 2.85


def test_generic_marlin_defaults() -> None:
    p = load_builtin("generic-marlin")
    assert isinstance(p, PrinterProfile) and p.marlin is not None
    m = p.marlin
    assert (m.max_acceleration_mm_s2.x, m.max_acceleration_mm_s2.z) == (3000.0, 100.0)
    assert m.junction_deviation_mm == 0.013 and m.jerk_mm_s is None
    assert p.pa_smooth_time_s == 0.0
