"""The twin printer's extruder: one step of the extrusion state equation, and its parameters.

The twin runs in (real, accelerated or simulated) time and meets every multiplier change
as it comes, so it advances the state equation of docs/spec.md §3.4 step by step instead of over a
whole planned feed like :func:`flowtwin.dynamics.integrate`. Over one step the commanded
filament speed ``v`` (the gear surface speed ``ω·r``) is constant, and in every regime the
equation is linear in the state ``x = Δl`` (mm of column compression), so each regime
piece has an exact exponential solution:

* **slip** (``v > 0``, ``x ≥ 0``, not grinding): ``dx/dt = v(1 − k_p) − β·x`` with
  ``β = 1/K + v·s'(v)/k`` — the slip ``s = k_p + s'(v)·F`` of [000 Eq. 6/8] at the feed
  force ``F = x/k`` [001 Eq. 2], the output ``v*_out = x/K`` [001 Eq. 5, 10];
* **grinding** (``v > 0``): the roller eats into the filament [000 §4, 003]: ``v_in = 0``,
  ``dx/dt = −x/K``, until ``F`` falls below ``(1 − release)·F_max``;
* **gap** (``x < 0`` after a retraction): nothing flows; forward feed closes the gap at
  ``v(1 − k_p)`` (no force, so the slip is ``k_p``);
* **retraction** (``v ≤ 0``): the filament follows the gear without slip,
  ``dx/dt = v − max(x, 0)/K``; no backflow [001 Fig. 8].

Regime changes inside a step (the force reaching ``F_max``, its release, ``x`` crossing 0)
are located exactly from the exponential solutions. Every exponential piece is the one lag
step of :mod:`flowtwin.physics.lag` (:func:`~flowtwin.physics.lag.lag_linear`, with the
time constant ``1/β`` in the slip regime; :func:`~flowtwin.physics.lag.lag_step` for the
retraction, which finds the crossing of 0). The same equations, integrated over a
whole G-code, are :func:`flowtwin.dynamics.integrate`; ``tests/control`` checks that the
two agree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from flowtwin.physics.compliance import bowden_compliance_mm_per_n, compliance_mm_per_n
from flowtwin.physics.lag import lag_factor_s, lag_linear, lag_step
from flowtwin.physics.nozzle import hydraulic_resistance_mpa_s_per_mm3
from flowtwin.physics.units import pa_s_to_mpa_s
from flowtwin.profiles.machine import Machine
from flowtwin.simulation.viscosity import viscosity_pa_s

__all__ = ["EQ8_PINCH_RANGE_N", "ExtruderState", "StepFlux", "StepParams", "step_extrusion",
           "step_params"]

#: Eq. 8 of [000] (velocity law) holds at pinch forces of 80–130 N only [000 §4.2].
EQ8_PINCH_RANGE_N = (80.0, 130.0)
#: Largest number of regime pieces in one step (each change needs a piece; more would be a bug).
_MAX_PIECES = 64


@dataclass(frozen=True, slots=True)
class StepParams:
    """Parameters of the state equation at one operating point.

    Attributes
    ----------
    lag_k_s
        Lag factor ``K = k·R_hyd·A²``, s (> 0) [001 Eq. 5, 15].
    compliance_mm_per_n
        Column compliance ``k``, mm/N (> 0) [001 Eq. 2, 002].
    slip_offset
        ``k_p`` of [000 Eq. 6], fraction.
    slip_a_per_n, slip_b_per_n, slip_c_s_per_mm
        Slip gradient ``s'(v) = a + b·exp(−c·v)`` [000 Eq. 8], 1/N, 1/N, s/mm; Eq. 6's
        constant gradient is ``b = 0``.
    max_feed_force_n
        Feed force at which the roller grinds [000 §4], N (``inf``: never).
    grind_release_fraction
        Feeding resumes below ``(1 − fraction)·max_feed_force_n`` (as in
        :class:`flowtwin.dynamics.ExtrusionParams`).
    """

    lag_k_s: float
    compliance_mm_per_n: float
    slip_offset: float = 0.0
    slip_a_per_n: float = 0.0
    slip_b_per_n: float = 0.0
    slip_c_s_per_mm: float = 0.0
    max_feed_force_n: float = math.inf
    grind_release_fraction: float = 0.2

    def __post_init__(self) -> None:
        if not (self.lag_k_s > 0.0 and math.isfinite(self.lag_k_s)):
            raise ValueError(f"lag_k_s must be > 0, got {self.lag_k_s!r}")
        if not (self.compliance_mm_per_n > 0.0 and math.isfinite(self.compliance_mm_per_n)):
            raise ValueError(f"compliance_mm_per_n must be > 0, got {self.compliance_mm_per_n!r}")
        if not self.max_feed_force_n > 0.0:
            raise ValueError(f"max_feed_force_n must be > 0, got {self.max_feed_force_n!r}")
        if not 0.0 <= self.grind_release_fraction < 1.0:
            raise ValueError("grind_release_fraction must be in [0, 1)")

    def slip_gradient_per_n(self, v_mm_s: float) -> float:
        """``s'(v) = a + b·exp(−c·v)`` [000 Eq. 8], 1/N."""
        if self.slip_b_per_n == 0.0:
            return self.slip_a_per_n
        return self.slip_a_per_n + self.slip_b_per_n * math.exp(-self.slip_c_s_per_mm
                                                                * abs(v_mm_s))


