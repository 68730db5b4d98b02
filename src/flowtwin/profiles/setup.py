"""Set-up profile: a machine made of named printer, drive, hot end, material and filament."""

from __future__ import annotations

from pydantic import Field

from flowtwin.profiles.base import NamedProfile

__all__ = ["SetupProfile"]

class SetupProfile(NamedProfile):
    """Names the parts of one machine and the print temperature.

    Each reference is a library name (``flowtwin profiles list``) or a path to a TOML file
    ending in ``.toml``, relative to the set-up file's folder.
    :func:`flowtwin.profiles.load_machine` resolves the references and checks that the
    parts fit together.
    """

    printer: str = Field(min_length=1, max_length=500,
                       description="Printer profile name or .toml path.")
    drive: str = Field(min_length=1, max_length=500,
                       description="Drive profile name or .toml path.")
    hotend: str = Field(min_length=1, max_length=500,
                       description="Hot-end profile name or .toml path.")
    material: str = Field(min_length=1, max_length=500,
                       description="Material profile name or .toml path.")
    filament: str = Field(min_length=1, max_length=500,
                       description="Filament profile name or .toml path.")
    temperature_c: float = Field(gt=0.0, le=600.0, description="Nozzle temperature, °C.")
    line_width_mm: float | None = Field(None, gt=0.0, le=10.0,
                                        description="Nominal extrusion width, mm (optional).")
    layer_height_mm: float | None = Field(None, gt=0.0, le=5.0,
                                          description="Nominal layer height, mm (optional).")
