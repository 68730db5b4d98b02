"""Applying sweep values to a machine, and the points of grids and samples."""

from __future__ import annotations

from pathlib import Path

import pytest

from flowtwin.batch.overrides import (
    MachineBuilder,
    check_axes,
    count_points,
    grid_points,
    load_base,
    sample_points,
)
from flowtwin.batch.params import parse_axis
from flowtwin.errors import ProfileError
from flowtwin.profiles import load_builtin, load_machine, load_rollers, save_profile


@pytest.fixture(scope="module")
def builder() -> MachineBuilder:
    return MachineBuilder(load_base("tronvoll2019"))


def test_values_land_in_the_parts_they_name(builder: MachineBuilder) -> None:
    m = builder.build({"setup.temperature_c": 200.0, "drive.pinch_force_n": 60.0,
                       "printer.pressure_advance.k_s": 0.05})
    assert m.temperature_c == 200.0
    assert m.drive.pinch_force_n == 60.0
    assert m.printer.pressure_advance.k_s == 0.05
    base = builder.base
    assert (m.hotend, m.material, m.filament) == (base.hotend, base.material, base.filament)
    assert base.temperature_c == 215.0  # the base is a value: unchanged


def test_a_new_roller_id_resolves_the_roller(builder: MachineBuilder) -> None:
    m = builder.build({"drive.roller_id": 5})
    assert m.roller == load_rollers()[5]


def test_slip_overrides_reach_the_roller(builder: MachineBuilder) -> None:
    # The base drive has no [slip_overrides] table: the path creates it.
    assert builder.base.drive.slip_overrides is None
    m = builder.build({"drive.slip_overrides.k_s_pct_N": 123.0})
    assert m.roller.k_s_pct_N == 123.0
    assert m.roller.fp_min_tabulated_N is None  # dropped with new k_s (DriveProfile doc)


def test_swapping_a_part_by_name_loads_it(builder: MachineBuilder) -> None:
    m = builder.build({"setup.material": "pla-4043d-wlf"})
    assert m.material == load_builtin("pla-4043d-wlf")
    assert m.material.viscosity.law == "wlf"


def test_linked_nozzle_changes_pass_the_fit_check(builder: MachineBuilder) -> None:
    axis = parse_axis("hotend.nozzle_diameter_mm+printer.extruder.nozzle_diameter_mm=0.6")
    m = builder.build(next(grid_points([axis])))
    assert m.hotend.nozzle_diameter_mm == m.printer.extruder.nozzle_diameter_mm == 0.6


def test_out_of_range_value_names_parameter_value_and_range(builder: MachineBuilder) -> None:
    with pytest.raises(ProfileError) as info:
        check_axes(builder, [parse_axis("drive.pinch_force_n=60,600")])
    err = info.value
    assert (err.field, err.value, err.allowed) == ("drive.pinch_force_n", 600.0,
                                                   "> 0 and <= 500")
    assert "drive.pinch_force_n" in str(err) and "600" in str(err)


def test_fit_checks_of_load_machine_apply(builder: MachineBuilder) -> None:
    # 170 °C is inside SetupProfile's bounds but outside the PLA viscosity law's range.
    with pytest.raises(ProfileError, match="validity range") as info:
        check_axes(builder, [parse_axis("setup.temperature_c=170,200")])
    assert info.value.field == "setup.temperature_c" and info.value.value == 170.0
    law = builder.base.material.viscosity
    assert info.value.allowed == f"{law.t_min_c:g} <= temperature_c <= {law.t_max_c:g}"
    # The firmware's nozzle must match the hot end's.
    with pytest.raises(ProfileError, match=r"0\.4 mm nozzle") as info:
        builder.build({"hotend.nozzle_diameter_mm": 0.6})
    assert info.value.field == "hotend.nozzle_diameter_mm"


