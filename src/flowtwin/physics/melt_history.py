"""Melt temperature at the nozzle through a sequence of moves: the plug's residence history.

The steady model of :mod:`flowtwin.physics.melt` follows a slice of filament that enters
the melt zone (volume ``V = πR²L``) at ``T_in`` and leaves it after its residence time
``t_res`` with the bulk temperature ``T_w − (T_w − T_in)·θ_b(α·t_res/R²)`` (Carslaw &
Jaeger 1959 §7.4). With plug flow and radial conduction only, that holds for *any* flow
history, not only a steady one: each slice heats for exactly the time it spends in the
zone. The slice leaving at time ``t`` entered when the cumulative fresh volume was
``𝒱(t) − V``, so

    t_res(t) = t − 𝒱⁻¹(𝒱(t) − V),      T(t) = T_w − (T_w − T_in)·θ_b(α·t_res(t)/R²).

At steady flow ``t_res = V/Q`` and this is the steady model exactly; at rest the slice in
the zone keeps heating (``t_res`` grows, ``T → T_w``); after a flow step the exit
temperature moves over one residence time as the slices with the new history arrive. A
burst of a few milliseconds (a pressure-advance piece) changes ``t_res`` only by its share
of ``V``: the melt zone averages the feed over its volume, not over a move.

``𝒱`` counts *fresh* filament only (:func:`flowtwin.simulation.parameters`): a retraction
and the unretraction after it move the same, already heated filament.

The wall temperature is the hot end's set point during the move the slice leaves in (the
heater block's own lag is :mod:`flowtwin.dynamics.thermal`); a slice that entered before
the first move (the initial fill) has been heating since ``MeltState.fill_time_s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.physics._checks import require_positive
from flowtwin.physics._melt_history_kernel import (
    breakpoints,
    mean_temperatures,
    mean_temperatures_parallel,
)
from flowtwin.physics.melt import bulk_temperature_fraction

__all__ = ["PARALLEL_MOVES", "MeltState", "fill_time_for_temperature_s",
           "melt_temperature_history"]

#: Moves from which the mean temperatures are computed in spans on numba's threads (the
#: same numbers): below it, loading the parallel runtime costs more than it saves.
PARALLEL_MOVES = 200_000

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class MeltState:
    """What the melt zone remembers at the end of a stretch of moves.

    Attributes
    ----------
    times_s
        Increasing times (absolute, s) at which the cumulative fresh volume reached
        ``volumes_mm3``, shape ``(p,)``: the recent breakpoints of ``𝒱(t)`` covering at
        least the zone volume.
    volumes_mm3
        Cumulative fresh volume at those times, mm³, shape ``(p,)``, increasing.
    fill_time_s
        When the filament that was in the zone before ``volumes_mm3[0]`` entered, s
        (``-inf``: fully heated).
    end_c
        Melt temperature at the end of the stretch, °C (for reports).
    retracted_mm
        ``(tool, mm)``: how far each tool's filament stands below the furthest point it
        was fed to (what an unretraction pushes back without feeding fresh filament).
    """

    times_s: FloatArray
    volumes_mm3: FloatArray
    fill_time_s: float
    end_c: float
    retracted_mm: tuple[tuple[int, float], ...] = ()


def fill_time_for_temperature_s(melt_c: float, *, wall_c: float, inlet_c: float,
                                diffusivity_mm2_s: float, filament_radius_mm: float,
                                at_s: float) -> float:
    """The entry time of a fill that is at ``melt_c`` at time ``at_s`` (inverse of θ_b).

    Returns ``-inf`` when ``melt_c ≥ wall_c`` (fully heated).
    """
    if melt_c >= wall_c or wall_c <= inlet_c:
        return -math.inf
    target = (wall_c - melt_c) / (wall_c - inlet_c)
    if target >= 1.0:
        return at_s
    lo, hi = 0.0, 1.0
    while float(bulk_temperature_fraction(hi)) > target:
        hi *= 2.0
    for _ in range(100):  # bisection on the monotone θ_b(Fo)
        mid = 0.5 * (lo + hi)
        if float(bulk_temperature_fraction(mid)) > target:
            lo = mid
        else:
            hi = mid
    fourier = 0.5 * (lo + hi)
    return at_s - fourier * filament_radius_mm ** 2 / diffusivity_mm2_s


def melt_temperature_history(q_mm3_s: FloatArray, start_s: FloatArray, duration_s: FloatArray,
                             wall_c: FloatArray, *, inlet_c: float, diffusivity_mm2_s: float,
                             heated_length_mm: float, filament_radius_mm: float,
                             state: MeltState | None = None, end_s: float | None = None,
                             retracted_mm: tuple[tuple[int, float], ...] = ()
                             ) -> tuple[FloatArray, MeltState]:
    """Time-mean melt temperature of every move from the plug's residence (module docstring).

    Parameters
    ----------
    q_mm3_s
        Mean flow of fresh filament into the melt zone during each move, mm³/s, shape
        ``(n,)`` (``≤ 0``: at rest).
    start_s, duration_s
        Start (absolute) and duration of each move, s, shape ``(n,)``; moves in time order.
    wall_c
        Hot-end set temperature during each move, °C, shape ``(n,)``.
    inlet_c
        Filament temperature entering the melt zone, °C.
    diffusivity_mm2_s, heated_length_mm, filament_radius_mm
        ``α`` (mm²/s), effective heated length ``L`` (mm) and ``R`` (mm).
    state
        The zone's memory from the moves before (default: fully heated, empty history).
    end_s
        Time at which the returned state's ``end_c`` is taken (default: the last move's end).
    retracted_mm
        Stored in the returned state (see :class:`MeltState`).

    Returns
    -------
    (mean, state)
        Time-mean melt temperature of every move, °C, shape ``(n,)`` (Simpson's rule on
        the move's start, middle and end), and the memory at the end.
    """
    a = float(require_positive("diffusivity_mm2_s", diffusivity_mm2_s))
    length = float(require_positive("heated_length_mm", heated_length_mm))
    r = float(require_positive("filament_radius_mm", filament_radius_mm))
    zone = math.pi * r * r * length
    q = np.maximum(np.asarray(q_mm3_s, dtype=np.float64), 0.0)
    t0 = np.asarray(start_s, dtype=np.float64)
    dur = np.maximum(np.asarray(duration_s, dtype=np.float64), 0.0)
    vol = q * dur
    prior_t = state.times_s if state is not None else np.zeros(0)
    prior_v = state.volumes_mm3 if state is not None else np.zeros(0)
    fill = state.fill_time_s if state is not None else -math.inf
    base = float(prior_v[-1]) if prior_v.size else 0.0
    v_start = base + np.concatenate(([0.0], np.cumsum(vol)[:-1])) if vol.size else vol
    v_end = v_start + vol
    # breakpoints of 𝒱(t): the prior ones, then every feeding move's start and end
    bt, bv = breakpoints(np.asarray(prior_t, dtype=np.float64),
                         np.asarray(prior_v, dtype=np.float64), t0, dur, v_start, v_end, vol)
    wall = np.asarray(wall_c, dtype=np.float64)
    mean = np.empty(t0.shape[0])
    if t0.shape[0] >= PARALLEL_MOVES:
        import numba

        mean_temperatures_parallel(t0, dur, v_start, v_end, wall, bt, bv, zone, fill,
                                   float(inlet_c), a, r, mean, 2 * numba.get_num_threads())
    else:
        mean_temperatures(t0, dur, v_start, v_end, wall, bt, bv, zone, fill, float(inlet_c), a,
                          r, mean)

    def entry_time(v_out: FloatArray) -> FloatArray:
        """Entry time of the slice at cumulative volume ``v_out − V`` (fill: ``fill``)."""
        v_in = v_out - zone
        out = np.full(v_in.shape, fill)
        if bv.size:
            k = np.searchsorted(bv, v_in, side="left")
            inside = (v_in >= bv[0]) & (k < bv.size)
            kk = np.clip(k, 1, max(bv.size - 1, 1))
            v_a, v_b = bv[kk - 1], bv[kk]
            t_a, t_b = bt[kk - 1], bt[kk]
            span = np.where(v_b > v_a, v_b - v_a, 1.0)
            frac = np.clip((v_in - v_a) / span, 0.0, 1.0)
            t_in = np.where(v_b > v_a, t_a + frac * (t_b - t_a), t_b)
            out = np.where(inside & (k > 0), t_in, np.where(v_in == bv[0], bt[0], out))
        return out

    def temperature(t: FloatArray, v: FloatArray, wall: FloatArray) -> FloatArray:
        residence = t - entry_time(v)
        fo = np.where(np.isfinite(residence), np.maximum(residence, 0.0) * a / (r * r),
                      np.inf)
        return wall - (wall - inlet_c) * bulk_temperature_fraction(fo)

    # keep the breakpoints that cover the last zone volume (and one before it)
    total = float(v_end[-1]) if v_end.size else base
    keep = np.searchsorted(bv, total - zone, side="right") - 1 if bv.size else 0
    keep = max(int(keep), 0)  # later slices all entered after bv[keep] (or from the fill)
    last_t = end_s if end_s is not None else (float(t0[-1] + dur[-1]) if t0.size else 0.0)
    last_wall = np.array([float(wall[-1])]) if wall.size else np.array([inlet_c])
    end_c = float(temperature(np.array([last_t]), np.array([total]), last_wall)[0])
    memory = MeltState(times_s=bt[keep:].copy(), volumes_mm3=bv[keep:].copy(),
                       fill_time_s=fill, end_c=end_c, retracted_mm=retracted_mm)
    return mean, memory
