"""Parameter paths and value syntax of sweeps."""

from __future__ import annotations

import pytest

from flowtwin.batch.params import ALIASES, describe_path, parse_axis, resolve_path
from flowtwin.errors import ProfileError


def test_paths_resolve_to_profile_fields_with_their_types_and_bounds() -> None:
    info = resolve_path("drive.pinch_force_n")
    assert (info.part, info.keys, info.kind) == ("drive", ("pinch_force_n",), "float")
    assert info.allowed == "> 0 and <= 500"  # DriveProfile.pinch_force_n: gt=0, le=500
    assert resolve_path("drive.roller_id").kind == "int"
    assert resolve_path("printer.pressure_advance.k_s").keys == ("pressure_advance", "k_s")
    assert resolve_path("printer.retraction.enabled").kind == "bool"
    assert resolve_path("setup.material").kind == "str"
    firmware = resolve_path("printer.firmware")
    assert firmware.kind == "str" and "klipper" in firmware.choices
    # A key of one member of the viscosity-law union.
    assert resolve_path("material.viscosity.b_per_c").kind == "float"
    assert "setup.temperature_c" in describe_path("setup.temperature_c")


def test_the_issue_spelling_of_the_temperature_is_a_documented_alias() -> None:
    assert ALIASES["material.temperature_c"] == "setup.temperature_c"
    assert resolve_path("material.temperature_c").path == "setup.temperature_c"
    axis = parse_axis("material.temperature_c=190:230:5")
    assert axis.paths == ("setup.temperature_c",)


@pytest.mark.parametrize(("path", "match"), [
    ("nozzle.diameter_mm", "unknown profile part"),
    ("roller.k_s_pct_N", "drive.roller_id"),
    ("drive", "needs a key"),
    ("drive.pinch_force", "has no key 'pinch_force'"),
    ("drive.slip_overrides", "names a table"),
    ("drive.pinch_force_n.x", "is a value, not a table"),
])
def test_bad_paths_are_profile_errors_naming_the_path(path: str, match: str) -> None:
    with pytest.raises(ProfileError, match=match) as info:
        resolve_path(path)
    assert info.value.field == path
    assert info.value.allowed


def test_ranges_are_inclusive_and_exact_in_decimal() -> None:
    # Binary float steps would give 0.30000000000000004 and miss the end point.
    assert parse_axis("setup.layer_height_mm=0.1:0.3:0.1").values == (0.1, 0.2, 0.3)
    assert parse_axis("setup.temperature_c=190:230:5").values == tuple(
        float(t) for t in range(190, 231, 5))
    # An end point off the grid is not reached: 190, 197, 204 (211 > 210).
    assert parse_axis("setup.temperature_c=190:210:7").values == (190.0, 197.0, 204.0)
    assert parse_axis("setup.temperature_c=220:200:-10").values == (220.0, 210.0, 200.0)
    assert parse_axis("drive.roller_id=1:7:2").values == (1, 3, 5, 7)
    assert parse_axis("setup.temperature_c=200:200:5").values == (200.0,)


def test_lists_are_typed_by_the_field() -> None:
    assert parse_axis("drive.pinch_force_n=60,80,100").values == (60.0, 80.0, 100.0)
    assert parse_axis("drive.roller_id=3,5").values == (3, 5)
    assert parse_axis("printer.retraction.enabled=true,false").values == (True, False)
    assert parse_axis("setup.material=pla-4043d,pla-4043d-wlf").values == (
        "pla-4043d", "pla-4043d-wlf")


def test_linked_paths_share_one_axis() -> None:
    axis = parse_axis("hotend.nozzle_diameter_mm+printer.extruder.nozzle_diameter_mm=0.4,0.6")
    assert axis.paths == ("hotend.nozzle_diameter_mm", "printer.extruder.nozzle_diameter_mm")
    assert axis.values == (0.4, 0.6)


def test_intervals_only_with_sampling() -> None:
    with pytest.raises(ProfileError, match="needs random sampling"):
        parse_axis("setup.temperature_c=190:230")
    axis = parse_axis("setup.temperature_c=190:230", sampling=True)
    assert axis.interval == (190.0, 230.0) and axis.size is None


@pytest.mark.parametrize(("text", "match", "field"), [
    ("setup.temperature_c", "PATH=VALUES", None),
    ("setup.temperature_c=", "no values", "setup.temperature_c"),
    ("setup.temperature_c=abc", "not a number", "setup.temperature_c"),
    ("setup.temperature_c=190:230:0", "step must be non-zero", "setup.temperature_c"),
    ("setup.temperature_c=230:190:5", "step must be non-zero", "setup.temperature_c"),
    ("setup.temperature_c=1:2:3:4", "start:stop:step", "setup.temperature_c"),
    ("drive.roller_id=1.5", "must be an integer", "drive.roller_id"),
    ("drive.roller_id=1:2:0.5", "integer range", "drive.roller_id"),
    ("printer.retraction.enabled=maybe", "not a flag", "printer.retraction.enabled"),
    ("printer.firmware=grbl", "not one of the allowed", "printer.firmware"),
    ("drive.pinch_force_n=60,60", "repeated", "drive.pinch_force_n"),
    ("drive.roller_id+setup.material=1", "same kind", "drive.roller_id+setup.material"),
])
def test_bad_values_name_the_parameter(text: str, match: str, field: str | None) -> None:
    with pytest.raises(ProfileError, match=match) as info:
        parse_axis(text)
    assert info.value.field == field