def test_a_bad_combination_names_the_point(builder: MachineBuilder) -> None:
    # Each value is fine alone; together the law's range moves away from the temperature.
    point = {"setup.temperature_c": 235.0, "material.viscosity.t_max_c": 230.0}
    builder.build({"setup.temperature_c": 235.0})
    builder.build({"material.viscosity.t_max_c": 230.0})
    with pytest.raises(ProfileError, match=r"point: setup.temperature_c=235.0"):
        builder.build(point)


def test_unknown_part_name_is_reported(builder: MachineBuilder) -> None:
    with pytest.raises(ProfileError, match="unknown built-in material") as info:
        builder.build({"setup.material": "no-such-pla"})
    assert info.value.field == "setup.material"


def test_grid_order_and_size() -> None:
    axes = [parse_axis("setup.temperature_c=190:200:10"), parse_axis("drive.roller_id=1,3,5")]
    points = list(grid_points(axes))
    assert count_points(axes) == len(points) == 6
    assert points[0] == {"setup.temperature_c": 190.0, "drive.roller_id": 1}
    assert points[1] == {"setup.temperature_c": 190.0, "drive.roller_id": 3}
    assert points[-1] == {"setup.temperature_c": 200.0, "drive.roller_id": 5}


def test_discrete_samples_are_distinct_grid_points_reproducible_by_seed() -> None:
    axes = [parse_axis("setup.temperature_c=190:230:5", sampling=True),
            parse_axis("drive.roller_id=1:7:1", sampling=True)]
    grid = list(grid_points(axes))
    a = sample_points(axes, 20, seed=3)
    assert a == sample_points(axes, 20, seed=3)
    assert a != sample_points(axes, 20, seed=4)
    assert len({tuple(p.items()) for p in a}) == 20
    assert all(p in grid for p in a)
    assert a == sorted(a, key=grid.index)  # returned in grid order
    assert len(sample_points(axes, len(grid), seed=0)) == len(grid)
    with pytest.raises(ProfileError, match="more samples than grid points") as info:
        sample_points(axes, len(grid) + 1, seed=0)
    assert info.value.field == "--sample"


def test_interval_samples_stay_inside_the_interval() -> None:
    axes = [parse_axis("setup.temperature_c=190:230", sampling=True),
            parse_axis("drive.roller_id=2:6", sampling=True),
            parse_axis("drive.pinch_force_n=60,80")]
    points = sample_points(axes, 200, seed=1)
    temps = [float(p["setup.temperature_c"]) for p in points]
    rollers = {p["drive.roller_id"] for p in points}
    assert all(190.0 <= t <= 230.0 for t in temps)
    assert rollers == {2, 3, 4, 5, 6}  # 200 draws of 5 integers: all appear (P(miss) ~ 1e-19)
    assert {p["drive.pinch_force_n"] for p in points} == {60.0, 80.0}
    assert points == sample_points(axes, 200, seed=1)
    with pytest.raises(ProfileError, match="cannot be gridded"):
        count_points(axes)


def test_setup_file_with_relative_parts_can_be_swept_from_anywhere(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    folder = tmp_path / "profiles"
    folder.mkdir()
    material = load_machine("tronvoll2019").material
    save_profile(material.model_copy(update={"name": "my-pla"}), folder / "my-pla.toml")
    (folder / "setup.toml").write_text(
        'kind = "setup"\nname = "mine"\nprinter = "prusa-i3-mk25"\n'
        'drive = "hobb-goblin-80n"\nhotend = "e3d-v6-0.4"\nmaterial = "my-pla.toml"\n'
        'filament = "pla-4043d-1.75"\ntemperature_c = 210.0\n')
    monkeypatch.chdir(tmp_path)  # not the set-up's folder
    base = load_base("profiles/setup.toml")
    assert Path(base.setup.material).is_absolute()
    swapped = MachineBuilder(base).build({"setup.temperature_c": 220.0,
                                          "setup.filament": "pla-4043d-1.75"})
    assert swapped.material.name == "my-pla" and swapped.temperature_c == 220.0
