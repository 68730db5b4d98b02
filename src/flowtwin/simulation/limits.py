"""Steady extrusion with the melt model and the maximum volumetric flow of a machine.

At a steady commanded flow ``Q`` the filament fed into the melt zone is ``Q·(1 − s)``;
the melt reaches the nozzle at ``T_b`` (:mod:`flowtwin.physics.melt`, plug-flow conduction
over the effective heated length), its viscosity follows the material's law [002], the
hot end's resistance (cone + capillary [002, 001 Eq. 4] + tip back-pressure) gives the
feed force ``F = R_hyd(T_b)·Q·(1 − s)·A`` and the drive's slip law [000 Eqs. 6, 8] the
slip ``s = (k_p + s'F_0)/(1 + s'F_0)`` with ``F_0 = R_hyd·Q·A`` (solved together by fixed
point: ``T_b`` depends on the delivered flow). Without a melt zone in the hot-end profile
the melt is at the set temperature (the seeds' model).

The *maximum volumetric flow* is the first flow where the delivered/commanded ratio
``1 − s`` falls below 95 % (``slip``) or the force reaches the roller's maximum feed force
[000 Figs. 4–8] (``grinding``), whichever comes first; if the melt at the nozzle falls
below the viscosity law's validity range before either, the model cannot say more and
that flow is reported as the limit (``melt``). Free extrusion (no bed) is the default, as
hot-end makers and testers measure; ``layer_height_mm`` adds the tip back-pressure.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.errors import ProfileError
from flowtwin.physics import defaults
from flowtwin.physics.drive import slip_gradient_velocity
from flowtwin.physics.melt import theta_scalar
from flowtwin.physics.melt_capacity import melt_capacity_mm3_s
from flowtwin.physics.nozzle import hydraulic_resistance_mpa_s_per_mm3
from flowtwin.physics.units import pa_s_to_mpa_s
from flowtwin.physics.viscosity import GAS_CONSTANT_J_MOL_K, KELVIN_OFFSET
from flowtwin.profiles.hotend import HotendProfile
from flowtwin.profiles.machine import Machine
from flowtwin.profiles.material import (
    ArrheniusViscosity,
    ExponentialViscosity,
    MaterialProfile,
    WlfViscosity,
)
from flowtwin.scalar_search import bracketed_root

__all__ = ["DELIVERED_MIN", "FlowFlags", "FlowLimit", "SteadyExtrusion", "flow_flags",
           "flow_limit", "flow_limit_table", "melt_model", "steady_extrusion"]

#: Delivered/commanded ratio below which the flow counts as beyond the machine's limit.
DELIVERED_MIN = 0.95
#: Highest flow searched, mm³/s.
Q_SEARCH_MAX = 200.0
#: Eq. 8 of [000] holds for pinch forces of 80–130 N only [000 §4.2].
_EQ8_PINCH_RANGE_N = (80.0, 130.0)


@dataclass(frozen=True, slots=True)
class MeltModel:
    """What the melt model of one machine needs (``None`` from :func:`melt_model`: off).

    Attributes
    ----------
    diffusivity_mm2_s
        Thermal diffusivity of the material, mm²/s.
    heated_length_mm
        Effective heated length (profile length × factor), mm.
    inlet_c
        Filament temperature entering the melt zone, °C.
    """

    diffusivity_mm2_s: float
    heated_length_mm: float
    inlet_c: float


def melt_model(machine: Machine) -> MeltModel | None:
    """The machine's melt model, or ``None`` when the hot end has no melt zone or the
    material no thermal data (then the melt is at the set temperature, as in the seeds)."""
    alpha = machine.material.diffusivity_mm2_s
    length = machine.hotend.effective_heated_length_mm(defaults.MELT_LENGTH_FACTOR)
    if alpha is None or length is None:
        return None
    return MeltModel(alpha, length, machine.hotend.melt_inlet_temperature_c)


@dataclass(frozen=True, slots=True)
class SteadyExtrusion:
    """The machine extruding steadily (module docstring); forces in N, flows in mm³/s.

    Attributes
    ----------
    flow_mm3_s
        Commanded flow ``Q``.
    temperature_c
        Set (wall) temperature, °C.
    melt_temperature_c
        Bulk melt temperature at the nozzle, °C (the set temperature without melt model).
    viscosity_pa_s
        Viscosity used, Pa·s (the law at ``melt_temperature_c`` clipped to its range).
    feed_force_n
        Feed force at the delivered flow.
    slip
        Steady slip, fraction.
    delivered_ratio
        ``1 − slip``.
    max_feed_force_n
        The roller's maximum feed force at the drive's pinch force.
    melt_in_range
        ``False`` when the melt is colder than the viscosity law's range (force is then a
        lower bound).
    """

    flow_mm3_s: float
    temperature_c: float
    melt_temperature_c: float
    viscosity_pa_s: float
    feed_force_n: float
    slip: float
    delivered_ratio: float
    max_feed_force_n: float
    melt_in_range: bool

    @property
    def force_margin_n(self) -> float:
        """``max_feed_force_n − feed_force_n``, N."""
        return self.max_feed_force_n - self.feed_force_n


def _scalar_law(material: MaterialProfile) -> Callable[[float], float]:
    """The material's viscosity law as a scalar function, Pa·s (the formulas of
    :mod:`flowtwin.physics.viscosity`; the tests compare them)."""
    law = material.viscosity
    if isinstance(law, ExponentialViscosity):
        return lambda t: law.mu0_pa_s * math.exp(-law.b_per_c * t)
    if isinstance(law, ArrheniusViscosity):
        ea_r = law.activation_energy_j_mol / GAS_CONSTANT_J_MOL_K
        t_ref = law.t_ref_c + KELVIN_OFFSET
        return lambda t: law.mu_ref_pa_s * math.exp(ea_r * (1.0 / (t + KELVIN_OFFSET)
                                                            - 1.0 / t_ref))
    assert isinstance(law, WlfViscosity)
    return lambda t: law.mu_ref_pa_s * 10.0 ** (-law.c1 * (t - law.t_ref_c)
                                               / (law.c2_k + t - law.t_ref_c))


def _slip_gradient(machine: Machine, feed_mm_s: float) -> float:
    roller = machine.roller
    fp = machine.drive.pinch_force_n
    if roller.velocity_dependent and _EQ8_PINCH_RANGE_N[0] <= fp <= _EQ8_PINCH_RANGE_N[1]:
        return float(slip_gradient_velocity(
            feed_mm_s, float(roller.a_per_n),  # type: ignore[arg-type]
            float(roller.b_per_n), float(roller.c_s_per_mm)))  # type: ignore[arg-type]
    return roller.k_s_n / fp ** 2 + roller.k_inf_per_n


def _max_force(machine: Machine) -> float:
    fit = machine.roller.max_feed_force_fit
    return fit.max_feed_force_n(machine.drive.pinch_force_n) if fit is not None else math.inf


@functools.lru_cache(maxsize=256)
def _unit_resistance(hot: HotendProfile, layer_height_mm: float | None) -> float:
    """The hot end's hydraulic resistance at 1 Pa·s, MPa·s/mm³: every resistance term is
    linear in the viscosity, ``R_hyd = μ·R(1 Pa·s)``; one value per hot end and layer height
    (the profile is frozen and hashable), asked for by every steady state of a flow limit."""
    return float(hydraulic_resistance_mpa_s_per_mm3(
        pa_s_to_mpa_s(1.0), capillary_length_mm=hot.land_length_mm,
        nozzle_radius_mm=hot.nozzle_radius_mm, bore_radius_mm=hot.bore_diameter_mm / 2.0,
        cone_half_angle_deg=hot.cone_half_angle_deg, layer_height_mm=layer_height_mm,
        back_pressure_length_mm=hot.back_pressure_length_mm,
        back_pressure_exponent=hot.back_pressure_exponent))


def steady_extrusion(machine: Machine, flow_mm3_s: float, *, temperature_c: float | None = None,
                     layer_height_mm: float | None = None, melt: bool = True
                     ) -> SteadyExtrusion:
    """The machine extruding steadily at the commanded flow ``flow_mm3_s`` (module docstring).

    Parameters
    ----------
    machine
        The set-up.
    flow_mm3_s
        Commanded volume flow, mm³/s (≥ 0).
    temperature_c
        Set temperature, °C (default: the set-up's).
    layer_height_mm
        ``None`` for free extrusion; else the tip back-pressure at that layer height.
    melt
        ``False`` switches the melt model off (melt at the set temperature).

    Returns
    -------
    SteadyExtrusion
    """
    if not (flow_mm3_s >= 0.0 and math.isfinite(flow_mm3_s)):
        raise ProfileError("the flow must be finite and >= 0", field="flow_mm3_s",
                           value=flow_mm3_s, allowed=">= 0 mm³/s")
    mat = machine.material
    area = machine.filament.area_mm2
    t_set = machine.temperature_c if temperature_c is None else float(temperature_c)
    model = melt_model(machine) if melt else None
    lo, hi = mat.viscosity.t_min_c, mat.viscosity.t_max_c
    grad = _slip_gradient(machine, flow_mm3_s / area)

    r_unit = _unit_resistance(machine.hotend, layer_height_mm)

    # scalar forms of steady_melt_temperature_c and the viscosity law (same formulas,
    # without the array checks: this runs thousands of times per limit)
    law = _scalar_law(mat)

    def at(q_fed: float) -> tuple[float, float, float]:
        if model is None or q_fed <= 0.0:
            t_melt = t_set
        else:
            fo = math.pi * model.diffusivity_mm2_s * model.heated_length_mm / q_fed
            t_melt = t_set - (t_set - model.inlet_c) * theta_scalar(fo)
        mu = law(min(max(t_melt, lo), hi))
        return t_melt, mu, mu * r_unit

    kp = machine.drive.k_p

    def slip_at(s: float) -> float:
        """[000 Eq. 6] with F ∝ delivered flow (steady_state_slip), the melt temperature
        (hence viscosity) set by the filament fed at slip ``s``."""
        force0 = at(flow_mm3_s * (1.0 - s))[2] * flow_mm3_s * area
        return (kp + grad * force0) / (1.0 + grad * force0)

    slip = slip_at(0.0)
    if model is not None and slip > 0.0:
        # the slip is the fixed point s = slip_at(s): slip_at falls as s rises (less fed,
        # hotter melt, lower force), so s - slip_at(s) has one root in [0, 1)
        slip = bracketed_root(lambda s: slip_at(s) - s, 0.0, 1.0, xtol=1e-13, rtol=0.0)
    t_melt, mu, r_hyd = at(flow_mm3_s * (1.0 - slip))
    force = r_hyd * flow_mm3_s * (1.0 - slip) * area
    return SteadyExtrusion(flow_mm3_s=float(flow_mm3_s), temperature_c=t_set,
                           melt_temperature_c=t_melt, viscosity_pa_s=mu, feed_force_n=force,
                           slip=slip, delivered_ratio=1.0 - slip,
                           max_feed_force_n=_max_force(machine),
                           melt_in_range=bool(t_melt >= lo))


@dataclass(frozen=True, slots=True)
class FlowLimit:
    """The maximum volumetric flow of a machine at one temperature (module docstring).

    Attributes
    ----------
    max_volumetric_flow_mm3_s
        The limit, mm³/s (``Q_SEARCH_MAX`` with reason ``none`` if nothing binds below it).
    reason
        ``"slip"``, ``"grinding"``, ``"melt"`` or ``"none"``.
    temperature_c
        Set temperature, °C.
    at_limit
        The steady extrusion at the limit.
    melt_capacity_mm3_s
        The hot end's melt capacity (:mod:`flowtwin.physics.melt_capacity`), mm³/s;
        ``None`` without melt model.
    melt_model
        Whether the melt model was on.
    """

    max_volumetric_flow_mm3_s: float
    reason: str
    temperature_c: float
    at_limit: SteadyExtrusion
    melt_capacity_mm3_s: float | None
    melt_model: bool

    def as_dict(self) -> dict[str, object]:
        """JSON-ready dict (the key ``max_volumetric_flow_mm3_s`` first)."""
        a = self.at_limit
        cap = self.melt_capacity_mm3_s
        return {"max_volumetric_flow_mm3_s": self.max_volumetric_flow_mm3_s,
                "reason": self.reason, "temperature_c": self.temperature_c,
                "melt_temperature_c": a.melt_temperature_c, "feed_force_n": a.feed_force_n,
                "slip": a.slip, "delivered_ratio": a.delivered_ratio,
                "max_feed_force_n": a.max_feed_force_n if math.isfinite(a.max_feed_force_n)
                else None,
                "melt_capacity_mm3_s": cap if cap is not None and math.isfinite(cap) else None,
                "melt_model": self.melt_model}


def _first_crossing(values: list[float], grid: npt.NDArray[np.float64],
                    fn: Callable[[float], float]) -> float | None:
    """Smallest ``q`` with ``fn(q) ≤ 0`` (``fn`` decreasing in ``q``) from its values on
    ``grid``, refined by :func:`~flowtwin.scalar_search.bracketed_root`; ``None`` if it stays
    positive."""
    for i, v in enumerate(values):
        if v <= 0.0:
            if i == 0:
                return float(grid[0])
            return bracketed_root(fn, float(grid[i - 1]), float(grid[i]),
                                  xtol=1e-9, rtol=1e-10)
    return None


def flow_limit(machine: Machine, *, temperature_c: float | None = None,
               layer_height_mm: float | None = None, melt: bool = True,
               delivered_min: float = DELIVERED_MIN) -> FlowLimit:
    """The machine's maximum volumetric flow at one set temperature (module docstring).

    Parameters
    ----------
    machine
        The set-up.
    temperature_c
        Set temperature, °C (default: the set-up's).
    layer_height_mm
        ``None`` for free extrusion (default).
    melt
        ``False``: without the melt model (the seeds' isothermal melt).
    delivered_min
        Delivered/commanded ratio that bounds the flow (default 0.95).

    Returns
    -------
    FlowLimit
    """
    from flowtwin.simulation.viscosity import viscosity_pa_s

    t_set = machine.temperature_c if temperature_c is None else float(temperature_c)

    def steady(q: float) -> SteadyExtrusion:
        return steady_extrusion(machine, q, temperature_c=t_set,
                                layer_height_mm=layer_height_mm, melt=melt)

    lo = machine.material.viscosity.t_min_c
    grid = np.geomspace(0.05, Q_SEARCH_MAX, 64)
    states = [steady(float(q)) for q in grid]
    candidates: list[tuple[float, str]] = []
    for reason, fn in (("slip", lambda st: st.delivered_ratio - delivered_min),
                       ("grinding", lambda st: st.force_margin_n),
                       ("melt", lambda st: st.melt_temperature_c - lo)):
        q = _first_crossing([fn(st) for st in states], grid,
                            lambda x, f=fn: f(steady(x)))  # type: ignore[misc]
        if q is not None:
            candidates.append((q, reason))
    q_lim, reason = min(candidates) if candidates else (Q_SEARCH_MAX, "none")
    model = melt_model(machine) if melt else None
    cap = None
    if model is not None and t_set > model.inlet_c:
        cap = melt_capacity_mm3_s(lambda t: float(viscosity_pa_s(machine.material, t)),
                                  set_c=t_set, inlet_c=model.inlet_c,
                                  diffusivity_mm2_s=model.diffusivity_mm2_s,
                                  heated_length_mm=model.heated_length_mm)
    return FlowLimit(max_volumetric_flow_mm3_s=q_lim, reason=reason, temperature_c=t_set,
                     at_limit=steady(q_lim), melt_capacity_mm3_s=cap,
                     melt_model=model is not None)


@functools.lru_cache(maxsize=1024)
def _limit_mm3_s(machine: Machine, temperature_c: float, layer_height_mm: float | None
                 ) -> float:
    """:func:`flow_limit`'s flow at one temperature and layer height, remembered: a pure
    function of its arguments (``Machine`` is frozen and hashable), asked again for every
    section of a streamed print."""
    return flow_limit(machine, temperature_c=temperature_c,
                      layer_height_mm=layer_height_mm).max_volumetric_flow_mm3_s


def flow_limit_table(machine: Machine, temperatures_c: Sequence[float], *,
                     layer_height_mm: float | None = None, melt: bool = True
                     ) -> list[FlowLimit]:
    """:func:`flow_limit` at each temperature (the table of ``flowtwin limits``)."""
    return [flow_limit(machine, temperature_c=t, layer_height_mm=layer_height_mm, melt=melt)
            for t in temperatures_c]


@dataclass(frozen=True, slots=True)
class FlowFlags:
    """Moves that ask for more than the machine's maximum volumetric flow.

    Attributes
    ----------
    limit_mm3_s
        The limit at each move's nozzle temperature (rounded to 1 °C) and layer height
        (rounded to 0.01 mm; the tip back-pressure of a bead on the layer below), mm³/s,
        ``(n,)``; NaN where not evaluated (moves that do not extrude).
    over
        Extruding moves whose mean commanded flow exceeds it, ``(n,)`` bool.
    """

    limit_mm3_s: npt.NDArray[np.float64]
    over: npt.NDArray[np.bool_]

    @property
    def count(self) -> int:
        """Number of flagged moves."""
        return int(np.count_nonzero(self.over))


def flow_flags(machine: Machine, flow_mm3_s: npt.NDArray[np.float64],
               nozzle_c: npt.NDArray[np.float64], extruding: npt.NDArray[np.bool_],
               layer_height_mm: npt.NDArray[np.float64] | None = None) -> FlowFlags:
    """Flag the moves above the machine's maximum volumetric flow (the API ``simulate`` and
    the G-code post-processor use).

    Parameters
    ----------
    machine
        The set-up.
    flow_mm3_s
        Mean commanded flow of each move, mm³/s, shape ``(n,)``.
    nozzle_c
        Nozzle (set) temperature during each move, °C, shape ``(n,)``.
    extruding
        Which moves extrude (only they are flagged), shape ``(n,)``.
    layer_height_mm
        Layer height of each move (tip back-pressure), mm, shape ``(n,)``; ``None``:
        free extrusion.

    Returns
    -------
    FlowFlags
    """
    temps = np.round(np.asarray(nozzle_c, dtype=np.float64))
    heights = (np.full(temps.shape, np.nan) if layer_height_mm is None
               else np.round(np.asarray(layer_height_mm, dtype=np.float64), 2))
    limit = np.full(temps.shape, np.nan)
    ok = (np.isfinite(temps) & (temps > machine.hotend.melt_inlet_temperature_c)
          & np.asarray(extruding, dtype=bool))
    if np.any(ok):
        # one limit per (temperature, layer height): few distinct pairs in a print, in
        # long runs of rows (the distinct keys are found among the runs' first rows)
        h_key = np.nan_to_num(heights, nan=-1.0)
        rows = np.flatnonzero(ok)
        key = temps[rows] * 1000.0 + h_key[rows]
        run = np.flatnonzero(np.concatenate(([True], key[1:] != key[:-1])))
        _, first, inverse = np.unique(key[run], return_index=True, return_inverse=True)
        head = rows[run[first]]  # the first row of each distinct key
        values = np.array([_limit_mm3_s(machine, t, None if h < 0.0 else h) for t, h in
                           zip(temps[head].tolist(), h_key[head].tolist(), strict=True)])
        limit[rows] = np.repeat(values[inverse], np.diff(np.append(run, rows.size)))
    over = ok & (np.asarray(flow_mm3_s) > np.where(np.isnan(limit), np.inf, limit))
    return FlowFlags(limit_mm3_s=limit, over=over)
