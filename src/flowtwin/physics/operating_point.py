"""Set-up level compositions of the physics models, and the calibration of the defaults.

Small compositions of the pure models for a :class:`~flowtwin.physics.defaults.SetupConstants`
(viscosity → resistance → lag factor; resistance → feed force → steady slip), used to
check the defaults against the seeds (docs/spec.md §4) and to derive them
(:func:`derive_tronvoll_calibration`). The dynamics engine uses the pure functions
directly with profile values.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize_scalar

from flowtwin.errors import CalibrationError
from flowtwin.physics.compliance import compliance_mm_per_n
from flowtwin.physics.defaults import HotendConstants, SetupConstants
from flowtwin.physics.drive import (
    is_grinding,
    max_feed_force_n,
    slip_gradient,
    steady_state_slip,
)
from flowtwin.physics.lag import lag_factor_s
from flowtwin.physics.nozzle import hydraulic_resistance_mpa_s_per_mm3
from flowtwin.physics.seed_tables import TRONVOLL_TABLE_II
from flowtwin.physics.units import circle_area_mm2, pa_s_to_mpa_s, percent_to_fraction
from flowtwin.physics.viscosity import viscosity_exponential_pa_s

__all__ = [
    "SteadyFeed",
    "TronvollCalibration",
    "derive_tronvoll_calibration",
    "setup_compliance_mm_per_n",
    "setup_lag_factor_s",
    "setup_resistance_mpa_s_per_mm3",
    "setup_steady_feed",
    "setup_viscosity_mpa_s",
]

FloatArray = npt.NDArray[np.float64]


def setup_viscosity_mpa_s(setup: SetupConstants, temp_c: float | None = None) -> float:
    """Melt viscosity of the set-up's material by the exponential law [002].

    Parameters
    ----------
    setup
        The set-up.
    temp_c
        Melt temperature, °C; default the set-up's.

    Returns
    -------
    float
        Viscosity, MPa·s.
    """
    t = setup.temp_c if temp_c is None else temp_c
    m = setup.material
    return float(pa_s_to_mpa_s(viscosity_exponential_pa_s(t, m.mu0_pa_s, m.b_per_c)))


def setup_resistance_mpa_s_per_mm3(setup: SetupConstants, *,
                                   layer_height_mm: npt.ArrayLike | None,
                                   temp_c: float | None = None) -> FloatArray:
    """Hot-end resistance: cone + capillary + tip back-pressure (docs/spec.md §3.3).

    Parameters
    ----------
    setup
        The set-up.
    layer_height_mm
        Layer height(s), mm, any shape; ``None`` for free extrusion (no tip term).
    temp_c
        Melt temperature, °C; default the set-up's.

    Returns
    -------
    ndarray
        ``R_hyd``, MPa·s/mm³, shape of ``layer_height_mm`` (0-d for None or a scalar).
    """
    he = setup.hotend
    return hydraulic_resistance_mpa_s_per_mm3(
        setup_viscosity_mpa_s(setup, temp_c),
        capillary_length_mm=he.land_length_mm,
        nozzle_radius_mm=he.nozzle_diameter_mm / 2.0,
        bore_radius_mm=he.bore_diameter_mm / 2.0,
        cone_half_angle_deg=he.cone_half_angle_deg,
        layer_height_mm=layer_height_mm,
        back_pressure_length_mm=he.back_pressure_length_mm,
        back_pressure_exponent=he.back_pressure_exponent,
    )


def setup_compliance_mm_per_n(setup: SetupConstants) -> float:
    """Column compliance ``k`` of the set-up [002].

    Parameters
    ----------
    setup
        The set-up (``l_rt_mm``, hot end ``l_hot_mm``, material moduli, filament diameter).

    Returns
    -------
    float
        ``k``, mm/N.
    """
    return float(compliance_mm_per_n(circle_area_mm2(setup.filament_diameter_mm),
                                     setup.l_rt_mm, setup.material.e_rt_mpa,
                                     setup.hotend.l_hot_mm, setup.material.e_hot_mpa))


def setup_lag_factor_s(setup: SetupConstants, *, layer_height_mm: npt.ArrayLike | None,
                       temp_c: float | None = None) -> FloatArray:
    """Lag factor ``K = k·R_hyd·A²`` of the set-up (docs/spec.md §3.4).

    Parameters
    ----------
    setup
        The set-up.
    layer_height_mm
        Layer height(s), mm, any shape; ``None`` for free extrusion.
    temp_c
        Melt temperature, °C; default the set-up's.

    Returns
    -------
    ndarray
        ``K``, s, shape of ``layer_height_mm``.
    """
    return lag_factor_s(setup_compliance_mm_per_n(setup),
                        setup_resistance_mpa_s_per_mm3(setup, layer_height_mm=layer_height_mm,
                                                       temp_c=temp_c),
                        circle_area_mm2(setup.filament_diameter_mm))


@dataclass(frozen=True)
class SteadyFeed:
    """Steady extrusion at a nominal feed velocity.

    Attributes
    ----------
    nominal_force_n
        Feed force the nominal velocity would need, ``R·A²·v_nom``, N.
    slip
        Steady slip fraction (:func:`flowtwin.physics.drive.steady_state_slip`).
    force_n
        Feed force actually transmitted, ``nominal·(1 − slip)``, N.
    max_force_n
        Maximum feed force of the drive at its pinch force [000 Figs. 4–8], N.
    grinding
        True when ``force_n`` exceeds ``max_force_n``.
    """

    nominal_force_n: float
    slip: float
    force_n: float
    max_force_n: float
    grinding: bool


def setup_steady_feed(setup: SetupConstants, feed_mm_s: float, *,
                      layer_height_mm: float | None = None,
                      temp_c: float | None = None) -> SteadyFeed:
    """Steady feed force and slip of a set-up at nominal feed velocity ``feed_mm_s`` (mm/s).

    Uses Eq. 6 of [000] (pinch-force law); the velocity law Eq. 8 is valid only at 80–130 N.

    Parameters
    ----------
    setup
        The set-up.
    feed_mm_s
        Nominal feed velocity ``ω·r``, mm/s.
    layer_height_mm
        Layer height, mm; ``None`` (default) for free extrusion.
    temp_c
        Melt temperature, °C; default the set-up's.

    Returns
    -------
    SteadyFeed
        Nominal and transmitted force, slip, maximum force and the grinding flag.
    """
    area = float(circle_area_mm2(setup.filament_diameter_mm))
    resistance = float(setup_resistance_mpa_s_per_mm3(setup, layer_height_mm=layer_height_mm,
                                                      temp_c=temp_c))
    nominal = resistance * area * area * feed_mm_s
    d = setup.drive
    gradient = slip_gradient(d.pinch_force_n, percent_to_fraction(d.k_s_pct_n),
                             percent_to_fraction(d.k_inf_pct_per_n))
    s = float(steady_state_slip(nominal, gradient, k_p=d.k_p))
    force = nominal * (1.0 - s)
    fmax = float(max_feed_force_n(d.pinch_force_n, d.max_feed_force_coeffs))
    return SteadyFeed(nominal, s, force, fmax, bool(is_grinding(force, fmax)))


@dataclass(frozen=True)
class TronvollCalibration:
    """Result of :func:`derive_tronvoll_calibration`.

    Attributes
    ----------
    back_pressure_length_mm
        Fitted ``λ_bp``, mm.
    e_hot_mpa
        ``E_hot`` that makes ``K(h_ref) = K_ref``, MPa.
    layer_heights_mm, lag_factors_s, targets_s
        Predicted and [001 Table II] average ``K`` per layer height.
    """

    back_pressure_length_mm: float
    e_hot_mpa: float
    layer_heights_mm: tuple[float, ...]
    lag_factors_s: tuple[float, ...]
    targets_s: tuple[float, ...]


def derive_tronvoll_calibration(setup: SetupConstants, *,
                                reference_height_mm: float = 0.2) -> TronvollCalibration:
    """Re-derive ``λ_bp`` and ``E_hot`` of the defaults from [001 Table II].

    Step 1 fits the one shape parameter ``λ_bp`` by least squares on
    ``log(K(h)/K(h_ref))`` against Table II at the other layer heights (the ratio does not
    depend on the compliance). Step 2 sets ``E_hot`` (with the set-up's ``l_hot``, ``l_RT``,
    ``E_RT``) so that ``K(h_ref)`` equals Table II.

    Parameters
    ----------
    setup
        Tronvoll's set-up (its ``λ_bp`` and ``E_hot`` are ignored and re-derived).
    reference_height_mm
        Layer height that anchors the level of ``K``, mm (0.2 in docs/spec.md §4).

    Returns
    -------
    TronvollCalibration
        The two numbers and the resulting ``K`` per layer height.
    """
    rows = {row.layer_height_mm: row.k_average_s for row in TRONVOLL_TABLE_II}
    if reference_height_mm not in rows:
        raise CalibrationError("the reference layer height is not a row of [001 Table II]",
                               field="reference_height_mm", value=reference_height_mm,
                               allowed=str(sorted(rows)))
    heights = np.array(sorted(rows))
    targets = np.array([rows[h] for h in heights])
    ref = int(np.flatnonzero(heights == reference_height_mm)[0])
    others = np.arange(heights.size) != ref

    def with_length(length_mm: float) -> SetupConstants:
        hotend: HotendConstants = replace(setup.hotend, back_pressure_length_mm=length_mm)
        return replace(setup, hotend=hotend)

    def cost(log_length: float) -> float:
        r = setup_resistance_mpa_s_per_mm3(with_length(float(np.exp(log_length))),
                                           layer_height_mm=heights)
        err = np.log(r[others] / r[ref]) - np.log(targets[others] / targets[ref])
        return float(np.sum(err * err))

    best = minimize_scalar(cost, bounds=(np.log(1e-4), np.log(1e3)), method="bounded",
                           options={"xatol": 1e-10})
    if not best.success:
        raise CalibrationError(f"back-pressure fit failed: {best.message}")
    length = float(np.exp(best.x))
    fitted = with_length(length)
    area = float(circle_area_mm2(setup.filament_diameter_mm))
    r_ref = float(setup_resistance_mpa_s_per_mm3(fitted, layer_height_mm=reference_height_mm))
    k_total = targets[ref] / (r_ref * area * area)
    k_hot = k_total - setup.l_rt_mm / (setup.material.e_rt_mpa * area)
    if k_hot <= 0.0:
        raise CalibrationError("the cold column alone is softer than the target lag needs",
                               field="l_rt_mm", value=setup.l_rt_mm)
    e_hot = setup.hotend.l_hot_mm / (k_hot * area)
    final = replace(fitted, material=replace(setup.material, e_hot_mpa=e_hot))
    lags = setup_lag_factor_s(final, layer_height_mm=heights)
    return TronvollCalibration(length, float(e_hot), tuple(heights.tolist()),
                               tuple(np.asarray(lags).tolist()), tuple(targets.tolist()))
