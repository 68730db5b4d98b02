"""Filament profile: the wire that enters the drive."""

from __future__ import annotations

import math

from pydantic import Field, model_validator

from flowtwin.profiles.base import NamedProfile

__all__ = ["FilamentProfile"]


class FilamentProfile(NamedProfile):
    """Measured filament geometry.

    The reference filament is PLA (Ingeo 4043D), 1.752 ± 0.003 mm, roundness
    0.011 ± 0.004 mm [000 §3].
    """

    diameter_mm: float = Field(gt=0.0, le=5.0, description="Mean filament diameter, mm.")
    tolerance_mm: float = Field(ge=0.0, le=1.0,
                                description="Diameter tolerance (±), mm.")
    roundness_mm: float | None = Field(None, ge=0.0, le=1.0,
                                       description="Out-of-roundness, mm (optional).")

    @model_validator(mode="after")
    def _tolerance_below_diameter(self) -> FilamentProfile:
        if self.tolerance_mm >= self.diameter_mm:
            raise ValueError(f"tolerance_mm ({self.tolerance_mm}) must be smaller than "
                             f"diameter_mm ({self.diameter_mm})")
        return self

    @property
    def area_mm2(self) -> float:
        """Cross-section ``π·d²/4`` of the mean diameter, mm²."""
        return math.pi * self.diameter_mm ** 2 / 4.0
