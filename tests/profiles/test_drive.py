"""Drive profile: roller choice, custom rollers, slip overrides."""

from __future__ import annotations

from typing import Any

import pytest

from flowtwin.errors import ProfileError
from flowtwin.profiles import DriveProfile, load_builtin, load_rollers, profile_from_dict

ROLLERS = load_rollers()


def drive(**extra: Any) -> DriveProfile:
    data = {"name": "d", "pinch_force_n": 100.0, "rotation_distance_mm": 25.0, **extra}
    result = profile_from_dict(data, "drive", source="drive.toml")
    assert isinstance(result, DriveProfile)
    return result


def test_catalogue_roller() -> None:
    d = drive(roller_id=5, k_p_pct=0.63)
    assert d.resolve_roller(ROLLERS) == ROLLERS[5]
    assert d.k_p == pytest.approx(0.0063)


def test_exactly_one_roller() -> None:
    with pytest.raises(ProfileError, match=r"drive\.toml: give exactly one of roller_id"):
        drive()
    custom = load_builtin("rf1000-gear").model_dump(mode="json")["custom_roller"]
    with pytest.raises(ProfileError, match="give exactly one of roller_id"):
        drive(roller_id=3, custom_roller=custom)


def test_overrides_replace_parameters_and_drop_the_tabulated_fp_min() -> None:
    d = drive(roller_id=3, slip_overrides={"k_s_pct_N": 192.0})
    r = d.resolve_roller(ROLLERS)
    assert r.k_s_pct_N == 192.0 and r.k_inf_pct_per_N == 0.32
    # sqrt(192/(0.1*0.32)) = 77.46 N: the tabulated 77 N no longer belongs to new parameters
    assert r.fp_min_tabulated_N is None and r.fp_min_discrepancy() is None
    assert r.fp_min_eq9_n == pytest.approx(77.46, abs=0.01)
    assert "overridden" in r.source


def test_velocity_override_turns_on_velocity_dependence() -> None:
    d = drive(roller_id=7, slip_overrides={"b_pct_per_N": 0.1, "c_s_per_mm": 0.5})
    r = d.resolve_roller(ROLLERS)
    assert r.velocity_dependent and r.b_per_n == pytest.approx(0.001)
    with pytest.raises(ProfileError, match=r"velocity_dependent = true needs .*missing: "
                                           r"c_s_per_mm"):
        drive(roller_id=7, slip_overrides={"b_pct_per_N": 0.1}).resolve_roller(ROLLERS)


def test_unknown_roller_in_catalogue() -> None:
    d = drive(roller_id=2)
    with pytest.raises(ProfileError, match=r"\[roller_id\]: drive 'd' refers to an unknown "
                                           r"roller; got 2; allowed: 1, 3"):
        d.resolve_roller({k: ROLLERS[k] for k in (1, 3)})


def test_roller_id_range() -> None:
    with pytest.raises(ProfileError, match=r"drive\.toml \[roller_id\]: must be <= 7; got 8; "
                                           r"allowed: >= 1 and <= 7"):
        drive(roller_id=8)


def test_custom_roller_resolves_to_itself() -> None:
    d = load_builtin("rf1000-gear")
    assert isinstance(d, DriveProfile) and d.custom_roller is not None
    r = d.resolve_roller(ROLLERS)
    assert r is d.custom_roller
    assert r.name == "custom-roller" and r.number is None
    assert r.fp_min_discrepancy() is None
