"""Melt capacity of a hot end and the one fitted constant of the melt model (beyond the seeds).

The *melt capacity* ``Q_melt`` is the flow at which the heat transfer of the melt zone
alone doubles the nozzle's pressure: the bulk melt temperature ``T_b(Q)``
(:mod:`flowtwin.physics.melt`) has fallen so far below the set temperature that
``μ(T_b)/μ(T_set) = 2`` (:data:`MELT_CAPACITY_PRESSURE_RATIO`). Above it the hot end, not
the nozzle, sets the feed force. It depends on the hot end and the material only (not on
the drive), which makes it the quantity to compare with hot-end makers' and testers'
maximum flows, measured with drives strong enough that the hot end is what gives out.
The limit of a whole machine (drive included) is :mod:`flowtwin.simulation.limits`.

``fit_melt_length_factor`` finds the effective/physical heated length ratio that makes
the capacity of one reference hot end equal to a published figure (the calibration of
``flowtwin.physics.defaults.MELT_LENGTH_FACTOR``; docs/physics.md §9).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from flowtwin.errors import ProfileError
from flowtwin.physics.melt import bulk_temperature_fraction, steady_melt_temperature_c
from flowtwin.scalar_search import bracketed_root

__all__ = ["MELT_CAPACITY_PRESSURE_RATIO", "fit_melt_length_factor", "melt_capacity_mm3_s",
           "melt_fourier_at_fraction"]

#: ``μ(T_b)/μ(T_set)`` that defines the melt capacity.
MELT_CAPACITY_PRESSURE_RATIO = 2.0

ViscosityFn = Callable[[float], float]


def melt_fourier_at_fraction(theta: float) -> float:
    """The Fourier number where the bulk temperature fraction ``θ_b(Fo)`` equals ``theta``.

    Inverse of :func:`flowtwin.physics.melt.bulk_temperature_fraction` (monotone
    decreasing from 1 at ``Fo = 0`` to 0), by :func:`~flowtwin.scalar_search.bracketed_root`.

    Parameters
    ----------
    theta
        Target fraction in (0, 1).

    Returns
    -------
    float
        ``Fo > 0``.
    """
    if not 0.0 < theta < 1.0:
        raise ProfileError("the bulk temperature fraction must lie in (0, 1)", field="theta",
                           value=theta, allowed="0 < theta < 1")
    hi = 1.0
    while float(bulk_temperature_fraction(hi)) > theta:
        hi *= 2.0
    return float(bracketed_root(lambda fo: float(bulk_temperature_fraction(fo)) - theta, 0.0, hi,
                        xtol=1e-14, rtol=1e-13))


def melt_capacity_mm3_s(viscosity_pa_s: ViscosityFn, *, set_c: float, inlet_c: float,
                        diffusivity_mm2_s: float, heated_length_mm: float,
                        pressure_ratio: float = MELT_CAPACITY_PRESSURE_RATIO) -> float:
    """Flow at which the melt zone alone multiplies the nozzle pressure by ``pressure_ratio``.

    Solves ``μ(T_b(Q))/μ(T_set) = pressure_ratio`` with ``T_b`` of
    :func:`flowtwin.physics.melt.steady_melt_temperature_c` (plug-flow conduction,
    Carslaw & Jaeger 1959 §7.4; the Fourier number ``π·α·L/Q`` of Mackay et al. 2017):
    first the melt temperature ``T*`` where the viscosity has risen by the ratio, then
    ``Q = π·α·L/Fo(θ*)`` with ``θ* = (T_set − T*)/(T_set − T_in)``.

    Parameters
    ----------
    viscosity_pa_s
        The material's law ``T (°C) → μ (Pa·s)``, decreasing in ``T``.
    set_c
        Set (wall) temperature, °C.
    inlet_c
        Filament temperature entering the melt zone, °C (< ``set_c``).
    diffusivity_mm2_s
        Thermal diffusivity of the filament, mm²/s.
    heated_length_mm
        Effective heated length, mm.
    pressure_ratio
        Viscosity (pressure) ratio that defines the capacity (> 1).

    Returns
    -------
    float
        ``Q_melt``, mm³/s; ``inf`` when the law cannot rise by the ratio above ``T_in``.
    """
    if not set_c > inlet_c:
        raise ProfileError("the set temperature must exceed the melt-zone inlet temperature",
                           field="set_c", value=set_c, allowed=f"> {inlet_c:g} °C")
    if not pressure_ratio > 1.0:
        raise ProfileError("the pressure ratio must exceed 1", field="pressure_ratio",
                           value=pressure_ratio, allowed="> 1")
    mu_set = viscosity_pa_s(set_c)
    target = pressure_ratio * mu_set
    if viscosity_pa_s(inlet_c) < target:
        return math.inf
    t_star = bracketed_root(lambda t: viscosity_pa_s(t) - target, inlet_c, set_c,
                            xtol=1e-12, rtol=1e-13)
    fo = melt_fourier_at_fraction((set_c - t_star) / (set_c - inlet_c))
    q = math.pi * diffusivity_mm2_s * heated_length_mm / fo
    # the round trip through the forward model (guards the inverse)
    back = float(steady_melt_temperature_c(q, wall_c=set_c, inlet_c=inlet_c,
                                           diffusivity_mm2_s=diffusivity_mm2_s,
                                           heated_length_mm=heated_length_mm))
    assert abs(back - t_star) < 1e-6 * max(1.0, abs(t_star)), (back, t_star)
    return q


def fit_melt_length_factor(viscosity_pa_s: ViscosityFn, *, measured_mm3_s: float,
                           set_c: float, inlet_c: float, diffusivity_mm2_s: float,
                           heated_length_mm: float,
                           pressure_ratio: float = MELT_CAPACITY_PRESSURE_RATIO) -> float:
    """Effective/physical heated-length factor that makes the capacity equal a measurement.

    ``Q_melt`` is proportional to the effective length (``Q = π·α·L_eff/Fo*``), so the
    factor is ``Q_measured/Q_melt(L_physical)``.

    Parameters
    ----------
    viscosity_pa_s, set_c, inlet_c, diffusivity_mm2_s, pressure_ratio
        As :func:`melt_capacity_mm3_s`.
    measured_mm3_s
        The published maximum flow of the reference hot end, mm³/s (> 0).
    heated_length_mm
        Its physical heated length, mm.

    Returns
    -------
    float
        The factor (dimensionless).
    """
    q1 = melt_capacity_mm3_s(viscosity_pa_s, set_c=set_c, inlet_c=inlet_c,
                             diffusivity_mm2_s=diffusivity_mm2_s,
                             heated_length_mm=heated_length_mm, pressure_ratio=pressure_ratio)
    if not (np.isfinite(q1) and measured_mm3_s > 0.0):
        raise ProfileError("cannot fit the melt length factor", field="measured_mm3_s",
                           value=measured_mm3_s, allowed="> 0 with a finite model capacity")
    return measured_mm3_s / q1
