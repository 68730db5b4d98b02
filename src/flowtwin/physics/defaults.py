"""Documented default physics constants (docs/spec.md §4), to be copied into the TOML profiles.

The seeds give the drive (roller #3, [000]), the filament (PLA 4043D, 1.752 mm,
1.25 g/cm³ [000, 001]), the nozzle (0.4 mm, 0.6 mm land [001]) and Tronvoll's and Greeff's
set-ups [001 Table I, 003]. They do not give ``E_hot``, ``l_hot``, ``μ0``, ``b``, the cone or
the back-pressure under the tip; these are chosen here so the default twin reproduces the
seeds' observed magnitudes. The derivation (docs/physics.md, re-run by
:func:`flowtwin.physics.operating_point.derive_tronvoll_calibration` and checked by
tests/physics/test_defaults.py):

1. ``μ0``, ``b``: the exponential law [002] through the two ends of the range [001] quotes
   for PLA, 1000 Pa·s at 190 °C and 200 Pa·s at 220 °C: ``b = ln 5/30 = 0.05365 /°C``,
   ``μ0 = 2.672e7 Pa·s``; ``μ(215 °C) = 261.5 Pa·s``. The Arrhenius alternative goes
   through the same two points (``E_a = 101.9 kJ/mol``); the WLF alternative uses the
   universal constants about ``T_g = 55 °C`` [003] scaled to the same ``μ(215 °C)``.
2. Nozzle (E3D V6 0.4 [001]): land 0.6 mm [001]; bore 2.0 mm and 30° cone half angle are
   assumptions (the cone adds 19 % to the capillary resistance).
3. Back-pressure length ``λ_bp``: the ONE parameter fitted to the *shape* of [001 Table II]
   (least squares on ``log K(h)/K(0.2 mm)`` at 0.1 and 0.3 mm) with ``n = 1``.
4. ``E_hot``: set so that ``K(0.2 mm) = 0.06 s`` [001 Table II] for Tronvoll's set-up, with
   ``l_hot = 10 mm`` (assumed: heat-break transition plus solid core in the melt zone),
   ``l_RT = 40 mm`` (drive gear to heat break, assumed) and ``E_RT = 3500 MPa``. Only
   ``l_hot/E_hot`` matters; the value (≈ 400 MPa) lies between rubbery PLA (a few MPa) and
   the confined (bulk-modulus-like) response of filament that fills its bore [002].
5. Greeff's gear (RF1000, 8 mm, 24 teeth [003]) is not one of [000]'s rollers. We use
   roller #2's slip parameters (``k_s = 788.5 %·N``, ``k_∞ = 0.63 %/N`` [000 Table 3]): the
   closest outer diameter (8.64 mm) and a knurl made for 3 mm filament (Ultimaker 2+
   [000 §3]), like Greeff's 2.85 mm. The pinch force of its spring-loaded bearing is
   unknown; 40 N (below roller #2's ``F_p,min = 112 N``, the steep part of Eq. 6) gives
   ≈ 10 % steady slip at 215 °C and 2 mm/s [003 §3.1] with the nozzle model in free
   extrusion (assumed hot end: 0.5 mm nozzle, 0.6 mm land, 3.2 mm bore, 30° cone).
6. Melt zone (beyond the seeds, :mod:`flowtwin.physics.melt`): PLA ``k = 0.13 W/(m·K)``,
   ``c_p = 1800 J/(kg·K)`` (typical values, provisional), filament entering at 25 °C; the
   E3D V6 heats 11.5 mm of filament path (its heater block's height). The effective length
   factor ``MELT_LENGTH_FACTOR`` is the ONE parameter of the melt model, fitted so that the
   V6's melt capacity (:mod:`flowtwin.physics.melt_capacity`) at 215 °C is the 11 mm³/s
   of the fit set (docs/physics.md §9); every other hot end is a check.
"""

from __future__ import annotations

from dataclasses import dataclass

from flowtwin.physics.seed_tables import ROLLERS

