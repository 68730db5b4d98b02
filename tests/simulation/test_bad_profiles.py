"""Physically impossible profiles and data outside the roller's range: clear errors."""

from __future__ import annotations

from pathlib import Path

import pytest

from flowtwin.errors import ProfileError
from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.profiles import load_builtin, load_machine
from flowtwin.profiles.machine import Machine
from flowtwin.simulation import simulate


def _with(machine: Machine, **parts: object) -> Machine:
    fields = {"setup": machine.setup, "printer": machine.printer, "drive": machine.drive,
              "roller": machine.roller, "hotend": machine.hotend,
              "material": machine.material, "filament": machine.filament}
    fields.update(parts)
    return Machine(**fields)  # type: ignore[arg-type]


@pytest.mark.parametrize(("kind", "name", "key", "value"), [
    ("material", "pla-4043d", "e_hot_mpa", -5.0),
    ("material", "pla-4043d", "density_g_cm3", 0.0),
    ("hotend", "e3d-v6-0.4", "nozzle_diameter_mm", 0.0),
    ("hotend", "e3d-v6-0.4", "land_length_mm", -0.6),
])
def test_impossible_values_are_refused_with_their_key(kind: str, name: str, key: str,
                                                      value: float) -> None:
    from flowtwin.profiles import profile_from_dict

    data = load_builtin(name).model_dump(mode="json")  # type: ignore[union-attr]
    data[key] = value
    data["kind"] = kind
    with pytest.raises(ProfileError, match=key):
        profile_from_dict(data, kind, source=f"{name}.toml")  # type: ignore[arg-type]


def test_negative_viscosity_parameter_is_refused() -> None:
    from flowtwin.profiles import profile_from_dict

    data = load_builtin("pla-4043d").model_dump(mode="json")  # type: ignore[union-attr]
    data["viscosity"]["mu0_pa_s"] = -1.0
    data["kind"] = "material"
    with pytest.raises(ProfileError, match="mu0_pa_s"):
        profile_from_dict(data, "material")


def test_pinch_force_outside_the_rollers_data_is_an_error(tmp_path: Path) -> None:
    setup = tmp_path / "setup.toml"
    drive = tmp_path / "drive.toml"
    drive.write_text('kind = "drive"\nname = "strong"\nroller_id = 3\npinch_force_n = 200.0\n'
                     "rotation_distance_mm = 25.07\n")
    setup.write_text('kind = "setup"\nname = "s"\nprinter = "generic-klipper"\n'
                     f'drive = "{drive}"\nhotend = "e3d-v6-0.4"\nmaterial = "pla-4043d"\n'
                     'filament = "pla-4043d-1.75"\ntemperature_c = 215.0\n')
    with pytest.raises(ProfileError, match="pinch"):
        load_machine(setup)


def test_temperature_outside_the_viscosity_law_is_an_explicit_warning(tmp_path: Path) -> None:
    gcode = tmp_path / "hot.gcode"
    write_print(gcode, PrintSpec(layers=2, nozzle_temp_c=400.0))
    result = simulate(gcode)
    assert any("outside the viscosity law's range" in w for w in result.warnings)
    assert any("outside the viscosity law's range" in w
               for w in result.summary().warnings)
