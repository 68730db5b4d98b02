"""[002] "Theory of extrusion" (K8400 community article) — claims and figures.

The responses of the extrusion low-pass (step, impulse, step + impulse = "pressure
advance") are computed by :func:`flowtwin.dynamics.integrate` for the lag factor of
Tronvoll's set-up in free extrusion ("extruding with the nozzle lifted from the building
plate" [002]) and compared with the closed forms [002] describes; the time constant comes
from :mod:`flowtwin.physics` (viscosity → Hagen–Poiseuille → ``K = k·R_hyd·A²``).
"""

from __future__ import annotations

import math

import numpy as np
from matplotlib.figure import Figure

from flowtwin.dynamics import DynamicsResult, ExtrusionParams, integrate
from flowtwin.dynamics.feed import PHASE_CRUISE, CommandedFeed
from flowtwin.physics.compliance import compliance_mm_per_n
from flowtwin.physics.defaults import TRONVOLL_MK25
from flowtwin.physics.lag import lag_factor_s
from flowtwin.physics.operating_point import (
    setup_compliance_mm_per_n,
    setup_lag_factor_s,
    setup_resistance_mpa_s_per_mm3,
    setup_viscosity_mpa_s,
)
from flowtwin.physics.units import circle_area_mm2, mpa_s_to_pa_s
from flowtwin.reproduce.claims import Claim, Outcome, RowKind, rounded
from flowtwin.reproduce.context import ReproContext
from flowtwin.reproduce.figures import FigureSpec, PaperSection
from flowtwin.teststand.figures import new_figure

__all__ = ["SECTION"]

PAPER = "theory"
_DYN = "flowtwin.dynamics.integrate (exact lag, no backflow)"
#: Commanded filament speed of the examples, mm/s (about 45 mm/s printing at 0.2 mm).
V_STEP_MM_S = 2.0


def free_lag_s() -> float:
    """Lag factor of Tronvoll's set-up in free extrusion (no bed under the tip), s."""
    return float(setup_lag_factor_s(TRONVOLL_MK25, layer_height_mm=None))


def _feed(dt: list[float], speed: list[float]) -> CommandedFeed:
    d = np.array(dt, dtype=np.float64)
    coef = np.zeros((d.size, 4))
    coef[:, 0] = speed
    seg = d * coef[:, 0]
    t0 = np.concatenate(([0.0], np.cumsum(d)[:-1]))
    n = d.size
    return CommandedFeed(t0_s=t0, dt_s=d, coef=coef,
                         e0_mm=np.concatenate(([0.0], np.cumsum(seg)[:-1])),
                         move=np.arange(n, dtype=np.int64), gap=np.zeros(n, dtype=bool),
                         phase=np.full(n, PHASE_CRUISE, dtype=np.int8), move_t0_s=t0,
                         move_t1_s=t0 + d, move_de_mm=seg)


def _run(feed: CommandedFeed, k_s: float, *, x0: float = 0.0,
         dt_s: float = 0.0002) -> tuple[np.ndarray, np.ndarray, DynamicsResult]:
    params = ExtrusionParams.build(feed.n_moves, lag_k_s=k_s,
                                   compliance_mm_per_n=setup_compliance_mm_per_n(TRONVOLL_MK25),
                                   filament_diameter_mm=TRONVOLL_MK25.filament_diameter_mm)
    res = integrate(feed, params, initial_compression_mm=x0, series_dt_s=dt_s)
    assert res.series is not None
    t = np.asarray(res.series["t_s"], dtype=np.float64)
    return t, np.asarray(res.series["q_out_mm3_s"]) / params.filament_area_mm2, res


