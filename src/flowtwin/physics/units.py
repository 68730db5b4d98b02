"""Unit conversions and small geometric helpers used by the physics models (docs/spec.md §2).

Internal units are mm, s, N, MPa (= N/mm²), MPa·s and °C. Slip is a fraction internally;
the seeds give slip parameters in percent (``k_s`` in %·N, ``k_∞`` in %/N [000 Table 3]),
which :func:`percent_to_fraction` converts. Density: with mm, s and N the consistent mass
unit is the tonne (N·s²/mm = t), so a density in g/cm³ becomes ``1e-9`` times that in
t/mm³ (:func:`density_t_mm3`).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

__all__ = [
    "PA_S_PER_MPA_S",
    "circle_area_mm2",
    "density_t_mm3",
    "fraction_to_percent",
    "mpa_s_to_pa_s",
    "pa_s_to_mpa_s",
    "percent_to_fraction",
]

#: Pa·s in one MPa·s.
PA_S_PER_MPA_S = 1.0e6


def pa_s_to_mpa_s(visc_pa_s: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Convert a viscosity from Pa·s (profiles, reports) to MPa·s (internal).

    Parameters
    ----------
    visc_pa_s
        Viscosity, Pa·s, any shape.

    Returns
    -------
    ndarray
        Viscosity, MPa·s, same shape.
    """
    return np.asarray(visc_pa_s, dtype=np.float64) / PA_S_PER_MPA_S


def mpa_s_to_pa_s(visc_mpa_s: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Convert a viscosity from MPa·s (internal) to Pa·s.

    Parameters
    ----------
    visc_mpa_s
        Viscosity, MPa·s, any shape.

    Returns
    -------
    ndarray
        Viscosity, Pa·s, same shape.
    """
    return np.asarray(visc_mpa_s, dtype=np.float64) * PA_S_PER_MPA_S


def percent_to_fraction(value_pct: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Convert percent (e.g. ``k_s`` in %·N, ``k_∞`` in %/N [000 Table 3]) to a fraction.

    Parameters
    ----------
    value_pct
        Value in percent (or %·N, %/N), any shape.

    Returns
    -------
    ndarray
        ``value_pct / 100``, same shape.
    """
    return np.asarray(value_pct, dtype=np.float64) / 100.0


def fraction_to_percent(value: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Convert a fraction (internal slip) to percent (reports).

    Parameters
    ----------
    value
        Fraction, any shape.

    Returns
    -------
    ndarray
        ``100 · value``, same shape.
    """
    return np.asarray(value, dtype=np.float64) * 100.0


def circle_area_mm2(diameter_mm: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Area of a circle, ``π·d²/4``.

    Parameters
    ----------
    diameter_mm
        Diameter, mm, any shape.

    Returns
    -------
    ndarray
        Area, mm², same shape.
    """
    d = np.asarray(diameter_mm, dtype=np.float64)
    return np.pi * d * d / 4.0


def density_t_mm3(density_g_cm3: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Convert a density from g/cm³ to t/mm³ (= N·s²/mm⁴, consistent with mm, s, N).

    1 g/cm³ = 1e-3 g/mm³ = 1e-9 t/mm³.

    Parameters
    ----------
    density_g_cm3
        Density, g/cm³, any shape.

    Returns
    -------
    ndarray
        Density, t/mm³, same shape.
    """
    return np.asarray(density_g_cm3, dtype=np.float64) * 1.0e-9
