"""TOML load/save: round trips, and every error path names file, key, value, allowed."""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flowtwin.errors import ProfileError
from flowtwin.profiles import (
    KIND_MODELS,
    PrinterProfile,
    ProfileValidationError,
    library_names,
    load_builtin,
    load_profile,
    profile_from_dict,
    profile_from_toml,
    save_profile,
)

KLIPPER_TOML = """\
kind = "printer"
name = "test-printer"
firmware = "klipper"

[limits]
max_velocity_mm_s = 300.0
max_accel_mm_s2 = {accel}

[extruder]
nozzle_diameter_mm = 0.4
filament_diameter_mm = 1.75
"""


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize("name", library_names())
def test_round_trip_every_builtin(name: str, tmp_path: Path) -> None:
    profile = load_builtin(name)
    path = tmp_path / f"{name}.toml"
    save_profile(profile, path)
    assert load_profile(path) == profile
    # no temporary files left behind by the atomic write
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"{name}.toml"]


def test_save_replaces_existing_file(tmp_path: Path) -> None:
    path = write(tmp_path, "p.toml", "garbage")
    profile = load_builtin("generic-klipper")
    save_profile(profile, path)
    assert load_profile(path, "printer") == profile


def test_load_with_expected_kind(tmp_path: Path) -> None:
    path = write(tmp_path, "printer.toml", KLIPPER_TOML.format(accel=3000.0))
    printer = load_profile(path, "printer")
    assert isinstance(printer, PrinterProfile)
    assert printer.limits is not None and printer.limits.max_accel_mm_s2 == 3000.0


def test_out_of_range_value(tmp_path: Path) -> None:
    path = write(tmp_path, "printer.toml", KLIPPER_TOML.format(accel=-5.0))
    with pytest.raises(ProfileError, match=r"printer\.toml \[limits\.max_accel_mm_s2\]: "
                                           r"must be > 0; got -5\.0; allowed: > 0"):
        load_profile(path, "printer")


def test_error_carries_structured_fields(tmp_path: Path) -> None:
    path = write(tmp_path, "printer.toml", KLIPPER_TOML.format(accel=-5.0))
    with pytest.raises(ProfileValidationError) as info:
        load_profile(path)
    err = info.value
    assert err.source == str(path)
    assert err.field == "limits.max_accel_mm_s2"
    assert err.value == -5.0
    assert err.allowed == "> 0 and <= 1e+06"
    assert [p.key for p in err.problems] == ["limits.max_accel_mm_s2"]


def test_unknown_key_names_key_and_lists_allowed(tmp_path: Path) -> None:
    text = KLIPPER_TOML.format(accel=3000.0).replace("max_accel_mm_s2", "max_acel_mm_s2")
    path = write(tmp_path, "printer.toml", text)
    with pytest.raises(ProfileError, match=r"\[limits\.max_acel_mm_s2\]: unknown key "
                                           r"'max_acel_mm_s2' \(did you mean "
                                           r"'max_accel_mm_s2'\?\).*allowed: known keys: "
                                           r"max_velocity_mm_s, max_accel_mm_s2, "):
        load_profile(path)


def test_unknown_top_level_key(tmp_path: Path) -> None:
    path = write(tmp_path, "f.toml", 'kind = "filament"\nname = "f"\ndiameter_mm = 1.75\n'
                                     'tolerance_mm = 0.05\ncolour = "red"\n')
    with pytest.raises(ProfileError, match=r"f\.toml \[colour\]: unknown key 'colour'; "
                                           r"got 'red'; allowed: known keys: name, "):
        load_profile(path)


def test_missing_key() -> None:
    with pytest.raises(ProfileError, match=r"src\.toml \[tolerance_mm\]: missing required "
                                           r"key; allowed: >= 0 and <= 1"):
        profile_from_dict({"name": "f", "diameter_mm": 1.75}, "filament", source="src.toml")


def test_wrong_type_is_not_coerced() -> None:
    with pytest.raises(ProfileError, match=r"\[diameter_mm\]: must be a number; got '1\.75'"):
        profile_from_dict({"name": "f", "diameter_mm": "1.75", "tolerance_mm": 0.1},
                          "filament")