def step_response(k_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Output of a feed step of :data:`V_STEP_MM_S` over ``5K`` (times s, speeds mm/s)."""
    t, v, _ = _run(_feed([5.0 * k_s], [V_STEP_MM_S]), k_s)
    return t, v


def impulse_response(k_s: float, length_mm: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Output after ``length_mm`` of filament pushed in at once (times, speeds, total mm)."""
    t, v, res = _run(_feed([5.0 * k_s], [0.0]), k_s, x0=length_mm)
    total = (res.summary.out_mm3) / float(circle_area_mm2(TRONVOLL_MK25.filament_diameter_mm))
    return t, v, total


def advance_response(k_s: float, on_s: float, pulse_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Step + impulse ``K·V`` at the start, step down + negative impulse at ``on_s``.

    The negative impulse is a retraction of ``K·V`` mm within ``pulse_s``.
    """
    t, v, _ = _run(_feed([on_s, pulse_s, 3.0 * k_s],
                         [V_STEP_MM_S, -k_s * V_STEP_MM_S / pulse_s, 0.0]), k_s,
                   x0=k_s * V_STEP_MM_S)
    return t, v


def _step(ctx: ReproContext) -> Outcome:
    k = free_lag_s()
    t, v = step_response(k)
    exact = V_STEP_MM_S * (1.0 - np.exp(-t / k))
    dev = float(np.max(np.abs(v - exact)) / V_STEP_MM_S)
    i = int(np.argmin(np.abs(t - k)))
    return Outcome(round(1.0 - math.exp(-t[i] / k), 8), round(float(v[i]) / V_STEP_MM_S, 8),
                   "largest deviation from 1 - exp(-t/K) over 0-5K <= 1e-9 of the step",
                   dev <= 1e-9, f"K = {k:.4f} s (free extrusion, Tronvoll's set-up); values "
                   f"are output/step at the sample t = {t[i] * 1000:.1f} ms ≈ K; largest "
                   f"deviation {dev:.1e}")


def _impulse(ctx: ReproContext) -> Outcome:
    k = free_lag_s()
    length = k * V_STEP_MM_S
    t, v, total = impulse_response(k, length)
    exact = length / k * np.exp(-t / k)
    dev = float(np.max(np.abs(v - exact)) / (length / k))
    lost = abs(total - length * (1.0 - math.exp(-5.0))) / length
    i = int(np.argmin(np.abs(t - k)))
    return Outcome(round(math.exp(-t[i] / k), 8), round(float(v[i]) * k / length, 8),
                   "deviation from (D/K)·exp(-t/K) <= 1e-9 of the peak, extruded volume exact "
                   "to 1e-9", dev <= 1e-9 and lost <= 1e-9,
                   f"impulse of D = K·V = {length:.4f} mm; values are output·K/D at the sample "
                   f"t = {t[i] * 1000:.1f} ms ≈ K; largest deviation {dev:.1e}; extruded "
                   f"over 5K: {total:.6f} mm of D(1 − e^-5) = "
                   f"{length * (1.0 - math.exp(-5.0)):.6f} mm")


def _rectangle(ctx: ReproContext) -> Outcome:
    k = free_lag_s()
    on, pulse = 0.2, 1e-5
    t, v = advance_response(k, on, pulse)
    inside = (t > 0.0) & (t < on)
    after = t > on + pulse
    dev_in = float(np.max(np.abs(v[inside] - V_STEP_MM_S))) / V_STEP_MM_S
    dev_after = float(np.max(np.abs(v[after]))) / V_STEP_MM_S
    return Outcome("rectangular output", rounded([dev_in, dev_after], 3),
                   "output = V while on (<= 1e-9) and 0 after the negative impulse (<= 1e-9)",
                   dev_in <= 1e-9 and dev_after <= 1e-9,
                   f"step of V = {V_STEP_MM_S} mm/s plus an impulse of K·V; off after {on} s "
                   f"with a retraction of K·V in {pulse:g} s; deviations relative to V")


def _hot_only() -> tuple[float, float, float, float]:
    """``R_hyd``, ``A_fil``, ``l_hot/E_hot`` and flowtwin's K with the hot term only."""
    s = TRONVOLL_MK25
    area = float(circle_area_mm2(s.filament_diameter_mm))
    resistance = float(setup_resistance_mpa_s_per_mm3(s, layer_height_mm=None))
    l_over_e = s.hotend.l_hot_mm / s.material.e_hot_mpa
    k_hot = float(compliance_mm_per_n(area, 0.0, s.material.e_rt_mpa, s.hotend.l_hot_mm,
                                      s.material.e_hot_mpa))
    return resistance, area, l_over_e, float(lag_factor_s(k_hot, resistance, area))


def _time_constant(ctx: ReproContext) -> Outcome:
    resistance, area, l_over_e, k_flowtwin = _hot_only()
    tau_002 = resistance * area * l_over_e  # const·μ·A_fil·l_hot/E_hot
    rel = abs(k_flowtwin - tau_002) / tau_002
    return Outcome(round(tau_002, 6), round(k_flowtwin, 6), "relative difference <= 1e-12",
                   rel <= 1e-12,
                   "[002]: V_ext − V_seal = (const·μ·A_fil·l_hot/E_hot)·dV_seal/dt, const·μ = "
                   "R_hyd (P = R_hyd·Q); flowtwin: K = k·R_hyd·A² with k = l_hot/(E_hot·A) "
                   f"(cold term dropped as [002] does); Tronvoll's set-up, free extrusion, "
                   f"R_hyd = {resistance:.4f} MPa·s/mm³")


def _bracket(ctx: ReproContext) -> Outcome:
    resistance, area, l_over_e, k_flowtwin = _hot_only()
    a_noz = float(circle_area_mm2(TRONVOLL_MK25.hotend.nozzle_diameter_mm))
    printed = resistance * a_noz * l_over_e  # the bracket as printed: const·μ·A_noz·l_hot/E_hot
    ratio = printed / k_flowtwin
    ok = abs(ratio - a_noz / area) <= 1e-12 * (a_noz / area) and ratio < 0.5
    return Outcome(round(printed, 6), round(k_flowtwin, 6),
                   "a data check: passes when the printed bracket is the time constant times "
                   "A_noz/A_fil exactly", ok,
                   f"ratio {ratio:.4f} = A_noz/A_fil. Differentiating [002]'s balance gives "
                   "V_ext − (A_noz/A_fil)·V_noz = (const·μ·A_noz·l_hot/E_hot)·dV_noz/dt (the "
                   "text writes A_fil/A_noz: the continuity V_seal·A_fil = V_noz·A_noz is "
                   "inverted), whose time constant is the bracket divided by A_noz/A_fil")


CLAIMS: tuple[Claim, ...] = (
    Claim(PAPER, "step-response", "A feed step gives an exponential rise 1 − exp(−t/τ) "
          "(value at t = τ)", "[002 step response]", _step, figure="responses", engine=_DYN),
    Claim(PAPER, "impulse-response", "A feed impulse gives an exponentially decaying flow "
          "(D/τ)·exp(−t/τ) (value ·τ/D at t = τ)", "[002 Dirac response]", _impulse,
          figure="responses", engine=_DYN),
    Claim(PAPER, "pressure-advance-rectangle", "Step plus a scaled impulse gives a "
          "rectangular extrusion rate ('pressure advance')", "[002 pressure advance]",
          _rectangle, figure="responses", engine=_DYN),
    Claim(PAPER, "time-constant-formula", "The time constant of the low pass is "
          "const·μ·A·l_hot/E_hot", "[002 low-pass derivation]", _time_constant, unit="s",
          engine="flowtwin.physics.lag.lag_factor_s"),
    Claim(PAPER, "time-constant-bracket", "[002]'s printed bracket const·μ·A_noz·l_hot/E_hot "
          "is not the time constant (continuity inverted)", "[002 low-pass derivation]",
          _bracket, unit="s", kind=RowKind.DATA_CHECK, engine="flowtwin.physics.lag"),
)


def _fig_responses(ctx: ReproContext) -> Figure:
    k = free_lag_s()
    fig, axes = new_figure(12.0, 3.6, cols=3)
    t, v = step_response(k)
    axes[0].plot(t, [V_STEP_MM_S if x > 0 else 0.0 for x in t], color="black", lw=1,
                 label="input (step)")
    axes[0].plot(t, v, label="output (flowtwin.dynamics)")
    axes[0].plot(t, V_STEP_MM_S * (1 - np.exp(-t / k)), "--", label="1 − exp(−t/τ)")
    axes[0].set_title("step response")
    length = k * V_STEP_MM_S
    t, v, _ = impulse_response(k, length)
    axes[1].plot(t, v, label="output")
    axes[1].plot(t, length / k * np.exp(-t / k), "--", label="(D/τ)·exp(−t/τ)")
    axes[1].set_title(f"impulse of D = {length:.3f} mm")
    t, v = advance_response(k, 0.2, 1e-5)
    axes[2].plot(t, np.where((t > 0) & (t < 0.2), V_STEP_MM_S, 0.0), color="black", lw=1,
                 label="step part of the input")
    axes[2].plot(t, v, label="output: step + impulse")
    axes[2].set_title("pressure advance: rectangular output")
    for ax in axes:
        ax.set_xlabel("time (s)")
        ax.legend(fontsize=7)
    axes[0].set_ylabel("filament speed (mm/s)")
    fig.suptitle(f"τ = K = {k * 1000:.1f} ms (Tronvoll's set-up, free extrusion)", fontsize=9)
    return fig


FIGURES: tuple[FigureSpec, ...] = (
    FigureSpec("responses", "[002] step, impulse and step + impulse ('pressure advance') "
                            "responses of the extrusion low pass, integrated by "
                            "flowtwin.dynamics, against the closed forms.", _fig_responses),
)


def notes(ctx: ReproContext) -> list[str]:
    """Findings beyond the rows: the cold-column term and the temperature sensitivity."""
    s = TRONVOLL_MK25
    area = float(circle_area_mm2(s.filament_diameter_mm))
    cold = s.l_rt_mm / (s.material.e_rt_mpa * area)
    hot = s.hotend.l_hot_mm / (s.material.e_hot_mpa * area)
    mu = [mpa_s_to_pa_s(setup_viscosity_mpa_s(s, t)) for t in (205.0, 215.0)]
    return [
        f"[002] calls the room-temperature term of the column compliance negligible. With "
        f"flowtwin's default (assumed) l_RT = {s.l_rt_mm:g} mm at E_RT = "
        f"{s.material.e_rt_mpa:g} MPa and l_hot = {s.hotend.l_hot_mm:g} mm at E_hot = "
        f"{s.material.e_hot_mpa:g} MPa it is {100 * cold / (cold + hot):.0f} % of the "
        "compliance; the time-constant row uses the hot term only, as [002] does, and the "
        "defaults keep both (docs/spec.md §3.2).",
        f"Temperature sensitivity [002 μ(T) = μ0·exp(−bT)]: with the defaults, μ(205 °C)/"
        f"μ(215 °C) = {float(mu[0] / mu[1]):.2f}, and the time constant scales with μ.",
    ]


SECTION = PaperSection(PAPER, "'Theory of extrusion' (K8400 community article)", "002",
                       CLAIMS, FIGURES, notes)
