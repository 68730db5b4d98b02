"""Melt flow through the hot end: pressure drops, hydraulic resistance, forces [002, 001].

The melt is Newtonian (PLA shows little shear thinning [001]); every term is linear in the
volume flow ``Q``, so the hot end is one hydraulic resistance ``R_hyd = ΔP/Q`` (MPa·s/mm³)
and the feed force on the filament is ``F = ΔP·A_in`` (docs/spec.md §3.3). Terms, inlet to outlet:

1. **Cone** from the bore radius ``R_1`` to the capillary radius ``r`` at half angle ``α``
   (beyond the seeds). Applying Hagen–Poiseuille locally, ``dP/dz = 8μQ/(π·r(z)⁴)`` with
   ``dr = −tan α·dz``, and integrating gives
   ``ΔP_cone = 8μQ/(3π·tan α)·(1/r³ − 1/R_1³)``; it tends to the capillary law as ``α → 0``
   at fixed length and vanishes for a flat entry (``α = 90°``). The transition zone from
   solid to melt is not modelled [001].
2. **Capillary** (land) of length ``L`` and radius ``r``: Hagen–Poiseuille
   ``ΔP = 8μLQ/(π·r⁴)`` [002; 001 Eq. 4].
3. **Back-pressure under the nozzle tip** at layer height ``h`` (beyond the seeds). [001]
   reports K about twice as high at 0.1 mm as at 0.3 mm layers [001 Table II] and points to
   the melt's contact with the nozzle face and the layer below [001 Fig. 6]. We model it as
   an extra resistance scaled like the capillary's,
   ``R_bp(h) = 8μ·λ_bp/(π·r⁴)·(d/h)^n``, ``d = 2r``: at ``h = d`` the tip adds the
   resistance of ``λ_bp`` mm of extra capillary. ``n = 1`` (default) reproduces Table II with
   one fitted ``λ_bp`` within ±8 %; lubrication theory of the gap under a flat nozzle face
   (Couette–Poiseuille, fixed bead width) would give ``n = 3``, which cannot reproduce
   Table II (errors up to 26 %, docs/physics.md). Free extrusion (no bed) has no such term.

Forces of [001] for the order-of-magnitude argument: the Bernoulli (acceleration) term
``F_a = ρ(v_out² − v_in²)/8·π·d_in²`` [001 Eq. 3] and the capillary friction on the outlet
section ``F_f = ΔP_f·A_out = 8π·μ·L·v_out`` [001 Eq. 4]. Note that Eq. 3 multiplies by the
filament area and Eq. 4 by the outlet area; the force the friction puts on the *filament* is
``ΔP_f·A_in`` (:func:`feed_force_n`), ``(d_in/d_out)²`` times larger than Eq. 4.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from flowtwin.errors import ProfileError
from flowtwin.physics._checks import (
    as_float_array,
    require_nonnegative,
    require_positive,
)
from flowtwin.physics.units import density_t_mm3

__all__ = [
    "back_pressure_dp_mpa",
    "back_pressure_resistance_mpa_s_per_mm3",
    "bernoulli_force_n",
    "capillary_resistance_mpa_s_per_mm3",
    "cone_dp_mpa",
    "cone_resistance_mpa_s_per_mm3",
    "feed_force_n",
    "friction_force_n",
    "hagen_poiseuille_dp_mpa",
    "hydraulic_resistance_mpa_s_per_mm3",
    "outlet_velocity_mm_s",
]

FloatArray = npt.NDArray[np.float64]


def capillary_resistance_mpa_s_per_mm3(visc_mpa_s: npt.ArrayLike, length_mm: npt.ArrayLike,
                                       radius_mm: npt.ArrayLike) -> FloatArray:
    """Hagen–Poiseuille resistance of a capillary ``8μL/(π·r⁴)`` [002; 001 Eq. 4].

    Parameters
    ----------
    visc_mpa_s
        Melt viscosity, MPa·s (> 0), any shape.
    length_mm
        Capillary length, mm (≥ 0).
    radius_mm
        Capillary radius, mm (> 0).

    Returns
    -------
    ndarray
        Resistance, MPa·s/mm³, broadcast shape.
    """
    r = require_positive("radius_mm", radius_mm)
    return 8.0 * require_positive("visc_mpa_s", visc_mpa_s) * require_nonnegative(
        "length_mm", length_mm) / (np.pi * r ** 4)


def hagen_poiseuille_dp_mpa(visc_mpa_s: npt.ArrayLike, length_mm: npt.ArrayLike,
                            radius_mm: npt.ArrayLike, q_mm3_s: npt.ArrayLike) -> FloatArray:
    """Pressure drop in the capillary ``ΔP = 8μLQ/(π·r⁴)`` [002; 001 Eq. 4].

    Parameters
    ----------
    visc_mpa_s
        Melt viscosity, MPa·s (> 0).
    length_mm
        Capillary length, mm (≥ 0).
    radius_mm
        Capillary radius, mm (> 0).
    q_mm3_s
        Volume flow, mm³/s, any shape.

    Returns
    -------
    ndarray
        Pressure drop, MPa, broadcast shape.
    """
    return capillary_resistance_mpa_s_per_mm3(visc_mpa_s, length_mm, radius_mm) * \
        as_float_array(q_mm3_s)


def cone_resistance_mpa_s_per_mm3(visc_mpa_s: npt.ArrayLike, inlet_radius_mm: npt.ArrayLike,
                                  outlet_radius_mm: npt.ArrayLike,
                                  half_angle_deg: npt.ArrayLike) -> FloatArray:
    """Resistance of the conical section ``8μ/(3π·tan α)·(1/r³ − 1/R_1³)`` (beyond the seeds).

    Local Hagen–Poiseuille integrated over a cone (module docstring).

    Parameters
    ----------
    visc_mpa_s
        Melt viscosity, MPa·s (> 0).
    inlet_radius_mm
        Bore radius ``R_1`` where the cone starts, mm (≥ outlet radius).
    outlet_radius_mm
        Capillary radius ``r`` where the cone ends, mm (> 0).
    half_angle_deg
        Half angle ``α`` of the cone, degrees, in (0, 90]; 90 is a flat entry (term 0).

    Returns
    -------
    ndarray
        Resistance, MPa·s/mm³, broadcast shape.
    """
    r_in = require_positive("inlet_radius_mm", inlet_radius_mm)
    r_out = require_positive("outlet_radius_mm", outlet_radius_mm)
    if np.any(r_in < r_out):
        raise ProfileError("the cone inlet (bore) radius must not be below the capillary "
                           "radius", field="inlet_radius_mm", value=r_in.tolist(),
                           allowed=f">= {r_out.tolist()}")
    alpha = require_positive("half_angle_deg", half_angle_deg)
    if np.any(alpha > 90.0):
        raise ProfileError("the cone half angle must lie in (0, 90] degrees",
                           field="half_angle_deg", value=alpha.tolist(), allowed="(0, 90]")
    flat = alpha >= 90.0
    tan_a = np.tan(np.radians(np.where(flat, 45.0, alpha)))
    value = 8.0 * require_positive("visc_mpa_s", visc_mpa_s) / (3.0 * np.pi * tan_a) * (
        1.0 / r_out ** 3 - 1.0 / r_in ** 3)
    return np.where(flat, 0.0, value)


def cone_dp_mpa(visc_mpa_s: npt.ArrayLike, inlet_radius_mm: npt.ArrayLike,
                outlet_radius_mm: npt.ArrayLike, half_angle_deg: npt.ArrayLike,
                q_mm3_s: npt.ArrayLike) -> FloatArray:
    """Pressure drop in the cone, MPa: :func:`cone_resistance_mpa_s_per_mm3` times ``Q``.

    Parameters
    ----------
    visc_mpa_s, inlet_radius_mm, outlet_radius_mm, half_angle_deg
        See :func:`cone_resistance_mpa_s_per_mm3`.
    q_mm3_s
        Volume flow, mm³/s, any shape.

    Returns
    -------
    ndarray
        Pressure drop, MPa, broadcast shape.
    """
    return cone_resistance_mpa_s_per_mm3(visc_mpa_s, inlet_radius_mm, outlet_radius_mm,
                                         half_angle_deg) * as_float_array(q_mm3_s)


def back_pressure_resistance_mpa_s_per_mm3(visc_mpa_s: npt.ArrayLike,
                                           layer_height_mm: npt.ArrayLike, *,
                                           nozzle_radius_mm: npt.ArrayLike,
                                           back_pressure_length_mm: npt.ArrayLike,
                                           exponent: float = 1.0) -> FloatArray:
    """Layer-height dependent back-pressure under the nozzle tip (beyond the seeds).

    ``R_bp(h) = 8μ·λ_bp/(π·r⁴)·(2r/h)^n`` — see the module docstring for why ``n = 1`` and
    the calibration of ``λ_bp`` against [001 Table II] in docs/physics.md.

    Parameters
    ----------
    visc_mpa_s
        Melt viscosity, MPa·s (> 0).
    layer_height_mm
        Layer height ``h``, mm (> 0), any shape.
    nozzle_radius_mm
        Capillary radius ``r``, mm (> 0).
    back_pressure_length_mm
        ``λ_bp``: extra capillary length equivalent to the tip at ``h = 2r``, mm (≥ 0).
    exponent
        ``n`` (> 0); 1 fits [001 Table II], 3 is the lubrication-theory form.

    Returns
    -------
    ndarray
        Resistance, MPa·s/mm³, broadcast shape.
    """
    r = require_positive("nozzle_radius_mm", nozzle_radius_mm)
    h = require_positive("layer_height_mm", layer_height_mm)
    n = require_positive("exponent", exponent)
    return capillary_resistance_mpa_s_per_mm3(visc_mpa_s, back_pressure_length_mm, r) * \
        np.power(2.0 * r / h, n)


def back_pressure_dp_mpa(visc_mpa_s: npt.ArrayLike, layer_height_mm: npt.ArrayLike,
                         q_mm3_s: npt.ArrayLike, *, nozzle_radius_mm: npt.ArrayLike,
                         back_pressure_length_mm: npt.ArrayLike,
                         exponent: float = 1.0) -> FloatArray:
    """Back-pressure under the nozzle tip, MPa: the resistance above times ``Q``.

    Parameters
    ----------
    visc_mpa_s, layer_height_mm
        See :func:`back_pressure_resistance_mpa_s_per_mm3`.
    q_mm3_s
        Volume flow, mm³/s, any shape.
    nozzle_radius_mm, back_pressure_length_mm, exponent
        See :func:`back_pressure_resistance_mpa_s_per_mm3`.

    Returns
    -------
    ndarray
        Pressure, MPa, broadcast shape.
    """
    return back_pressure_resistance_mpa_s_per_mm3(
        visc_mpa_s, layer_height_mm, nozzle_radius_mm=nozzle_radius_mm,
        back_pressure_length_mm=back_pressure_length_mm, exponent=exponent,
    ) * as_float_array(q_mm3_s)


def hydraulic_resistance_mpa_s_per_mm3(visc_mpa_s: npt.ArrayLike, *,
                                       capillary_length_mm: float,
                                       nozzle_radius_mm: float,
                                       bore_radius_mm: float,
                                       cone_half_angle_deg: float,
                                       layer_height_mm: npt.ArrayLike | None = None,
                                       back_pressure_length_mm: float = 0.0,
                                       back_pressure_exponent: float = 1.0) -> FloatArray:
    """Total hydraulic resistance of the hot end ``R_hyd = ΔP/Q`` (cone + capillary + tip).

    Parameters
    ----------
    visc_mpa_s
        Melt viscosity, MPa·s (> 0), any shape (e.g. one value per temperature).
    capillary_length_mm
        Land length ``L``, mm.
    nozzle_radius_mm
        Capillary radius ``r``, mm.
    bore_radius_mm
        Melt chamber radius ``R_1`` where the cone starts, mm.
    cone_half_angle_deg
        Cone half angle, degrees, in (0, 90].
    layer_height_mm
        Layer height, mm, broadcast; ``None`` for free extrusion (no back-pressure term).
    back_pressure_length_mm
        ``λ_bp`` of :func:`back_pressure_resistance_mpa_s_per_mm3`, mm.
    back_pressure_exponent
        ``n`` of :func:`back_pressure_resistance_mpa_s_per_mm3`.

    Returns
    -------
    ndarray
        ``R_hyd``, MPa·s/mm³, broadcast shape.
    """
    total = capillary_resistance_mpa_s_per_mm3(visc_mpa_s, capillary_length_mm,
                                               nozzle_radius_mm) + \
        cone_resistance_mpa_s_per_mm3(visc_mpa_s, bore_radius_mm, nozzle_radius_mm,
                                      cone_half_angle_deg)
    if layer_height_mm is not None:
        total = total + back_pressure_resistance_mpa_s_per_mm3(
            visc_mpa_s, layer_height_mm, nozzle_radius_mm=nozzle_radius_mm,
            back_pressure_length_mm=back_pressure_length_mm, exponent=back_pressure_exponent)
    return total


def feed_force_n(dp_mpa: npt.ArrayLike, filament_area_mm2: npt.ArrayLike) -> FloatArray:
    """Feed force the melt pressure puts on the filament, ``F = ΔP·A_in`` (docs/spec.md §3.3), N.

    Parameters
    ----------
    dp_mpa
        Pressure drop from the filament face to the outlet, MPa, any shape.
    filament_area_mm2
        Filament cross-section ``A_in``, mm² (> 0).

    Returns
    -------
    ndarray
        Force, N, broadcast shape.
    """
    return as_float_array(dp_mpa) * require_positive("filament_area_mm2", filament_area_mm2)


def outlet_velocity_mm_s(q_mm3_s: npt.ArrayLike, d_out_mm: npt.ArrayLike) -> FloatArray:
    """Mean melt velocity in the capillary ``v_out = Q/(π·d_out²/4)`` (continuity).

    Parameters
    ----------
    q_mm3_s
        Volume flow, mm³/s, any shape.
    d_out_mm
        Capillary diameter, mm (> 0).

    Returns
    -------
    ndarray
        ``v_out``, mm/s, broadcast shape.
    """
    d = require_positive("d_out_mm", d_out_mm)
    return as_float_array(q_mm3_s) / (np.pi * d * d / 4.0)


def bernoulli_force_n(density_g_cm3: npt.ArrayLike, v_out_mm_s: npt.ArrayLike,
                      d_in_mm: npt.ArrayLike, d_out_mm: npt.ArrayLike) -> FloatArray:
    """Force from accelerating the melt ``F_a = ρ(v_out² − v_in²)/8·π·d_in²`` [001 Eq. 3].

    ``v_in = v_out·(d_out/d_in)²`` by continuity, so
    ``F_a = ρ·v_out²·(1 − d_out⁴/d_in⁴)/8·π·d_in²`` [001 Eq. 3].

    Parameters
    ----------
    density_g_cm3
        Melt density, g/cm³ (> 0); converted to t/mm³ so the force comes out in N.
    v_out_mm_s
        Outlet velocity, mm/s, any shape.
    d_in_mm
        Filament diameter, mm (> 0).
    d_out_mm
        Capillary diameter, mm (> 0).

    Returns
    -------
    ndarray
        Force on the filament, N, broadcast shape.
    """
    rho = density_t_mm3(require_positive("density_g_cm3", density_g_cm3))
    d_in = require_positive("d_in_mm", d_in_mm)
    d_out = require_positive("d_out_mm", d_out_mm)
    v_out = as_float_array(v_out_mm_s)
    v_in = v_out * (d_out / d_in) ** 2
    return rho * (v_out * v_out - v_in * v_in) / 8.0 * np.pi * d_in * d_in


def friction_force_n(visc_mpa_s: npt.ArrayLike, length_mm: npt.ArrayLike,
                     v_out_mm_s: npt.ArrayLike) -> FloatArray:
    """Capillary friction on the outlet section ``F_f = ΔP_f·A_out = 8π·μ·L·v_out`` [001 Eq. 4].

    Parameters
    ----------
    visc_mpa_s
        Melt viscosity, MPa·s (> 0) (1 Pa·s = 1e-6 MPa·s).
    length_mm
        Capillary (land) length, mm (≥ 0).
    v_out_mm_s
        Outlet velocity, mm/s, any shape.

    Returns
    -------
    ndarray
        Force, N, broadcast shape. Multiply the pressure by the filament area instead
        (:func:`feed_force_n`) for the force on the filament.
    """
    return 8.0 * np.pi * require_positive("visc_mpa_s", visc_mpa_s) * require_nonnegative(
        "length_mm", length_mm) * as_float_array(v_out_mm_s)