__all__ = [
    "E3D_V6_040",
    "GREEFF_RF1000",
    "HOBB_GOBLIN_80N",
    "MELT_FIT_REFERENCE",
    "MELT_INLET_C",
    "MELT_LENGTH_FACTOR",
    "PLA_4043D",
    "PLA_HEAT_CAPACITY_J_KGK",
    "PLA_THERMAL_CONDUCTIVITY_W_MK",
    "RF1000_GEAR_40N",
    "RF1000_HOTEND_050",
    "TRONVOLL_MK25",
    "V6_HEATED_LENGTH_MM",
    "DriveConstants",
    "HotendConstants",
    "MaterialConstants",
    "SetupConstants",
]


@dataclass(frozen=True)
class MaterialConstants:
    """Filament material (units in the names; viscosities in Pa·s as in the profiles)."""

    name: str
    density_g_cm3: float
    #: Young's modulus of the cold filament, MPa.
    e_rt_mpa: float
    #: Effective modulus of the hot column, MPa (fitted, see module docstring step 4).
    e_hot_mpa: float
    glass_transition_c: float
    #: Exponential law [002]: ``μ = mu0·exp(−b·T)``.
    mu0_pa_s: float
    b_per_c: float
    #: Arrhenius alternative through the same two points.
    arrhenius_mu_ref_pa_s: float
    arrhenius_t_ref_c: float
    arrhenius_ea_j_mol: float
    #: WLF alternative (universal constants about T_g).
    wlf_mu_ref_pa_s: float
    wlf_t_ref_c: float
    wlf_c1: float
    wlf_c2_k: float


@dataclass(frozen=True)
class HotendConstants:
    """Nozzle geometry, hot column length and tip back-pressure."""

    name: str
    nozzle_diameter_mm: float
    land_length_mm: float
    bore_diameter_mm: float
    cone_half_angle_deg: float
    #: Length of hot filament, mm (assumed, step 4).
    l_hot_mm: float
    #: ``λ_bp`` of :func:`flowtwin.physics.nozzle.back_pressure_resistance_mpa_s_per_mm3`.
    back_pressure_length_mm: float
    back_pressure_exponent: float


@dataclass(frozen=True)
class DriveConstants:
    """Drive roller at its pinch force; slip parameters in the paper's percent units."""

    name: str
    #: Roller number of [000] the parameters come from.
    roller: int
    gear_diameter_mm: float
    pinch_force_n: float
    k_s_pct_n: float
    k_inf_pct_per_n: float
    #: Offset ``k_p``, fraction (set-up specific, 0 until calibrated [000 §4.2]).
    k_p: float
    a_pct_per_n: float
    b_pct_per_n: float
    c_s_per_mm: float
    #: True when the pinch force lies in 80–130 N, where Eq. 8 (velocity law) is valid.
    velocity_law_valid: bool
    max_feed_force_coeffs: tuple[float, float, float]


@dataclass(frozen=True)
class SetupConstants:
    """A printer set-up of the seeds: material, hot end, drive, filament, operating point."""

    name: str
    material: MaterialConstants
    hotend: HotendConstants
    drive: DriveConstants
    filament_diameter_mm: float
    #: Cold filament length from the drive to the hot zone, mm (assumed).
    l_rt_mm: float
    temp_c: float
    #: Line width of the reference prints, mm (None: free extrusion).
    line_width_mm: float | None


PLA_4043D = MaterialConstants(
    name="PLA Ingeo 4043D",
    density_g_cm3=1.25,              # [000, 001]
    e_rt_mpa=3500.0,                 # typical PLA (datasheet ≈ 3.5 GPa)
    e_hot_mpa=414.0,                 # fitted: K(0.2 mm) = 0.06 s [001 Table II]
    glass_transition_c=55.0,         # [003 §3.2]
    mu0_pa_s=2.6718e7,               # 1000 Pa·s @ 190 °C, 200 Pa·s @ 220 °C [001]
    b_per_c=0.053648,                # ln(5)/30
    arrhenius_mu_ref_pa_s=1000.0,
    arrhenius_t_ref_c=190.0,
    arrhenius_ea_j_mol=101_880.0,    # same two points
    wlf_mu_ref_pa_s=4.024e15,        # μ(215 °C) = 261.5 Pa·s with universal constants
    wlf_t_ref_c=55.0,
    wlf_c1=17.44,
    wlf_c2_k=51.6,
)