def test_integer_field_rejects_float() -> None:
    with pytest.raises(ProfileError, match=r"\[roller_id\]: must be an integer; got 3\.0"):
        profile_from_dict({"name": "d", "roller_id": 3.0, "pinch_force_n": 80.0,
                           "rotation_distance_mm": 25.0}, "drive")


def test_inf_and_nan_are_rejected() -> None:
    for bad in (float("inf"), float("nan")):
        with pytest.raises(ProfileError, match=r"\[diameter_mm\]: must be a finite number"):
            profile_from_dict({"name": "f", "diameter_mm": bad, "tolerance_mm": 0.1},
                              "filament")


def test_literal_choice_lists_allowed() -> None:
    with pytest.raises(ProfileError, match=r"\[firmware\]: is not one of the allowed choices"
                                           r".*got 'klippr'; allowed: one of 'klipper', "
                                           r"'marlin', 'reprapfirmware', 'prusa'"):
        profile_from_toml(KLIPPER_TOML.format(accel=1.0).replace('"klipper"', '"klippr"'))


def test_discriminated_union_errors() -> None:
    base = load_builtin("pla-4043d").model_dump(mode="json")
    base["viscosity"] = {"law": "power", "t_min_c": 1.0, "t_max_c": 2.0}
    with pytest.raises(ProfileError, match=r"\[viscosity\]: unknown law; got 'power'; "
                                           r"allowed: law = one of 'exponential', "
                                           r"'arrhenius', 'wlf'"):
        profile_from_dict(base, "material")
    base["viscosity"] = {"law": "arrhenius", "mu_ref_pa_s": 300.0, "t_ref_c": 215.0,
                         "activation_energy_j_mol": -1.0, "t_min_c": 180.0, "t_max_c": 240.0}
    # the tag is not part of the key
    with pytest.raises(ProfileError, match=r"\[viscosity\.activation_energy_j_mol\]: "
                                           r"must be > 0; got -1\.0; allowed: > 0 and <= "):
        profile_from_dict(base, "material")


def test_error_inside_array_of_tables() -> None:
    table = load_builtin("rollers").model_dump(mode="json")
    table["roller"][2]["k_inf_pct_per_N"] = 0.0
    with pytest.raises(ProfileError, match=r"\[roller\[2\]\.k_inf_pct_per_N\]: must be > 0; "
                                           r"got 0\.0"):
        profile_from_dict(table, "roller_table")


def test_model_level_check_message() -> None:
    with pytest.raises(ProfileError, match=r"tolerance_mm \(0\.9\) must be smaller than "
                                           r"diameter_mm \(0\.5\)"):
        profile_from_dict({"name": "f", "diameter_mm": 0.5, "tolerance_mm": 0.9},
                          "filament")


def test_several_problems_are_counted() -> None:
    with pytest.raises(ProfileValidationError, match=r"and 2 more problems") as info:
        profile_from_dict({"name": "", "diameter_mm": -1.0, "tolerance_mm": -1.0},
                          "filament")
    assert len(info.value.problems) == 3


def test_malformed_toml_names_line_and_column(tmp_path: Path) -> None:
    path = write(tmp_path, "bad.toml", 'kind = "filament"\nname = "f"\ndiameter_mm = \n')
    with pytest.raises(ProfileError, match=r"bad\.toml:3: malformed TOML: .*\(column \d+\)"):
        load_profile(path)


def test_kind_errors(tmp_path: Path) -> None:
    with pytest.raises(ProfileError, match=r"\[kind\]: cannot tell which kind"):
        profile_from_dict({"name": "f"})
    with pytest.raises(ProfileError, match=r"\[kind\]: unknown profile kind; got 'nozzle'"):
        profile_from_dict({"kind": "nozzle", "name": "f"})
    path = write(tmp_path, "f.toml", 'kind = "filament"\nname = "f"\ndiameter_mm = 1.75\n'
                                     'tolerance_mm = 0.05\n')
    with pytest.raises(ProfileError, match=r"f\.toml \[kind\]: the file holds a filament "
                                           r"profile, not a printer profile"):
        load_profile(path, "printer")


