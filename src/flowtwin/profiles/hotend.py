"""Hot-end profile: nozzle geometry, melt-zone length, optional Bowden tube."""

from __future__ import annotations

import math

from pydantic import Field, model_validator

from flowtwin.profiles.base import NamedProfile, ProfileModel

__all__ = ["BowdenTube", "HotendProfile"]


class BowdenTube(ProfileModel):
    """A guide tube between a remote drive and the hot end (off by default).

    Its compliance (tube stretch under the feed force) and clearance take-up are a model
    beyond the seeds (docs/spec.md §3.2); this table only holds the geometry and the modulus.
    """

    length_mm: float = Field(gt=0.0, le=5000.0, description="Tube length, mm.")
    inner_diameter_mm: float = Field(gt=0.0, le=10.0, description="Tube bore, mm.")
    outer_diameter_mm: float = Field(gt=0.0, le=20.0, description="Tube outer diameter, mm.")
    modulus_mpa: float = Field(gt=0.0, le=1e5,
                               description="Young's modulus of the tube wall, MPa "
                                           "(PTFE is of order 500 MPa).")

    @model_validator(mode="after")
    def _walls(self) -> BowdenTube:
        if self.outer_diameter_mm <= self.inner_diameter_mm:
            raise ValueError(f"outer_diameter_mm ({self.outer_diameter_mm}) must exceed "
                             f"inner_diameter_mm ({self.inner_diameter_mm})")
        return self

    @property
    def wall_area_mm2(self) -> float:
        """Cross-section of the tube wall, mm²."""
        return math.pi / 4.0 * (self.outer_diameter_mm ** 2 - self.inner_diameter_mm ** 2)


class HotendProfile(NamedProfile):
    """Liquefier and nozzle geometry.

    Flow path: the filament enters the melt chamber (bore ``bore_diameter_mm``), the melt
    passes a cone of half angle ``cone_half_angle_deg`` and then the capillary ("land") of
    diameter ``nozzle_diameter_mm`` and length ``land_length_mm`` — the Hagen–Poiseuille
    section of [001 Eq. 4, 002]. ``l_hot_mm`` and ``l_rt_mm`` are the hot and cold filament
    lengths of the column compliance ``Δl = F/A·(l_RT/E_RT + l_hot/E_hot)`` [002].
    ``back_pressure_length_mm`` and ``back_pressure_exponent`` parametrise the tip
    back-pressure ``R_bp(h) = 8μ·λ_bp/(π·r⁴)·(2r/h)^n`` of
    :func:`flowtwin.physics.nozzle.back_pressure_resistance_mpa_s_per_mm3` (beyond the
    seeds; Tronvoll finds K about twice as high at 0.1 mm as at 0.3 mm layers [001 Table II]).
    ``heated_length_mm`` switches on the melt model of :mod:`flowtwin.physics.melt` (the
    filament heated over the melt zone: melt temperature against flow); without it the
    melt is at the set temperature at any flow, as in the seeds.
    """

    nozzle_diameter_mm: float = Field(gt=0.0, le=3.0,
                                      description="Capillary (orifice) diameter, mm.")
    land_length_mm: float = Field(gt=0.0, le=20.0,
                                  description="Capillary (land) length L, mm.")
    bore_diameter_mm: float = Field(gt=0.0, le=10.0,
                                    description="Melt chamber / nozzle inlet bore, mm.")
    cone_half_angle_deg: float = Field(gt=0.0, le=90.0,
                                       description="Half angle of the cone from the bore to "
                                                   "the capillary, degrees (90 = flat).")
    l_hot_mm: float = Field(gt=0.0, le=500.0,
                            description="Length of hot (above T_g) filament in the melt "
                                        "zone, mm.")
    l_rt_mm: float = Field(ge=0.0, le=5000.0,
                           description="Length of cold filament from the drive roller to "
                                       "the melt zone, mm.")
    back_pressure_length_mm: float = Field(0.0, ge=0.0, le=100.0,
                                           description="λ_bp of the layer-height dependent "
                                                       "back-pressure under the tip (beyond "
                                                       "the seeds), mm; 0 = none.")
    back_pressure_exponent: float = Field(1.0, gt=0.0, le=10.0,
                                          description="Exponent n of (2r/h)^n in the "
                                                      "back-pressure model.")
    heater_time_constant_s: float | None = Field(None, gt=0.0, le=10000.0,
                                                 description="First-order time constant of "
                                                             "the heater, s (optional).")
    bowden: BowdenTube | None = Field(None, description="Bowden tube (absent = direct "
                                                        "drive).")
    heated_length_mm: float | None = Field(None, gt=0.0, le=200.0,
                                           description="Heated length of the filament path "
                                                       "(melt zone), mm; absent = no melt "
                                                       "model: the melt is at the set "
                                                       "temperature at any flow.")
    melt_length_factor: float | None = Field(None, gt=0.0, le=20.0,
                                             description="Effective / physical heated length "
                                                         "of the melt model (default: the "
                                                         "fitted MELT_LENGTH_FACTOR).")
    melt_inlet_temperature_c: float = Field(25.0, ge=-50.0, le=300.0,
                                            description="Temperature of the filament entering "
                                                        "the melt zone, °C.")

    @model_validator(mode="after")
    def _geometry(self) -> HotendProfile:
        if self.bore_diameter_mm <= self.nozzle_diameter_mm:
            raise ValueError(f"bore_diameter_mm ({self.bore_diameter_mm}) must exceed "
                             f"nozzle_diameter_mm ({self.nozzle_diameter_mm})")
        return self

    @property
    def cone_length_mm(self) -> float:
        """Axial length of the cone, ``(D_bore − d_nozzle)/2 / tan(half angle)``, mm."""
        if self.cone_half_angle_deg >= 90.0:
            return 0.0
        radial = (self.bore_diameter_mm - self.nozzle_diameter_mm) / 2.0
        return radial / math.tan(math.radians(self.cone_half_angle_deg))

    def effective_heated_length_mm(self, default_factor: float) -> float | None:
        """Heated length the melt model uses, mm: ``heated_length_mm`` × the profile's
        ``melt_length_factor`` (or ``default_factor``); ``None`` without a melt zone."""
        if self.heated_length_mm is None:
            return None
        factor = default_factor if self.melt_length_factor is None else self.melt_length_factor
        return self.heated_length_mm * factor

    @property
    def nozzle_radius_mm(self) -> float:
        """Capillary radius, mm."""
        return self.nozzle_diameter_mm / 2.0
