"""Set-up resolution: the built-in machines and the checks that parts fit together."""

from __future__ import annotations

from pathlib import Path

import pytest

from flowtwin.errors import ProfileError
from flowtwin.profiles import load_builtin, load_machine, load_rollers, save_profile


def test_builtin_machines() -> None:
    m = load_machine("tronvoll2019")
    assert m.name == "tronvoll2019" and m.temperature_c == 215.0
    assert m.roller == load_rollers()[3]
    assert m.printer.name == "prusa-i3-mk25" and m.hotend.name == "e3d-v6-0.4"
    g = load_machine("greeff2017")
    assert g.roller.teeth == 24 and g.filament.diameter_mm == 2.85


def _setup_dir(tmp_path: Path, **changes: object) -> Path:
    """A set-up file referring to copies of the tronvoll2019 parts by relative path."""
    for name in ("prusa-i3-mk25", "hobb-goblin-80n", "e3d-v6-0.4", "pla-4043d",
                 "pla-4043d-1.75"):
        save_profile(load_builtin(name), tmp_path / "parts" / f"{name}.toml")
    lines = ['kind = "setup"', 'name = "mine"']
    refs = {"printer": "parts/prusa-i3-mk25.toml", "drive": "parts/hobb-goblin-80n.toml",
            "hotend": "parts/e3d-v6-0.4.toml", "material": "parts/pla-4043d.toml",
            "filament": "parts/pla-4043d-1.75.toml", "temperature_c": 215.0}
    refs.update(changes)
    for key, value in refs.items():
        lines.append(f'{key} = "{value}"' if isinstance(value, str) else f"{key} = {value}")
    path = tmp_path / "setup.toml"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_setup_file_with_relative_paths(tmp_path: Path) -> None:
    m = load_machine(_setup_dir(tmp_path))
    assert m.printer == load_builtin("prusa-i3-mk25")
    # a library name works as a reference too
    m2 = load_machine(_setup_dir(tmp_path, filament="pla-4043d-1.75"))
    assert m2.filament == m.filament


def test_missing_part_file(tmp_path: Path) -> None:
    path = _setup_dir(tmp_path, drive="parts/nope.toml")
    with pytest.raises(ProfileError, match=r"setup\.toml \[drive\]: the drive file named by "
                                           r"the set-up does not exist"):
        load_machine(path)


def test_unknown_part_name(tmp_path: Path) -> None:
    path = _setup_dir(tmp_path, hotend="e3d-v7")
    with pytest.raises(ProfileError, match=r"setup\.toml \[hotend\]: unknown built-in hotend "
                                           r"profile.*got 'e3d-v7'; allowed: one of "
                                           r".*e3d-v6-0.4, .*rf1000-0.5"):
        load_machine(path)


def test_nozzle_mismatch(tmp_path: Path) -> None:
    path = _setup_dir(tmp_path, hotend="rf1000-0.5")
    with pytest.raises(ProfileError, match=r"\[hotend\]: printer 'prusa-i3-mk25' is "
                                           r"configured for a 0.4 mm nozzle but hot end "
                                           r"'rf1000-0.5' has 0.5 mm"):
        load_machine(path)


def test_temperature_outside_viscosity_range(tmp_path: Path) -> None:
    path = _setup_dir(tmp_path, temperature_c=260.0)
    with pytest.raises(ProfileError, match=r"\[temperature_c\]: temperature outside the "
                                           r"validity range.*got 260\.0; allowed: 180 <= "
                                           r"temperature_c <= 240"):
        load_machine(path)


def test_filament_must_fit_the_bore(tmp_path: Path) -> None:
    path = _setup_dir(tmp_path, filament="pla-2.85")
    with pytest.raises(ProfileError, match=r"\[filament\]: filament 'pla-2.85' \(2.9 mm with "
                                           r"tolerance\) does not fit the bore"):
        load_machine(path)


def test_pinch_force_outside_fit_range(tmp_path: Path) -> None:
    path = _setup_dir(tmp_path)
    drive_path = tmp_path / "parts" / "hobb-goblin-80n.toml"
    drive_path.write_text(drive_path.read_text().replace("pinch_force_n = 80.0",
                                                         "pinch_force_n = 200.0"))
    with pytest.raises(ProfileError, match=r"\[drive\]: pinch force of drive "
                                           r"'hobb-goblin-80n' is outside the range.*got "
                                           r"200\.0; allowed: 10 <= pinch_force_n <= 150"):
        load_machine(path)


def test_invalid_part_names_its_own_file(tmp_path: Path) -> None:
    path = _setup_dir(tmp_path)
    part = tmp_path / "parts" / "e3d-v6-0.4.toml"
    part.write_text(part.read_text().replace("land_length_mm = 0.6", "land_length_mm = -0.6"))
    with pytest.raises(ProfileError, match=r"e3d-v6-0\.4\.toml \[land_length_mm\]: must be "
                                           r"> 0; got -0\.6"):
        load_machine(path)