def test_unreadable_and_non_utf8_files(tmp_path: Path) -> None:
    with pytest.raises(ProfileError, match=r"missing\.toml: cannot read profile"):
        load_profile(tmp_path / "missing.toml")
    path = tmp_path / "latin1.toml"
    path.write_bytes(b'kind = "filament"\nname = "f\xe9"\n')
    with pytest.raises(ProfileError, match=r"latin1\.toml:2: profile is not UTF-8"):
        load_profile(path)


def test_top_level_must_be_a_table() -> None:
    with pytest.raises(ProfileError, match="must be a TOML table"):
        profile_from_dict([1, 2], "filament")  # type: ignore[arg-type]


# --- fuzzing: nothing but ProfileError ---------------------------------------------------

_KNOWN_KEYS = sorted({key for model in KIND_MODELS.values() for key in model.model_fields}
                     | {"kind", "law", "x", "y", "z", "e"})
_keys = st.one_of(st.sampled_from(_KNOWN_KEYS), st.text(max_size=12))
_scalars = st.one_of(st.booleans(), st.integers(min_value=-10**6, max_value=10**6),
                     st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=20),
                     st.sampled_from([*KIND_MODELS, "exponential", "wlf", "klipper"]))
_values = st.recursive(_scalars, lambda children: st.one_of(
    st.lists(children, max_size=4), st.dictionaries(_keys, children, max_size=6)),
    max_leaves=20)
_tables = st.dictionaries(_keys, _values, max_size=10)
_kinds = st.sampled_from([None, *KIND_MODELS])


@settings(max_examples=200, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(data=_tables, kind=_kinds)
def test_random_dicts_raise_only_profile_error(data: dict[str, object],
                                               kind: str | None) -> None:
    try:
        profile_from_dict(data, kind)  # type: ignore[arg-type]
    except ProfileError as exc:
        assert str(exc)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(text=st.text(max_size=200), kind=_kinds)
def test_random_text_raises_only_profile_error(text: str, kind: str | None) -> None:
    try:
        profile_from_toml(text, kind)  # type: ignore[arg-type]
    except ProfileError as exc:
        assert str(exc)


def _toml_safe(value: object) -> bool:
    try:
        tomli_w.dumps({"v": value})
    except (TypeError, ValueError):
        return False
    return True


@settings(max_examples=100, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(data=_tables.filter(_toml_safe), kind=_kinds)
def test_random_valid_toml_raises_only_profile_error(data: dict[str, object],
                                                     kind: str | None,
                                                     tmp_path_factory: pytest.TempPathFactory
                                                     ) -> None:
    text = tomli_w.dumps(data)
    assert tomllib.loads(text) is not None
    path = tmp_path_factory.mktemp("fuzz") / "p.toml"
    path.write_text(text, encoding="utf-8")
    try:
        load_profile(path, kind)  # type: ignore[arg-type]
    except ProfileError as exc:
        assert os.fspath(path) in str(exc)


_BUILTIN_DATA = [(name, load_builtin(name)) for name in library_names()]


def _leaf_paths(data: object, prefix: tuple[object, ...] = ()) -> list[tuple[object, ...]]:
    paths = [prefix] if prefix else []
    if isinstance(data, dict):
        for key, value in data.items():
            paths.extend(_leaf_paths(value, (*prefix, key)))
    elif isinstance(data, list):
        for i, value in enumerate(data):
            paths.extend(_leaf_paths(value, (*prefix, i)))
    return paths


@settings(max_examples=300, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(index=st.integers(min_value=0, max_value=len(_BUILTIN_DATA) - 1),
       pick=st.integers(min_value=0), replacement=st.one_of(st.none(), _values))
def test_mutated_builtins_raise_only_profile_error(index: int, pick: int,
                                                   replacement: object) -> None:
    """Near-valid input: one key of a valid profile replaced (None = deleted), so the
    model-level checks run on odd values too."""
    from flowtwin.profiles import kind_of

    _, profile = _BUILTIN_DATA[index]
    data = profile.model_dump(mode="json")
    paths = _leaf_paths(data)
    path = paths[pick % len(paths)]
    parent: object = data
    for step in path[:-1]:
        parent = parent[step]  # type: ignore[index]
    if replacement is None and isinstance(parent, dict):
        del parent[path[-1]]
    else:
        parent[path[-1]] = replacement  # type: ignore[index]
    try:
        profile_from_dict(data, kind_of(profile))
    except ProfileError as exc:
        assert str(exc)