@dataclass(frozen=True, slots=True)
class ExtruderState:
    """State of the extruder: column compression (mm) and whether the drive grinds."""

    compression_mm: float = 0.0
    grinding: bool = False


@dataclass(frozen=True, slots=True)
class StepFlux:
    """What one step moved, all in mm of filament (times the filament area gives mm³).

    Attributes
    ----------
    commanded_mm
        ``∫ v dt``: what the gear surface travelled (the G-code's filament, multipliers in).
    fed_mm
        ``∫ v_in dt``: filament that entered the column (after slip and grinding).
    out_mm
        ``∫ max(x, 0)/K dt``: melt out of the nozzle [001 Eq. 5].
    grind_s
        Time spent grinding, s.
    """

    commanded_mm: float
    fed_mm: float
    out_mm: float
    grind_s: float


def step_extrusion(state: ExtruderState, v_mm_s: float, dt_s: float,
                   p: StepParams) -> tuple[ExtruderState, StepFlux]:
    """Advance the extrusion state equation (docs/spec.md §3.4) by ``dt_s`` at constant ``v_mm_s``.

    Parameters
    ----------
    state
        Compression and grinding flag at the start of the step.
    v_mm_s
        Commanded filament speed (gear surface speed), mm/s; negative retracts.
    dt_s
        Step length, s (>= 0).
    p
        Parameters at this operating point.

    Returns
    -------
    (ExtruderState, StepFlux)
        The state at the end of the step and the filament moved during it; the mass
        balance ``fed − out = Δx`` holds to rounding.
    """
    if not (dt_s >= 0.0 and math.isfinite(dt_s) and math.isfinite(v_mm_s)):
        raise ValueError(f"bad step: v={v_mm_s!r} mm/s, dt={dt_s!r} s")
    x, grinding = state.compression_mm, state.grinding
    k_lag, kc = p.lag_k_s, p.compliance_mm_per_n
    x_grind = kc * p.max_feed_force_n
    x_release = (1.0 - p.grind_release_fraction) * x_grind
    fed = out = grind_s = 0.0
    left = dt_s
    v = v_mm_s
    for _ in range(_MAX_PIECES):
        if left <= 0.0:
            break
        if v > 0.0 and grinding:
            # grinding: no feed, the column relaxes through the nozzle until the release
            if x <= x_release:
                grinding = False
                continue
            t_rel = k_lag * math.log(x / x_release)
            tau = min(left, t_rel)
            x_new, ix = lag_linear(x, 0.0, 0.0, tau, k_lag)
            out += ix / k_lag
            grind_s += tau
            x = x_new
            if tau == t_rel:
                x, grinding = x_release, False
        elif v > 0.0 and x < 0.0:
            # gap after a retraction: close it without force (slip = k_p)
            v_in = v * (1.0 - p.slip_offset)
            t_close = -x / v_in if v_in > 0.0 else math.inf
            tau = min(left, t_close)
            fed += v_in * tau
            x = 0.0 if tau == t_close else x + v_in * tau
        elif v > 0.0:
            # slip regime [000 Eq. 6/8] with the lag [001 Eq. 10]
            if x >= x_grind:
                grinding = True
                continue
            # the lag with the time constant 1/β and the input v(1 − k_p); out is x/K
            beta = 1.0 / k_lag + v * p.slip_gradient_per_n(v) / kc
            v_in = v * (1.0 - p.slip_offset)
            x_inf = v_in / beta
            t_grind = math.inf
            if x_inf > x_grind:
                t_grind = math.log((x - x_inf) / (x_grind - x_inf)) / beta
            tau = min(left, t_grind)
            x_new, ix = lag_linear(x, v_in, 0.0, tau, 1.0 / beta)
            out_piece = ix / k_lag
            out += out_piece
            fed += x_new - x + out_piece
            x = x_new
            if tau == t_grind:
                x, grinding = x_grind, True
        else:
            # retraction or standstill: the filament follows the gear (no slip), the lag
            # with no backflow
            tau = left
            step = lag_step(x, v, 0.0, tau, k_lag)
            out += step.out_mm
            fed += step.fed_mm
            x = step.x_mm
            if grinding and x <= x_release:
                grinding = False
        left -= tau
    else:
        raise RuntimeError("extrusion step did not converge (regime changes without end)")
    return ExtruderState(x, grinding), StepFlux(v * dt_s, fed, out, grind_s)


