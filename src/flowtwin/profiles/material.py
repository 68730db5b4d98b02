"""Material profile: density, viscosity law, moduli and temperatures.

The viscosity law is a discriminated union on the key ``law``:

* ``exponential`` — ``μ(T) = μ0·exp(−b·T)`` [002] (T in °C);
* ``arrhenius`` — ``μ(T) = μ_ref·exp(E_a/R·(1/T_K − 1/T_ref,K))`` (beyond the seeds,
  docs/spec.md §3.3);
* ``wlf`` — ``log10(μ/μ_ref) = −C1·(T − T_ref)/(C2 + T − T_ref)`` (beyond the seeds).

Each law carries the temperature range it is valid for; this module only holds the
parameters (the functions that evaluate the laws live in :mod:`flowtwin.physics`).
Profiles give viscosity in Pa·s (docs/spec.md §2); :attr:`ExponentialViscosity.mu0_mpa_s` and
friends convert to the internal MPa·s.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from flowtwin.profiles.base import NamedProfile, ProfileModel

__all__ = [
    "PA_S_TO_MPA_S",
    "ArrheniusViscosity",
    "ExponentialViscosity",
    "MaterialProfile",
    "ViscosityLaw",
    "WlfViscosity",
]

#: 1 Pa·s = 1e-6 MPa·s (docs/spec.md §2).
PA_S_TO_MPA_S = 1e-6


class _ViscosityRange(ProfileModel):
    t_min_c: float = Field(ge=-100.0, le=600.0,
                           description="Lowest temperature the law is valid for, °C.")
    t_max_c: float = Field(ge=-100.0, le=600.0,
                           description="Highest temperature the law is valid for, °C.")

    def _check_range(self) -> None:
        if self.t_min_c >= self.t_max_c:
            raise ValueError(f"t_min_c ({self.t_min_c}) must be below t_max_c ({self.t_max_c})")

    def contains(self, temperature_c: float) -> bool:
        """True when ``temperature_c`` lies inside the validity range (inclusive)."""
        return self.t_min_c <= temperature_c <= self.t_max_c


class ExponentialViscosity(_ViscosityRange):
    """``μ(T) = μ0·exp(−b·T)``, T in °C [002 "Theory of extrusion"]."""

    law: Literal["exponential"] = Field(description="Selects this law.")
    mu0_pa_s: float = Field(gt=0.0, le=1e30, description="μ0, Pa·s (viscosity extrapolated "
                                                         "to 0 °C).")
    b_per_c: float = Field(gt=0.0, le=1.0, description="b, 1/°C.")

    @model_validator(mode="after")
    def _valid(self) -> ExponentialViscosity:
        self._check_range()
        return self

    @property
    def mu0_mpa_s(self) -> float:
        """μ0 in the internal unit MPa·s."""
        return self.mu0_pa_s * PA_S_TO_MPA_S


class ArrheniusViscosity(_ViscosityRange):
    """``μ(T) = μ_ref·exp(E_a/R·(1/(T+273.15) − 1/(T_ref+273.15)))`` (beyond the seeds)."""

    law: Literal["arrhenius"] = Field(description="Selects this law.")
    mu_ref_pa_s: float = Field(gt=0.0, le=1e30, description="μ at t_ref_c, Pa·s.")
    t_ref_c: float = Field(ge=-100.0, le=600.0, description="Reference temperature, °C.")
    activation_energy_j_mol: float = Field(gt=0.0, le=1e6,
                                           description="Flow activation energy E_a, J/mol.")

    @model_validator(mode="after")
    def _valid(self) -> ArrheniusViscosity:
        self._check_range()
        return self

    @property
    def mu_ref_mpa_s(self) -> float:
        """μ_ref in the internal unit MPa·s."""
        return self.mu_ref_pa_s * PA_S_TO_MPA_S


class WlfViscosity(_ViscosityRange):
    """``log10(μ/μ_ref) = −C1·(T − T_ref)/(C2 + T − T_ref)`` (Williams–Landel–Ferry)."""

    law: Literal["wlf"] = Field(description="Selects this law.")
    mu_ref_pa_s: float = Field(gt=0.0, le=1e30, description="μ at t_ref_c, Pa·s.")
    t_ref_c: float = Field(ge=-100.0, le=600.0, description="Reference temperature, °C.")
    c1: float = Field(gt=0.0, le=100.0, description="C1 (dimensionless, base-10 form).")
    c2_k: float = Field(gt=0.0, le=1000.0, description="C2, K (= °C difference).")

    @model_validator(mode="after")
    def _valid(self) -> WlfViscosity:
        self._check_range()
        if self.c2_k + self.t_min_c - self.t_ref_c <= 0.0:
            raise ValueError(
                f"the WLF law is singular inside its range: c2_k + t_min_c - t_ref_c = "
                f"{self.c2_k + self.t_min_c - self.t_ref_c:g} must be > 0")
        return self

    @property
    def mu_ref_mpa_s(self) -> float:
        """μ_ref in the internal unit MPa·s."""
        return self.mu_ref_pa_s * PA_S_TO_MPA_S


#: One of the three viscosity laws, chosen by the key ``law``.
ViscosityLaw = Annotated[ExponentialViscosity | ArrheniusViscosity | WlfViscosity,
                         Field(discriminator="law")]


class MaterialProfile(NamedProfile):
    """Thermoplastic properties the extrusion model needs.

    ``e_rt_mpa`` and ``e_hot_mpa`` are the moduli of the cold and the hot filament column
    in ``Δl = F/A·(l_RT/E_RT + l_hot/E_hot)`` [002]; the seeds do not give ``E_hot`` (see
    docs/profiles.md for the provisional values).
    """

    density_g_cm3: float = Field(gt=0.0, le=25.0, description="Density, g/cm³.")
    viscosity: ViscosityLaw = Field(description="Viscosity law with its parameters and "
                                                "validity range.")
    e_rt_mpa: float = Field(gt=0.0, le=1e6,
                            description="Young's modulus of the cold filament, MPa.")
    e_hot_mpa: float = Field(gt=0.0, le=1e6,
                             description="Effective modulus of the hot filament column, MPa.")
    glass_transition_c: float = Field(ge=-150.0, le=500.0,
                                      description="Glass transition temperature, °C.")
    print_temp_min_c: float = Field(gt=0.0, le=600.0,
                                    description="Lowest recommended print temperature, °C.")
    print_temp_max_c: float = Field(gt=0.0, le=600.0,
                                    description="Highest recommended print temperature, °C.")
    thermal_conductivity_w_mk: float | None = Field(None, gt=0.0, le=10.0,
                                                    description="Thermal conductivity, "
                                                                "W/(m·K) (melt model; "
                                                                "optional).")
    heat_capacity_j_kgk: float | None = Field(None, gt=0.0, le=10000.0,
                                              description="Specific heat capacity, J/(kg·K) "
                                                          "(melt model; optional).")

    @model_validator(mode="after")
    def _consistent(self) -> MaterialProfile:
        if self.print_temp_min_c >= self.print_temp_max_c:
            raise ValueError(f"print_temp_min_c ({self.print_temp_min_c}) must be below "
                             f"print_temp_max_c ({self.print_temp_max_c})")
        if self.e_hot_mpa > self.e_rt_mpa:
            raise ValueError(f"e_hot_mpa ({self.e_hot_mpa}) must not exceed e_rt_mpa "
                             f"({self.e_rt_mpa}): the hot filament is the softer one")
        return self

    @property
    def diffusivity_mm2_s(self) -> float | None:
        """Thermal diffusivity ``k/(ρ·c_p)``, mm²/s; ``None`` without thermal data."""
        if self.thermal_conductivity_w_mk is None or self.heat_capacity_j_kgk is None:
            return None
        return self.thermal_conductivity_w_mk / (self.density_g_cm3 * 1000.0
                                                 * self.heat_capacity_j_kgk) * 1.0e6

    @property
    def density_g_mm3(self) -> float:
        """Density in g/mm³ (for mass from mm³)."""
        return self.density_g_cm3 * 1e-3
