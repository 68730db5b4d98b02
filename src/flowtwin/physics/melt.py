"""Heat transfer in the melt zone: melt temperature at the nozzle against flow (beyond the seeds).

The seeds treat the melt as being at the set temperature (docs/spec.md §3.9). Here the filament
(radius ``R``) enters the heated length ``L`` of the hot end at ``T_in`` and moves through
it as a plug at ``v = Q/(πR²)``; the wall is at the set temperature ``T_w``. With radial
conduction only (axial conduction is negligible at the Péclet numbers of FFF) each slice
of filament is an infinite cylinder whose surface is suddenly raised to ``T_w``: the
classical solution (Carslaw & Jaeger, *Conduction of Heat in Solids*, 2nd ed. 1959, §7.4,
cylinder with constant surface temperature; the plug-flow Graetz problem) gives the
cup-mixed (bulk) temperature after the residence time ``t = L/v`` as

    θ_b = (T_w − T_b)/(T_w − T_in) = Σ_n 4/λ_n² · exp(−λ_n²·Fo),   J0(λ_n) = 0,

with the Fourier number of the residence ``Fo = α·t/R² = π·α·L/Q`` — the radius cancels:
the heat-limited flow of a hot end scales with ``α·L`` alone. This dimensionless group is
the "Cameron number" ``Ca = α·L/(R²·V)`` of Mackay et al. (J. Rheol. 61(2):229, 2017, "The
performance of the hot end in a plasticating 3D printer"), and the same conduction
picture is the heat-transfer rate limit of Go, Schiffres, Stevens & Hart (Additive
Manufacturing 16:1, 2017, "Rate limits of additive manufacturing by fused filament
fabrication and guidelines for high-throughput system design").

The real melt zone is not a plain heated tube (the melt film, the cone and the nozzle
also heat the filament, Osswald et al. 2018), so the heated length that enters ``Fo`` is
an *effective* length: the hot end's heated filament path times one factor fitted to
published maximum flows (``flowtwin.physics.defaults.MELT_LENGTH_FACTOR``; fit and check
sets in docs/physics.md §9).

Transients (flow steps, rests, pressure-advance bursts): the same plug picture with the
residence time each slice really had, :mod:`flowtwin.physics.melt_history`. The heater
block itself is held at its set point by the firmware's controller (its own lag on set
point changes is :mod:`flowtwin.dynamics.thermal`); its sag under the melt's heat demand
is not modelled.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from flowtwin.physics._checks import as_float_array, require_positive

__all__ = [
    "J0_ZEROS",
    "bulk_temperature_fraction",
    "melt_fourier_number",
    "melt_temperature_c",
    "steady_melt_temperature_c",
    "thermal_diffusivity_mm2_s",
]

FloatArray = npt.NDArray[np.float64]

#: First 40 positive zeros of the Bessel function J0 (``scipy.special.jn_zeros(0, 40)``, tabulated
#: so that the numba kernel needs no scipy; the tests compare them).
J0_ZEROS: tuple[float, ...] = (
    2.4048255576957724, 5.520078110286311, 8.653727912911013, 11.791534439014281,
    14.930917708487787, 18.071063967910924, 21.21163662987926, 24.352471530749302,
    27.493479132040253, 30.634606468431976, 33.77582021357357, 36.917098353664045,
    40.05842576462824, 43.19979171317673, 46.341188371661815, 49.482609897397815,
    52.624051841115, 55.76551075501998, 58.90698392608094, 62.048469190227166,
    65.18996480020687, 68.3314693298568, 71.47298160359374, 74.61450064370183,
    77.75602563038805, 80.89755587113763, 84.0390907769382, 87.18062984364116,
    90.32217263721049, 93.46371878194478, 96.60526795099626, 99.7468198586806,
    102.88837425419479, 106.02993091645162, 109.17148964980538, 112.3130502804949,
    115.45461265366694, 118.59617663087253, 121.73774208795096, 124.87930891323295
,
)
_LAMBDA = np.array(J0_ZEROS)
_WEIGHT = 4.0 / (_LAMBDA * _LAMBDA)
#: Below this Fo the short-time expansion is used (the series needs > 40 terms there).
_FO_SHORT = 2.0e-3
#: Up to this many values :func:`bulk_temperature_fraction` runs :func:`theta_scalar` in
#: Python; more run it compiled (the same source, the same numbers: ``tests/physics``).
_PYTHON_MAX = 16


def thermal_diffusivity_mm2_s(conductivity_w_mk: npt.ArrayLike, density_g_cm3: npt.ArrayLike,
                              heat_capacity_j_kgk: npt.ArrayLike) -> FloatArray:
    """Thermal diffusivity ``α = k/(ρ·c_p)``, mm²/s (definition).

    Parameters
    ----------
    conductivity_w_mk
        Thermal conductivity ``k``, W/(m·K) (> 0).
    density_g_cm3
        Density ``ρ``, g/cm³ (> 0).
    heat_capacity_j_kgk
        Specific heat ``c_p``, J/(kg·K) (> 0).

    Returns
    -------
    ndarray
        ``α``, mm²/s (1 m²/s = 1e6 mm²/s), broadcast shape.
    """
    k = require_positive("conductivity_w_mk", conductivity_w_mk)
    rho = require_positive("density_g_cm3", density_g_cm3) * 1000.0     # kg/m³
    cp = require_positive("heat_capacity_j_kgk", heat_capacity_j_kgk)
    return k / (rho * cp) * 1.0e6


def melt_fourier_number(q_mm3_s: npt.ArrayLike, *, diffusivity_mm2_s: float,
                        heated_length_mm: float) -> FloatArray:
    """Fourier number of the residence in the melt zone ``Fo = π·α·L/Q`` (Mackay 2017's Ca).

    ``Fo = α·t/R²`` with ``t = L/v = πR²L/Q``; ``+inf`` at ``Q ≤ 0`` (filament at rest
    reaches the wall temperature).

    Parameters
    ----------
    q_mm3_s
        Volume flow of filament through the melt zone, mm³/s, any shape.
    diffusivity_mm2_s
        Thermal diffusivity ``α``, mm²/s (> 0).
    heated_length_mm
        (Effective) heated length ``L``, mm (> 0).

    Returns
    -------
    ndarray
        ``Fo``, dimensionless, shape of ``q_mm3_s``.
    """
    a = float(require_positive("diffusivity_mm2_s", diffusivity_mm2_s))
    length = float(require_positive("heated_length_mm", heated_length_mm))
    q = as_float_array(q_mm3_s)
    with np.errstate(divide="ignore"):
        return np.where(q > 0.0, math.pi * a * length / np.where(q > 0.0, q, 1.0), np.inf)


def bulk_temperature_fraction(fourier: npt.ArrayLike) -> FloatArray:
    """Unheated fraction of the bulk temperature ``θ_b = Σ 4/λ_n²·exp(−λ_n² Fo)``.

    Cup-mixed temperature of an infinite cylinder whose surface is held at ``T_w`` from
    ``Fo = 0`` on (Carslaw & Jaeger 1959 §7.4): ``θ_b = (T_w − T_b)/(T_w − T_in)``,
    ``λ_n`` the zeros of ``J0``. For ``Fo < 2e-3`` the short-time expansion
    ``θ_b = 1 − 4·sqrt(Fo/π) + Fo + Fo^(3/2)/(3·sqrt(π))`` (Laplace-transform asymptotics
    of the same solution) replaces the series, which would need more than 40 terms.

    Parameters
    ----------
    fourier
        ``Fo ≥ 0`` (``inf`` allowed: fully heated), any shape.

    Returns
    -------
    ndarray
        ``θ_b`` in [0, 1], shape of ``fourier``.
    """
    fo = as_float_array(fourier)
    if np.any(~(fo >= 0.0)):
        from flowtwin.errors import ProfileError
        raise ProfileError("the Fourier number must be >= 0", field="fourier",
                           value=float(np.nanmin(fo)) if fo.size else None, allowed=">= 0")
    if fo.size <= _PYTHON_MAX:  # a few values: no compiled code to load
        return np.array([theta_scalar(float(x)) for x in fo.ravel()]).reshape(fo.shape)
    from flowtwin.physics._melt_kernel import theta_kernel

    out = np.empty(fo.shape)
    flat_in = fo.ravel()
    flat_out = out.ravel()
    theta_kernel(flat_in, flat_out)
    return flat_out.reshape(fo.shape)


def theta_scalar(fo: float) -> float:
    """:func:`bulk_temperature_fraction` of one ``Fo ≥ 0`` (no checks), in plain Python;
    compiled as :data:`flowtwin.physics._melt_kernel.theta_scalar` for the kernels."""
    if fo == math.inf:
        return 0.0
    if fo < _FO_SHORT:
        s = math.sqrt(fo)
        return 1.0 - 4.0 * s / math.sqrt(math.pi) + fo + fo * s / (3.0 * math.sqrt(math.pi))
    total = 0.0
    for n in range(_LAMBDA.shape[0]):
        term = _WEIGHT[n] * math.exp(-_LAMBDA[n] * _LAMBDA[n] * fo)
        total += term
        if term < 1e-18 * total:
            break
    return total


def melt_temperature_c(wall_c: npt.ArrayLike, inlet_c: npt.ArrayLike,
                       fourier: npt.ArrayLike) -> FloatArray:
    """Bulk melt temperature ``T_b = T_w − (T_w − T_in)·θ_b(Fo)``, °C (Carslaw & Jaeger §7.4).

    Parameters
    ----------
    wall_c
        Wall (set) temperature ``T_w``, °C.
    inlet_c
        Temperature of the filament entering the melt zone ``T_in``, °C.
    fourier
        ``Fo`` of :func:`melt_fourier_number`.

    Returns
    -------
    ndarray
        ``T_b``, °C, broadcast shape.
    """
    tw = as_float_array(wall_c)
    return tw - (tw - as_float_array(inlet_c)) * bulk_temperature_fraction(fourier)


def steady_melt_temperature_c(q_mm3_s: npt.ArrayLike, *, wall_c: npt.ArrayLike,
                              inlet_c: float, diffusivity_mm2_s: float,
                              heated_length_mm: float) -> FloatArray:
    """Melt temperature at the nozzle at steady flow ``Q``, °C (module docstring).

    Parameters
    ----------
    q_mm3_s
        Volume flow, mm³/s, any shape (``Q ≤ 0``: the wall temperature).
    wall_c
        Set temperature of the hot end, °C, broadcast.
    inlet_c
        Filament temperature entering the melt zone, °C.
    diffusivity_mm2_s
        ``α``, mm²/s.
    heated_length_mm
        Effective heated length ``L``, mm.

    Returns
    -------
    ndarray
        °C, broadcast shape.
    """
    fo = melt_fourier_number(q_mm3_s, diffusivity_mm2_s=diffusivity_mm2_s,
                             heated_length_mm=heated_length_mm)
    return melt_temperature_c(wall_c, inlet_c, fo)
