"""Validated profiles (printer, drive, hot end, material, filament, set-up) and the built-in
library, read from and written to TOML.

Quick start::

    from flowtwin.profiles import load_builtin, load_machine, load_rollers

    rollers = load_rollers()                 # {1: Roller, ..., 7: Roller} of [000]
    rollers[3].k_inf_per_n                   # 0.0032 (fraction/N)
    rollers[3].fp_min_discrepancy()          # 77 N tabulated vs 54.8 N from Eq. 9
    machine = load_machine("tronvoll2019")   # printer + drive + hot end + material + filament

Every user error raises :class:`flowtwin.errors.ProfileError` naming the file, the key, the
value and what is allowed. See docs/profiles.md for the schema.
"""

from flowtwin.profiles.drive import DriveProfile, SlipOverrides
from flowtwin.profiles.filament import FilamentProfile
from flowtwin.profiles.hotend import BowdenTube, HotendProfile
from flowtwin.profiles.library import (
    LibraryEntry,
    library_entries,
    library_names,
    load_builtin,
    load_roller_table,
    load_rollers,
)
from flowtwin.profiles.machine import Machine, load_machine
from flowtwin.profiles.material import (
    ArrheniusViscosity,
    ExponentialViscosity,
    MaterialProfile,
    ViscosityLaw,
    WlfViscosity,
)
from flowtwin.profiles.printer import (
    ArcSettings,
    AxisAccelerations,
    AxisFeedrates,
    AxisJerks,
    FirmwareExtruder,
    FirmwareRetraction,
    KlipperLimits,
    MarlinDeltaGeometry,
    MarlinLimits,
    Position,
    PressureAdvance,
    PrinterProfile,
)
from flowtwin.profiles.rollers import FpMinCheck, MaxFeedForceFit, Roller, RollerTable
from flowtwin.profiles.setup import SetupProfile
from flowtwin.profiles.toml_io import (
    KIND_MODELS,
    Profile,
    ProfileKind,
    kind_of,
    load_profile,
    profile_from_dict,
    profile_from_toml,
    profile_to_toml,
    save_profile,
)
from flowtwin.profiles.validation import Problem, ProfileValidationError

__all__ = [
    "KIND_MODELS",
    "ArcSettings",
    "ArrheniusViscosity",
    "AxisAccelerations",
    "AxisFeedrates",
    "AxisJerks",
    "BowdenTube",
    "DriveProfile",
    "ExponentialViscosity",
    "FilamentProfile",
    "FirmwareExtruder",
    "FirmwareRetraction",
    "FpMinCheck",
    "HotendProfile",
    "KlipperLimits",
    "LibraryEntry",
    "Machine",
    "MarlinDeltaGeometry",
    "MarlinLimits",
    "MaterialProfile",
    "MaxFeedForceFit",
    "Position",
    "PressureAdvance",
    "PrinterProfile",
    "Problem",
    "Profile",
    "ProfileKind",
    "ProfileValidationError",
    "Roller",
    "RollerTable",
    "SetupProfile",
    "SlipOverrides",
    "ViscosityLaw",
    "WlfViscosity",
    "kind_of",
    "library_entries",
    "library_names",
    "load_builtin",
    "load_machine",
    "load_profile",
    "load_roller_table",
    "load_rollers",
    "profile_from_dict",
    "profile_from_toml",
    "profile_to_toml",
    "save_profile",
]