E3D_V6_040 = HotendConstants(
    name="E3D V6, 0.4 mm",
    nozzle_diameter_mm=0.4,          # [001]
    land_length_mm=0.6,              # [001]
    bore_diameter_mm=2.0,            # assumed (1.75 mm filament path)
    cone_half_angle_deg=30.0,        # assumed
    l_hot_mm=10.0,                   # assumed
    back_pressure_length_mm=0.483,   # fitted to the shape of [001 Table II]
    back_pressure_exponent=1.0,
)

RF1000_HOTEND_050 = HotendConstants(
    name="Renkforce RF1000, 0.5 mm (assumed geometry)",
    nozzle_diameter_mm=0.5,          # [003]
    land_length_mm=0.6,              # assumed, as E3D [001]
    bore_diameter_mm=3.2,            # assumed (2.85 mm filament path)
    cone_half_angle_deg=30.0,        # assumed
    l_hot_mm=10.0,                   # assumed
    back_pressure_length_mm=0.483,   # same tip model as E3D (unused in free extrusion)
    back_pressure_exponent=1.0,
)

_R3 = ROLLERS[3]
HOBB_GOBLIN_80N = DriveConstants(
    name="Hobb-Goblin (roller #3) at 80 N",
    roller=3, gear_diameter_mm=_R3.outer_diameter_mm, pinch_force_n=80.0,
    k_s_pct_n=_R3.k_s_pct_n, k_inf_pct_per_n=_R3.k_inf_pct_per_n, k_p=0.0,
    a_pct_per_n=_R3.a_pct_per_n, b_pct_per_n=_R3.b_pct_per_n, c_s_per_mm=_R3.c_s_per_mm,
    velocity_law_valid=True, max_feed_force_coeffs=_R3.max_feed_force_coeffs,
)

_R2 = ROLLERS[2]
RF1000_GEAR_40N = DriveConstants(
    name="RF1000 8 mm 24-tooth gear (roller #2 parameters) at 40 N",
    roller=2, gear_diameter_mm=8.0, pinch_force_n=40.0,
    k_s_pct_n=_R2.k_s_pct_n, k_inf_pct_per_n=_R2.k_inf_pct_per_n, k_p=0.0,
    a_pct_per_n=_R2.a_pct_per_n, b_pct_per_n=_R2.b_pct_per_n, c_s_per_mm=_R2.c_s_per_mm,
    velocity_law_valid=False, max_feed_force_coeffs=_R2.max_feed_force_coeffs,
)

TRONVOLL_MK25 = SetupConstants(
    name="Tronvoll: Prusa i3 MK2.5, E3D V6 0.4, PLA 215 °C [001 Table I]",
    material=PLA_4043D, hotend=E3D_V6_040, drive=HOBB_GOBLIN_80N,
    filament_diameter_mm=1.752, l_rt_mm=40.0, temp_c=215.0, line_width_mm=0.48,
)

GREEFF_RF1000 = SetupConstants(
    name="Greeff: Renkforce RF1000, 0.5 mm nozzle, 2.85 mm PLA 215 °C [003]",
    material=PLA_4043D, hotend=RF1000_HOTEND_050, drive=RF1000_GEAR_40N,
    filament_diameter_mm=2.85, l_rt_mm=50.0, temp_c=215.0, line_width_mm=None,
)

#: Thermal conductivity of PLA, W/(m·K) (typical value, provisional; melt model).
PLA_THERMAL_CONDUCTIVITY_W_MK = 0.13
#: Specific heat of PLA over 25–215 °C, J/(kg·K) (typical value, provisional; melt model).
PLA_HEAT_CAPACITY_J_KGK = 1800.0
#: Temperature of the filament entering the melt zone, °C (room temperature, assumed).
MELT_INLET_C = 25.0
#: Heated length of the E3D V6 (its heater block's height), mm.
V6_HEATED_LENGTH_MM = 11.5
#: The fit point of the melt model: (hot end, published maximum flow mm³/s, set °C, source).
MELT_FIT_REFERENCE = ("e3d-v6-0.4", 11.0, 215.0,
                      "Ellis' Print Tuning Guide, 'Determining Maximum Volumetric Flow "
                      "Rate', approximate values for a 0.4 mm brass nozzle: E3D V6 11 mm³/s")
#: Effective / physical heated length of the melt model, fitted to MELT_FIT_REFERENCE with
#: PLA 4043D's exponential law (re-derived by tests/physics/test_melt.py within 0.1 %).
MELT_LENGTH_FACTOR = 2.1136
