"""Viscosity law from a temperature sweep of feed force, slip or viscosity.

What to measure: extrude into air (no bed, so no tip back-pressure) at one constant
volumetric flow ``Q`` and a series of nozzle temperatures, waiting at each until the force
is steady; record the temperature and either the feed force on the filament (a load cell
under the drive or the hot end), or the drive's slip (with a drive profile), or a
viscosity measured elsewhere. Columns (CSV, see :mod:`flowtwin.calibration.csvdata`):

* ``temp_c`` — melt temperature, °C (required);
* ``viscosity_pa_s`` — viscosity, Pa·s; or
* ``feed_force_n`` and ``flow_mm3_s`` — steady feed force (N) at that flow (mm³/s); or
* ``slip_pct`` and ``flow_mm3_s`` — steady drive slip (%) at that flow.

A feed force becomes a viscosity through the hot end's hydraulic resistance, which is
linear in ``μ`` (Newtonian melt [001]): ``F = ΔP·A_fil = μ·R₁·Q·A_fil`` with
``R₁ = R_hyd(μ = 1)`` of the cone and capillary (Hagen–Poiseuille, [002], [001 Eq. 4];
:func:`flowtwin.physics.nozzle.hydraulic_resistance_mpa_s_per_mm3`). A slip becomes a feed
force through the drive's slip law ``s = k_p + s'·F`` [000 Eq. 6] with
``s' = k_s/F_p² + k_∞``, or ``s' = a + b·exp(−c·v_fil)`` [000 Eq. 8] for a
velocity-dependent roller at 80–130 N pinch force, ``v_fil = Q/A_fil``.

The laws (:mod:`flowtwin.physics.viscosity`, keys of the material profile's
``[viscosity]`` table) are fitted to ``ln μ`` by least squares — the scatter of a force
measurement is roughly proportional to the force:

* ``exponential`` ``μ = μ0·exp(−b·T)`` [002]: fitted as ``ln μ = α − b·(T − T̄)``;
* ``arrhenius`` ``μ = μ_ref·exp(E_a/R·(1/T_K − 1/T_ref,K))``;
* ``wlf`` ``log10(μ/μ_ref) = −C1·(T − T_ref)/(C2 + T − T_ref)``, optionally with ``C2``
  fixed (``C1`` and ``C2`` are hard to separate over a narrow temperature range).

Uncertainties are 1σ standard errors; ``μ0`` (the law extrapolated to 0 °C) gets its
error from the covariance of ``α`` and ``b`` (delta method).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, ValidationError

from flowtwin.calibration.csvdata import Column, Table
from flowtwin.calibration.fits.fitting import CurveFit, fit_curve, propagate_std
from flowtwin.errors import CalibrationError, DataError
from flowtwin.physics.drive import slip_gradient, slip_gradient_velocity
from flowtwin.physics.nozzle import hydraulic_resistance_mpa_s_per_mm3
from flowtwin.physics.units import circle_area_mm2
from flowtwin.physics.viscosity import (
    GAS_CONSTANT_J_MOL_K,
    KELVIN_OFFSET,
    viscosity_arrhenius_pa_s,
    viscosity_exponential_pa_s,
    viscosity_wlf_pa_s,
)
from flowtwin.profiles.drive import DriveProfile
from flowtwin.profiles.hotend import HotendProfile
from flowtwin.profiles.material import ArrheniusViscosity, ExponentialViscosity, WlfViscosity
from flowtwin.profiles.rollers import Roller

__all__ = [
    "VISCOSITY_COLUMNS",
    "ViscosityFit",
    "ViscosityLawName",
    "ViscositySweep",
    "apparent_viscosity_pa_s",
    "feed_force_from_slip_n",
    "fit_viscosity_law",
    "sweep_from_table",
]

FloatArray = npt.NDArray[np.float64]
ViscosityLawName = Literal["exponential", "arrhenius", "wlf"]
_LAWS = ("exponential", "arrhenius", "wlf")
_PA_S_PER_MPA_S = 1e6

#: Columns of a temperature-sweep file.
VISCOSITY_COLUMNS = (
    Column("temp_c", "melt temperature, °C", lower=-KELVIN_OFFSET, upper=600.0,
           lower_open=True),
    Column("viscosity_pa_s", "melt viscosity, Pa·s", required=False, lower=0.0,
           lower_open=True),
    Column("feed_force_n", "steady feed force on the filament, N", required=False,
           lower=0.0, lower_open=True, upper=1e4),
    Column("slip_pct", "steady drive slip, %", required=False, upper=100.0),
    Column("flow_mm3_s", "volumetric flow during the measurement, mm³/s", required=False,
           lower=0.0, lower_open=True, upper=1e4),
)


@dataclass(frozen=True)
class ViscositySweep:
    """Viscosity at each temperature of a sweep.

    Attributes
    ----------
    temp_c
        Temperatures, °C, shape ``(n,)``.
    visc_pa_s
        Viscosities, Pa·s, shape ``(n,)``.
    basis
        What was measured: ``"viscosity"``, ``"feed_force"`` or ``"slip"``.
    source
        File name.
    notes
        How the viscosities were derived (hot end, filament, drive).
    """

    temp_c: FloatArray
    visc_pa_s: FloatArray
    basis: str
    source: str = "<data>"
    notes: tuple[str, ...] = ()


def apparent_viscosity_pa_s(feed_force_n: npt.ArrayLike, flow_mm3_s: npt.ArrayLike, *,
                            hotend: HotendProfile, filament_diameter_mm: float) -> FloatArray:
    """Viscosity from a steady feed force: ``μ = F/(R₁·Q·A_fil)`` ([002], [001 Eq. 4]).

    ``R₁`` is the hot end's hydraulic resistance per unit viscosity (cone + capillary, free
    extrusion: no bed back-pressure), so this is the inverse of
    ``F = ΔP·A_fil`` with ``ΔP = R_hyd(μ)·Q`` (docs/spec.md §3.3).

    Parameters
    ----------
    feed_force_n
        Steady feed force, N (> 0), any shape.
    flow_mm3_s
        Volumetric flow, mm³/s (> 0), broadcast.
    hotend
        Nozzle geometry.
    filament_diameter_mm
        Filament diameter, mm.

    Returns
    -------
    ndarray
        Viscosity, Pa·s, broadcast shape.
    """
    r1 = float(hydraulic_resistance_mpa_s_per_mm3(
        1.0, capillary_length_mm=hotend.land_length_mm,
        nozzle_radius_mm=hotend.nozzle_radius_mm,
        bore_radius_mm=hotend.bore_diameter_mm / 2.0,
        cone_half_angle_deg=hotend.cone_half_angle_deg))
    area = float(circle_area_mm2(filament_diameter_mm))
    force = np.asarray(feed_force_n, dtype=np.float64)
    flow = np.asarray(flow_mm3_s, dtype=np.float64)
    return force / (r1 * flow * area) * _PA_S_PER_MPA_S


def feed_force_from_slip_n(slip: npt.ArrayLike, flow_mm3_s: npt.ArrayLike, *,
                           drive: DriveProfile, roller: Roller,
                           filament_diameter_mm: float) -> FloatArray:
    """Feed force from slip by inverting ``s = k_p + s'·F`` [000 Eq. 6 / Eq. 8].

    ``s'`` is Eq. 8's ``a + b·exp(−c·v_fil)`` (``v_fil = Q/A_fil``) for a velocity-dependent
    roller pinched with 80–130 N (the range Eq. 8 was measured in), else Eq. 6's
    ``k_s/F_p² + k_∞``.

    Parameters
    ----------
    slip
        Slip, fraction (not %), any shape.
    flow_mm3_s
        Volumetric flow, mm³/s, broadcast.
    drive
        Drive profile (pinch force, ``k_p``).
    roller
        The drive's roller (``drive.resolve_roller(load_rollers())``).
    filament_diameter_mm
        Filament diameter, mm.

    Returns
    -------
    ndarray
        Feed force, N, broadcast shape.
    """
    s = np.asarray(slip, dtype=np.float64)
    fp = drive.pinch_force_n
    if roller.velocity_dependent and 80.0 <= fp <= 130.0:
        v_fil = np.asarray(flow_mm3_s, dtype=np.float64) / float(
            circle_area_mm2(filament_diameter_mm))
        a, b, c = roller.a_per_n, roller.b_per_n, roller.c_s_per_mm
        assert a is not None and b is not None and c is not None  # the Roller validates
        gradient = slip_gradient_velocity(v_fil, a, b, c)
    else:
        gradient = slip_gradient(fp, roller.k_s_n, roller.k_inf_per_n)
    return (s - drive.k_p) / gradient


def sweep_from_table(table: Table, *, hotend: HotendProfile | None = None,
                     filament_diameter_mm: float = 1.75, drive: DriveProfile | None = None,
                     roller: Roller | None = None) -> ViscositySweep:
    """Turn a temperature-sweep table into viscosities (see the module docstring).

    Raises
    ------
    DataError
        The table has no, or more than one, measured quantity, or lacks ``flow_mm3_s``.
    CalibrationError
        A force or slip basis without the hot end or drive it needs, or a slip below the
        drive's offset ``k_p`` (negative force).
    """
    bases = [b for b in ("viscosity_pa_s", "feed_force_n", "slip_pct") if table.has(b)]
    if len(bases) != 1:
        raise DataError("the sweep must have exactly one of viscosity_pa_s, feed_force_n, "
                        "slip_pct", source=table.source, field=",".join(bases) or None,
                        allowed="one measured quantity per file")
    temp = table.get("temp_c")
    if bases[0] == "viscosity_pa_s":
        return ViscositySweep(temp, table.get("viscosity_pa_s"), "viscosity", table.source)
    if not table.has("flow_mm3_s"):
        raise DataError(f"{bases[0]} needs the flow it was measured at", source=table.source,
                        field="flow_mm3_s", allowed="a flow_mm3_s column")
    if hotend is None:
        raise CalibrationError("a feed force or slip sweep needs the hot end geometry",
                               field="hotend", allowed="a hot-end profile")
    flow = table.get("flow_mm3_s")
    notes = [f"hot end {hotend.name}: land {hotend.land_length_mm:g} mm, nozzle "
             f"{hotend.nozzle_diameter_mm:g} mm, cone {hotend.cone_half_angle_deg:g}°; "
             f"filament {filament_diameter_mm:g} mm"]
    if bases[0] == "feed_force_n":
        force = table.get("feed_force_n")
        basis = "feed_force"
    else:
        if drive is None or roller is None:
            raise CalibrationError("a slip sweep needs the drive (roller and pinch force)",
                               field="drive", allowed="a drive profile")
        slip = table.get("slip_pct") / 100.0
        force = feed_force_from_slip_n(slip, flow, drive=drive, roller=roller,
                                       filament_diameter_mm=filament_diameter_mm)
        bad = np.nonzero(~(force > 0.0))[0]
        if bad.size:
            i = int(bad[0])
            raise CalibrationError("slip at or below the drive's offset k_p: no feed force",
                                   source=table.source, line=int(table.lines[i]),
                                   field="slip_pct", value=float(slip[i] * 100.0),
                                   allowed=f"> k_p = {drive.k_p_pct:g} %")
        basis = "slip"
        notes.append(f"drive {drive.name}: {roller.name} at {drive.pinch_force_n:g} N, "
                     f"k_p {drive.k_p_pct:g} %")
    visc = apparent_viscosity_pa_s(force, flow, hotend=hotend,
                                   filament_diameter_mm=filament_diameter_mm)
    return ViscositySweep(temp, visc, basis, table.source, tuple(notes))


@dataclass(frozen=True)
class ViscosityFit:
    """A fitted viscosity law with 1σ uncertainties.

    Attributes
    ----------
    law
        ``"exponential"``, ``"arrhenius"`` or ``"wlf"``.
    params
        Parameters under the material profile's keys (``mu0_pa_s``, ``b_per_c``, …).
    stderr
        1σ standard error of each fitted parameter (fixed ones absent).
    fixed
        Parameters held fixed (``t_ref_c``, a fixed ``c2_k``).
    t_min_c, t_max_c
        Temperature range of the data (the validity range written to the profile).
    n_points
        Number of measurements.
    rms_log10
        RMS residual of ``log10 μ``.
    curve
        The underlying least-squares result (internal parameters).
    sweep
        The data fitted.
    """

    law: str
    params: dict[str, float]
    stderr: dict[str, float]
    fixed: dict[str, float]
    t_min_c: float
    t_max_c: float
    n_points: int
    rms_log10: float
    curve: CurveFit = field(repr=False)
    sweep: ViscositySweep = field(repr=False)

    def viscosity_pa_s(self, temp_c: npt.ArrayLike) -> FloatArray:
        """The fitted law at ``temp_c`` (°C), Pa·s, via :mod:`flowtwin.physics.viscosity`."""
        p = {**self.params, **self.fixed}
        if self.law == "exponential":
            return viscosity_exponential_pa_s(temp_c, p["mu0_pa_s"], p["b_per_c"])
        if self.law == "arrhenius":
            return viscosity_arrhenius_pa_s(temp_c, p["mu_ref_pa_s"], p["t_ref_c"],
                                            p["activation_energy_j_mol"])
        return viscosity_wlf_pa_s(temp_c, p["mu_ref_pa_s"], p["t_ref_c"], p["c1"], p["c2_k"])

    def profile_table(self) -> dict[str, Any]:
        """The material profile's ``[viscosity]`` table, validated by its schema.

        Raises
        ------
        CalibrationError
            The fitted values lie outside what a material profile accepts.
        """
        table: dict[str, Any] = {"law": self.law, **self.params, **self.fixed,
                                 "t_min_c": self.t_min_c, "t_max_c": self.t_max_c}
        models: dict[str, type[BaseModel]] = {
            "exponential": ExponentialViscosity, "arrhenius": ArrheniusViscosity,
            "wlf": WlfViscosity}
        model = models[self.law]
        try:
            model.model_validate(table)
        except ValidationError as exc:
            first = exc.errors()[0]
            raise CalibrationError(f"the fitted {self.law} law is not a valid material "
                                   f"profile: {first['msg']}",
                                   field=".".join(str(x) for x in first["loc"]) or "viscosity",
                                   value=first.get("input")) from None
        return table

    def summary(self) -> dict[str, Any]:
        """Plain JSON-able figures."""
        return {
            "law": self.law, "params": dict(self.params), "stderr": dict(self.stderr),
            "fixed": dict(self.fixed), "t_min_c": self.t_min_c, "t_max_c": self.t_max_c,
            "n_points": self.n_points, "rms_log10": self.rms_log10,
            "basis": self.sweep.basis, "source": self.sweep.source,
            "notes": list(self.sweep.notes),
            "internal": {"names": list(self.curve.names),
                         "values": self.curve.values.tolist(),
                         "covariance": self.curve.covariance.tolist()},
        }


def fit_viscosity_law(sweep: ViscositySweep, *, law: ViscosityLawName = "exponential",
                      t_ref_c: float | None = None,
                      wlf_c2_k: float | None = None) -> ViscosityFit:
    """Fit a viscosity law to a temperature sweep (least squares on ``ln μ``).

    Parameters
    ----------
    sweep
        Temperatures and viscosities (:func:`sweep_from_table`).
    law
        ``"exponential"`` [002], ``"arrhenius"`` or ``"wlf"``.
    t_ref_c
        Reference temperature of the Arrhenius and WLF laws, °C; default: the mean
        temperature of the data rounded to 1 °C (which decorrelates the parameters).
    wlf_c2_k
        Hold WLF's ``C2`` (K) fixed at this value and fit ``μ_ref`` and ``C1`` only.

    Returns
    -------
    ViscosityFit

    Raises
    ------
    CalibrationError
        Too few points or temperatures, viscosity not falling with temperature, a
        parameter the data do not determine, or values no material profile accepts.
    """
    if law not in _LAWS:
        raise CalibrationError("unknown viscosity law", field="law", value=law,
                               allowed=", ".join(_LAWS))
    t = np.asarray(sweep.temp_c, dtype=np.float64)
    mu = np.asarray(sweep.visc_pa_s, dtype=np.float64)
    if t.shape != mu.shape or t.ndim != 1:
        raise DataError("temperatures and viscosities must be 1-D of equal length",
                        source=sweep.source, field="temp_c", value=(t.shape, mu.shape))
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(mu)) and np.all(mu > 0.0)):
        raise DataError("viscosities must be finite and positive", source=sweep.source,
                        field="viscosity_pa_s")
    n_params = 3 if law == "wlf" and wlf_c2_k is None else 2
    distinct = np.unique(t).size
    if distinct < n_params:
        raise CalibrationError(
            f"the {law} law has {n_params} parameters: it needs measurements at as many "
            "distinct temperatures", source=sweep.source, field="temp_c", value=distinct,
            allowed=f">= {n_params} distinct temperatures")
    if t_ref_c is None:
        t_ref_c = float(round(float(np.mean(t))))
    y = np.log(mu)
    what = f"{law} viscosity law"
    fixed: dict[str, float] = {}
    if law == "exponential":
        t_bar = float(np.mean(t))
        slope0 = float(np.polyfit(t - t_bar, y, 1)[0])
        curve = fit_curve(lambda x, a, b: a - b * (x - t_bar), t, y,
                          [float(np.mean(y)), -slope0], names=("ln_mu_mean", "b_per_c"),
                          what=what)
        a, b = curve.values.tolist()
        _require_falling(b, "b_per_c", sweep)
        mu0 = math.exp(a + b * t_bar)
        params = {"mu0_pa_s": mu0, "b_per_c": b}
        stderr = {"mu0_pa_s": mu0 * propagate_std(np.array([1.0, t_bar]), curve.covariance),
                  "b_per_c": float(curve.stderr[1])}
        rms = curve.rms / math.log(10.0)
    elif law == "arrhenius":
        inv_ref = 1.0 / (t_ref_c + KELVIN_OFFSET)
        x = 1.0 / (t + KELVIN_OFFSET) - inv_ref
        slope0 = float(np.polyfit(x, y, 1)[0])
        curve = fit_curve(lambda xx, a, e: a + e * xx, x, y,
                          [float(np.mean(y)) - slope0 * float(np.mean(x)), slope0],
                          names=("ln_mu_ref", "ea_over_r_k"), what=what)
        a, e = curve.values.tolist()
        _require_falling(e, "activation_energy_j_mol", sweep)
        mu_ref = math.exp(a)
        fixed = {"t_ref_c": float(t_ref_c)}
        params = {"mu_ref_pa_s": mu_ref, "activation_energy_j_mol": e * GAS_CONSTANT_J_MOL_K}
        stderr = {"mu_ref_pa_s": mu_ref * float(curve.stderr[0]),
                  "activation_energy_j_mol": float(curve.stderr[1]) * GAS_CONSTANT_J_MOL_K}
        rms = curve.rms / math.log(10.0)
    else:
        curve, params, stderr, fixed = _fit_wlf(t, np.log10(mu), float(t_ref_c), wlf_c2_k,
                                                what, sweep)
        rms = curve.rms
    return ViscosityFit(law, params, stderr, fixed, float(np.min(t)), float(np.max(t)),
                        int(t.size), float(rms), curve, sweep)


def _require_falling(value: float, name: str, sweep: ViscositySweep) -> None:
    if not value > 0.0:
        raise CalibrationError("the viscosity does not fall with temperature (check the "
                               "columns and the temperatures)", source=sweep.source,
                               field=name, value=value, allowed="> 0")


def _fit_wlf(t: FloatArray, y10: FloatArray, t_ref: float, c2_fixed: float | None, what: str,
             sweep: ViscositySweep
             ) -> tuple[CurveFit, dict[str, float], dict[str, float], dict[str, float]]:
    """WLF on ``log10 μ = A − C1·d/(C2 + d)``, ``d = T − T_ref``."""
    d = t - t_ref
    c2_min = -float(np.min(d))          # C2 + d > 0 for every point (no singularity)
    if c2_fixed is not None:
        if not c2_fixed > max(c2_min, 0.0):
            raise CalibrationError("C2 puts the WLF singularity inside the data",
                                   field="wlf_c2_k", value=c2_fixed,
                                   allowed=f"> {max(c2_min, 0.0):g} K")
        g = d / (c2_fixed + d)
        slope0 = float(np.polyfit(g, y10, 1)[0])
        curve = fit_curve(lambda x, a, c1: a - c1 * x / (c2_fixed + x), d, y10,
                          [float(np.mean(y10)) + slope0 * float(np.mean(g)), -slope0],
                          names=("log10_mu_ref", "c1"), what=what)
        a, c1 = curve.values.tolist()
        _require_falling(c1, "c1", sweep)
        return (curve, {"mu_ref_pa_s": 10.0 ** a, "c1": c1},
                {"mu_ref_pa_s": 10.0 ** a * math.log(10.0) * float(curve.stderr[0]),
                 "c1": float(curve.stderr[1])},
                {"t_ref_c": t_ref, "c2_k": c2_fixed})
    # start: for each C2 on a grid the model is linear in (A, C1); keep the best
    lo = max(c2_min, 0.0) + 1e-3
    best: tuple[float, float, float, float] | None = None
    for c2 in np.geomspace(lo + 1e-3, 1e4, 400):
        g = d / (c2 + d)
        coef, res, *_ = np.polyfit(g, y10, 1, full=True)
        ssr = float(res[0]) if res.size else 0.0
        if best is None or ssr < best[0]:
            best = (ssr, float(coef[1]), float(-coef[0]), float(c2))
    assert best is not None
    _, a0, c1_0, c2_0 = best
    curve = fit_curve(lambda x, a, c1, c2: a - c1 * x / (c2 + x), d, y10, [a0, c1_0, c2_0],
                      names=("log10_mu_ref", "c1", "c2_k"), what=what,
                      bounds=([-np.inf, -np.inf, lo], [np.inf, np.inf, 1e5]))
    a, c1, c2 = curve.values.tolist()
    _require_falling(c1, "c1", sweep)
    return (curve, {"mu_ref_pa_s": 10.0 ** a, "c1": c1, "c2_k": c2},
            {"mu_ref_pa_s": 10.0 ** a * math.log(10.0) * float(curve.stderr[0]),
             "c1": float(curve.stderr[1]), "c2_k": float(curve.stderr[2])},
            {"t_ref_c": t_ref})
