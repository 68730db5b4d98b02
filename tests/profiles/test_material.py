"""Material profile: the three viscosity laws and their checks."""

from __future__ import annotations

from typing import Any

import pytest

from flowtwin.errors import ProfileError
from flowtwin.profiles import (
    ArrheniusViscosity,
    MaterialProfile,
    WlfViscosity,
    load_builtin,
    profile_from_dict,
)


def material(viscosity: dict[str, Any], **extra: Any) -> MaterialProfile:
    data = load_builtin("pla-4043d").model_dump(mode="json")
    data.update(viscosity=viscosity, **extra)
    result = profile_from_dict(data, "material", source="mat.toml")
    assert isinstance(result, MaterialProfile)
    return result


def test_arrhenius_and_wlf_laws_load() -> None:
    m = material({"law": "arrhenius", "mu_ref_pa_s": 300.0, "t_ref_c": 215.0,
                  "activation_energy_j_mol": 80e3, "t_min_c": 180.0, "t_max_c": 240.0})
    assert isinstance(m.viscosity, ArrheniusViscosity)
    assert m.viscosity.mu_ref_mpa_s == pytest.approx(3e-4)
    m = material({"law": "wlf", "mu_ref_pa_s": 300.0, "t_ref_c": 215.0, "c1": 8.86,
                  "c2_k": 101.6, "t_min_c": 180.0, "t_max_c": 240.0})
    assert isinstance(m.viscosity, WlfViscosity)


def test_wlf_singularity_inside_range_is_refused() -> None:
    with pytest.raises(ProfileError, match=r"mat\.toml \[viscosity\]: the WLF law is singular"):
        material({"law": "wlf", "mu_ref_pa_s": 300.0, "t_ref_c": 215.0, "c1": 8.86,
                  "c2_k": 10.0, "t_min_c": 180.0, "t_max_c": 240.0})


def test_validity_range_order() -> None:
    with pytest.raises(ProfileError, match=r"t_min_c \(240.0\) must be below t_max_c"):
        material({"law": "exponential", "mu0_pa_s": 1e7, "b_per_c": 0.05,
                  "t_min_c": 240.0, "t_max_c": 180.0})


def test_law_key_is_required() -> None:
    with pytest.raises(ProfileError, match=r"\[viscosity\]: needs the key 'law' to choose its "
                                           r"kind; allowed: law = one of 'exponential', "
                                           r"'arrhenius', 'wlf'"):
        material({"mu0_pa_s": 1e7, "b_per_c": 0.05, "t_min_c": 180.0, "t_max_c": 240.0})


def test_hot_modulus_not_above_cold() -> None:
    with pytest.raises(ProfileError, match=r"e_hot_mpa \(5000.0\) must not exceed e_rt_mpa"):
        material({"law": "exponential", "mu0_pa_s": 1e7, "b_per_c": 0.05, "t_min_c": 180.0,
                  "t_max_c": 240.0}, e_hot_mpa=5000.0)
