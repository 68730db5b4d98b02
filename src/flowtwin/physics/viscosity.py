"""Melt viscosity against temperature [002]; Arrhenius and WLF as alternatives.

* Exponential law ``μ(T) = μ0·exp(−b·T)``, T in °C — the model of [002] ("the most common
  model ... can be applied without large errors to our extrusion condition").
* Arrhenius ``μ(T) = μ_ref·exp(E_a/R·(1/T_K − 1/T_ref,K))`` (beyond the seeds, docs/spec.md §3.3).
* Williams–Landel–Ferry ``log10(μ/μ_ref) = −C1·(T − T_ref)/(C2 + T − T_ref)`` (beyond the
  seeds); with ``T_ref = T_g`` the "universal" constants are ``C1 = 17.44``,
  ``C2 = 51.6 K``.

The functions take and return Pa·s, the unit of profiles and reports (docs/spec.md §2); convert
with :func:`flowtwin.physics.units.pa_s_to_mpa_s` before the nozzle models. The helpers
``*_from_two_points`` derive a law from two (temperature, viscosity) pairs such as the
200–1000 Pa·s at 220–190 °C that [001] quotes for PLA.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin.errors import ProfileError
from flowtwin.physics._checks import as_float_array, require_finite, require_positive

__all__ = [
    "GAS_CONSTANT_J_MOL_K",
    "KELVIN_OFFSET",
    "arrhenius_energy_from_two_points",
    "exponential_law_from_two_points",
    "viscosity_arrhenius_pa_s",
    "viscosity_exponential_pa_s",
    "viscosity_wlf_pa_s",
]

FloatArray = npt.NDArray[np.float64]

#: Molar gas constant R, J/(mol·K).
GAS_CONSTANT_J_MOL_K = 8.314462618
#: 0 °C in kelvin.
KELVIN_OFFSET = 273.15


def viscosity_exponential_pa_s(temp_c: npt.ArrayLike, mu0_pa_s: npt.ArrayLike,
                               b_per_c: npt.ArrayLike) -> FloatArray:
    """Exponential viscosity law ``μ(T) = μ0·exp(−b·T)`` [002].

    Parameters
    ----------
    temp_c
        Melt temperature, °C, any shape.
    mu0_pa_s
        ``μ0``, Pa·s (> 0): the law extrapolated to 0 °C.
    b_per_c
        ``b``, 1/°C (> 0).

    Returns
    -------
    ndarray
        Viscosity, Pa·s, broadcast shape.
    """
    return require_positive("mu0_pa_s", mu0_pa_s) * np.exp(
        -require_positive("b_per_c", b_per_c) * require_finite("temp_c", temp_c))


def viscosity_arrhenius_pa_s(temp_c: npt.ArrayLike, mu_ref_pa_s: npt.ArrayLike,
                             t_ref_c: npt.ArrayLike,
                             activation_energy_j_mol: npt.ArrayLike) -> FloatArray:
    """Arrhenius viscosity law ``μ = μ_ref·exp(E_a/R·(1/T_K − 1/T_ref,K))`` (beyond the seeds).

    Parameters
    ----------
    temp_c
        Melt temperature, °C (> −273.15), any shape.
    mu_ref_pa_s
        Viscosity at ``t_ref_c``, Pa·s (> 0).
    t_ref_c
        Reference temperature, °C.
    activation_energy_j_mol
        Flow activation energy ``E_a``, J/mol (> 0).

    Returns
    -------
    ndarray
        Viscosity, Pa·s, broadcast shape.
    """
    t_k = require_finite("temp_c", temp_c) + KELVIN_OFFSET
    t_ref_k = require_finite("t_ref_c", t_ref_c) + KELVIN_OFFSET
    if np.any(t_k <= 0.0) or np.any(t_ref_k <= 0.0):
        raise ProfileError("temperatures must lie above absolute zero", field="temp_c",
                           value=float(np.min(t_k) - KELVIN_OFFSET), allowed="> -273.15 °C")
    ea_r = require_positive("activation_energy_j_mol", activation_energy_j_mol) / \
        GAS_CONSTANT_J_MOL_K
    return require_positive("mu_ref_pa_s", mu_ref_pa_s) * np.exp(ea_r * (1.0 / t_k - 1.0 / t_ref_k))


def viscosity_wlf_pa_s(temp_c: npt.ArrayLike, mu_ref_pa_s: npt.ArrayLike,
                       t_ref_c: npt.ArrayLike, c1: npt.ArrayLike,
                       c2_k: npt.ArrayLike) -> FloatArray:
    """WLF viscosity law ``μ = μ_ref·10^(−C1·(T − T_ref)/(C2 + T − T_ref))`` (beyond the seeds).

    Parameters
    ----------
    temp_c
        Melt temperature, °C, any shape; must satisfy ``C2 + T − T_ref > 0``.
    mu_ref_pa_s
        Viscosity at ``t_ref_c``, Pa·s (> 0).
    t_ref_c
        Reference temperature, °C (often the glass transition).
    c1
        ``C1`` (dimensionless, base-10 form), > 0.
    c2_k
        ``C2``, K, > 0.

    Returns
    -------
    ndarray
        Viscosity, Pa·s, broadcast shape.

    Raises
    ------
    ProfileError
        If a temperature lies at or below the WLF singularity ``T = T_ref − C2``.
    """
    dt = require_finite("temp_c", temp_c) - require_finite("t_ref_c", t_ref_c)
    denom = require_positive("c2_k", c2_k) + dt
    if np.any(denom <= 0.0):
        raise ProfileError("temperature at or below the WLF singularity T_ref - C2",
                           field="temp_c", value=as_float_array(temp_c).tolist(),
                           allowed="T > T_ref - C2")
    return require_positive("mu_ref_pa_s", mu_ref_pa_s) * np.power(
        10.0, -require_positive("c1", c1) * dt / denom)


def exponential_law_from_two_points(t1_c: float, mu1_pa_s: float, t2_c: float,
                                    mu2_pa_s: float) -> tuple[float, float]:
    """Parameters ``(μ0 in Pa·s, b in 1/°C)`` of the exponential law [002] through two points.

    ``b = ln(μ1/μ2)/(T2 − T1)``, ``μ0 = μ1·exp(b·T1)``.

    Parameters
    ----------
    t1_c, t2_c
        Two different temperatures, °C.
    mu1_pa_s, mu2_pa_s
        Viscosities at those temperatures, Pa·s (> 0); the hotter must be the thinner.

    Returns
    -------
    tuple of float
        ``(mu0_pa_s, b_per_c)``.
    """
    mu1 = float(require_positive("mu1_pa_s", mu1_pa_s))
    mu2 = float(require_positive("mu2_pa_s", mu2_pa_s))
    if t1_c == t2_c or (mu1 - mu2) * (t2_c - t1_c) <= 0.0:
        raise ProfileError("two points with falling viscosity at rising temperature needed",
                           field="t2_c", value=(t1_c, mu1, t2_c, mu2),
                           allowed="T1 != T2 and mu decreasing with T")
    b = float(np.log(mu1 / mu2) / (t2_c - t1_c))
    return mu1 * float(np.exp(b * t1_c)), b


def arrhenius_energy_from_two_points(t1_c: float, mu1_pa_s: float, t2_c: float,
                                     mu2_pa_s: float) -> float:
    """Activation energy ``E_a`` (J/mol) of the Arrhenius law through two points.

    ``E_a = R·ln(μ1/μ2)/(1/T1,K − 1/T2,K)``; use ``μ_ref = μ1``, ``T_ref = T1``.

    Parameters
    ----------
    t1_c, t2_c
        Two different temperatures, °C.
    mu1_pa_s, mu2_pa_s
        Viscosities at those temperatures, Pa·s (> 0), falling with temperature.

    Returns
    -------
    float
        ``E_a``, J/mol.
    """
    mu1 = float(require_positive("mu1_pa_s", mu1_pa_s))
    mu2 = float(require_positive("mu2_pa_s", mu2_pa_s))
    if t1_c == t2_c or (mu1 - mu2) * (t2_c - t1_c) <= 0.0:
        raise ProfileError("two points with falling viscosity at rising temperature needed",
                           field="t2_c", value=(t1_c, mu1, t2_c, mu2),
                           allowed="T1 != T2 and mu decreasing with T")
    inv = 1.0 / (t1_c + KELVIN_OFFSET) - 1.0 / (t2_c + KELVIN_OFFSET)
    return GAS_CONSTANT_J_MOL_K * float(np.log(mu1 / mu2)) / inv