def step_params(machine: Machine, *, temperature_c: float, layer_height_mm: float | None
                ) -> StepParams:
    """State-equation parameters of ``machine`` at a nozzle temperature and layer height.

    The same models as :func:`flowtwin.simulation.parameters.move_parameters`: viscosity
    by the material's law [002] (evaluated at the nearest end of its range outside it),
    hydraulic resistance of cone, capillary and tip back-pressure [002, 001 Eq. 4], lag
    factor ``K = k·R_hyd·A²``, compliance of the column (and Bowden tube), the slip law
    of the drive's roller — Eq. 8 of [000] at pinch forces of 80–130 N, Eq. 6 otherwise —
    and its maximum feed force [000 Figs. 4–8].

    Parameters
    ----------
    machine
        The set-up.
    temperature_c
        Nozzle temperature, °C.
    layer_height_mm
        Layer height, mm; ``None`` for free extrusion (no tip back-pressure).

    Returns
    -------
    StepParams
    """
    hot = machine.hotend
    mat = machine.material
    area = machine.filament.area_mm2
    t_eval = min(max(temperature_c, mat.viscosity.t_min_c), mat.viscosity.t_max_c)
    visc = float(viscosity_pa_s(mat, t_eval))
    r_hyd = float(hydraulic_resistance_mpa_s_per_mm3(
        pa_s_to_mpa_s(visc), capillary_length_mm=hot.land_length_mm,
        nozzle_radius_mm=hot.nozzle_diameter_mm / 2.0,
        bore_radius_mm=hot.bore_diameter_mm / 2.0, cone_half_angle_deg=hot.cone_half_angle_deg,
        layer_height_mm=layer_height_mm, back_pressure_length_mm=hot.back_pressure_length_mm,
        back_pressure_exponent=hot.back_pressure_exponent))
    k_col = float(compliance_mm_per_n(area, hot.l_rt_mm, mat.e_rt_mpa, hot.l_hot_mm,
                                      mat.e_hot_mpa))
    if hot.bowden is not None:
        tube = hot.bowden
        k_col += float(bowden_compliance_mm_per_n(
            tube.length_mm, tube.outer_diameter_mm, tube.inner_diameter_mm, tube.modulus_mpa,
            machine.filament.diameter_mm, mat.e_rt_mpa))
    roller = machine.roller
    fp = machine.drive.pinch_force_n
    if roller.velocity_dependent and EQ8_PINCH_RANGE_N[0] <= fp <= EQ8_PINCH_RANGE_N[1]:
        a, b, c = float(roller.a_per_n), float(roller.b_per_n), float(roller.c_s_per_mm)  # type: ignore[arg-type]
    else:
        a, b, c = roller.k_s_n / fp ** 2 + roller.k_inf_per_n, 0.0, 0.0
    fit = roller.max_feed_force_fit
    return StepParams(
        lag_k_s=float(lag_factor_s(k_col, r_hyd, area)), compliance_mm_per_n=k_col,
        slip_offset=machine.drive.k_p, slip_a_per_n=a, slip_b_per_n=b, slip_c_s_per_mm=c,
        max_feed_force_n=fit.max_feed_force_n(fp) if fit is not None else math.inf)
