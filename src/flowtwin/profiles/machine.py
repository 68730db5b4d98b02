"""Resolve a set-up into a :class:`Machine`: every part loaded and checked to fit."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from flowtwin.errors import ProfileError
from flowtwin.profiles.drive import DriveProfile
from flowtwin.profiles.filament import FilamentProfile
from flowtwin.profiles.hotend import HotendProfile
from flowtwin.profiles.library import load_builtin, load_rollers
from flowtwin.profiles.material import MaterialProfile
from flowtwin.profiles.printer import PrinterProfile
from flowtwin.profiles.rollers import Roller
from flowtwin.profiles.setup import SetupProfile
from flowtwin.profiles.toml_io import Profile, ProfileKind, load_profile

__all__ = ["Machine", "check_machine", "load_machine"]


@dataclass(frozen=True, slots=True)
class Machine:
    """A resolved set-up: the profiles of one machine and its print temperature.

    Attributes
    ----------
    setup
        The set-up profile that named the parts.
    printer, drive, hotend, material, filament
        The parts.
    roller
        The drive's roller with the drive's slip overrides applied.
    """

    setup: SetupProfile
    printer: PrinterProfile
    drive: DriveProfile
    roller: Roller
    hotend: HotendProfile
    material: MaterialProfile
    filament: FilamentProfile

    @property
    def name(self) -> str:
        """Name of the set-up."""
        return self.setup.name

    @property
    def temperature_c(self) -> float:
        """Nozzle temperature, °C."""
        return self.setup.temperature_c


def _is_path_ref(ref: str) -> bool:
    return ref.endswith(".toml")


def _resolve(ref: str, kind: ProfileKind, base_dir: Path | None, setup_src: str) -> Profile:
    if _is_path_ref(ref):
        path = Path(ref)
        if not path.is_absolute() and base_dir is not None:
            path = base_dir / path
        if not path.is_file():
            raise ProfileError(f"the {kind} file named by the set-up does not exist",
                               source=setup_src, field=kind, value=str(path),
                               allowed="a library name or an existing .toml file")
        return load_profile(path, kind)
    try:
        return load_builtin(ref, kind)
    except ProfileError as exc:
        raise ProfileError(exc.message, source=setup_src, field=kind, value=ref,
                           allowed=exc.allowed) from exc


def load_machine(setup: str | os.PathLike[str] | SetupProfile) -> Machine:
    """Load a set-up and every part it names, and check that they fit together.

    Parameters
    ----------
    setup
        A built-in set-up name (``"tronvoll2019"``), a path to a set-up ``.toml`` file, or
        a :class:`SetupProfile`. Part references ending in ``.toml`` are paths relative to
        the set-up file's folder (or to the working directory for a profile object or a
        built-in set-up); other references are built-in names.

    Returns
    -------
    Machine

    Raises
    ------
    ProfileError
        A part cannot be found or is invalid, or the parts do not fit: the firmware's
        nozzle diameter differs from the hot end's, the filament does not fit the hot end
        bore or the Bowden tube, the temperature is outside the viscosity law's validity
        range, or the pinch force is outside the roller's maximum-feed-force fit.
    """
    base_dir: Path | None
    if isinstance(setup, SetupProfile):
        setup_profile, setup_src, base_dir = setup, f"setup {setup.name!r}", None
    else:
        text = os.fspath(setup)
        if _is_path_ref(text) or Path(text).is_file():
            setup_profile = load_profile(text, "setup")
            setup_src, base_dir = text, Path(text).resolve().parent
        else:
            loaded = load_builtin(text, "setup")
            assert isinstance(loaded, SetupProfile)
            setup_profile, setup_src, base_dir = loaded, f"flowtwin/data/setups/{text}.toml", None

    s = setup_profile
    printer = _resolve(s.printer, "printer", base_dir, setup_src)
    drive = _resolve(s.drive, "drive", base_dir, setup_src)
    hotend = _resolve(s.hotend, "hotend", base_dir, setup_src)
    material = _resolve(s.material, "material", base_dir, setup_src)
    filament = _resolve(s.filament, "filament", base_dir, setup_src)
    assert isinstance(printer, PrinterProfile)
    assert isinstance(drive, DriveProfile)
    assert isinstance(hotend, HotendProfile)
    assert isinstance(material, MaterialProfile)
    assert isinstance(filament, FilamentProfile)
    roller = drive.resolve_roller(load_rollers())
    machine = Machine(setup=s, printer=printer, drive=drive, roller=roller, hotend=hotend,
                      material=material, filament=filament)
    check_machine(machine, setup_src)
    return machine


def check_machine(m: Machine, src: str) -> None:
    """Check that the parts of ``m`` fit together (nozzle, filament and bore, temperature
    within the viscosity law, pinch force within the roller's data); raise
    :class:`~flowtwin.errors.ProfileError` naming ``src`` otherwise."""
    fw_nozzle = m.printer.extruder.nozzle_diameter_mm
    if abs(fw_nozzle - m.hotend.nozzle_diameter_mm) > 1e-9:
        raise ProfileError(
            f"printer {m.printer.name!r} is configured for a {fw_nozzle:g} mm nozzle but hot "
            f"end {m.hotend.name!r} has {m.hotend.nozzle_diameter_mm:g} mm",
            source=src, field="hotend", value=m.hotend.name,
            allowed=f"a hot end with nozzle_diameter_mm = {fw_nozzle:g}")
    d_fil = m.filament.diameter_mm + m.filament.tolerance_mm
    if d_fil >= m.hotend.bore_diameter_mm:
        raise ProfileError(
            f"filament {m.filament.name!r} ({d_fil:g} mm with tolerance) does not fit the "
            f"bore of hot end {m.hotend.name!r}", source=src, field="filament",
            value=m.filament.name, allowed=f"diameter + tolerance < "
                                           f"{m.hotend.bore_diameter_mm:g} mm")
    if m.hotend.bowden is not None and d_fil >= m.hotend.bowden.inner_diameter_mm:
        raise ProfileError(
            f"filament {m.filament.name!r} does not fit the Bowden tube of hot end "
            f"{m.hotend.name!r}", source=src, field="filament", value=m.filament.name,
            allowed=f"diameter + tolerance < {m.hotend.bowden.inner_diameter_mm:g} mm")
    law = m.material.viscosity
    if not law.contains(m.temperature_c):
        raise ProfileError(
            f"temperature outside the validity range of the {law.law} viscosity law of "
            f"material {m.material.name!r}", source=src, field="temperature_c",
            value=m.temperature_c, allowed=f"{law.t_min_c:g} <= temperature_c <= "
                                           f"{law.t_max_c:g}")
    fit = m.roller.max_feed_force_fit
    if fit is not None and not fit.fp_min_valid_N <= m.drive.pinch_force_n <= fit.fp_max_valid_N:
        raise ProfileError(
            f"pinch force of drive {m.drive.name!r} is outside the range of the roller's "
            f"maximum-feed-force fit {fit.figure}", source=src, field="drive",
            value=m.drive.pinch_force_n,
            allowed=f"{fit.fp_min_valid_N:g} <= pinch_force_n <= {fit.fp_max_valid_N:g}")
