"""Extrusion dynamics throughput: commanded feed, pressure advance, lag/slip integrator.

Input: a synthetic planned print of 1.5 M moves (``--quick``: 100 k) — about a 20-hour
print at the typical 20–25 moves/s — built directly as a move table and trapezoid
timeline (0.5–20 mm extrusions at 20–200 mm/s, 3000 mm/s², junction speeds up to 5 mm/s,
travels, and retract/prime pairs as extrude-only moves), so the figures measure this
package alone. Reported: seconds and moves/s for building the nominal feed, Klipper
smoothing, Marlin LA, and integrating without advance, with Klipper advance, and with
slip and grinding; plus the first call in the process (numba cache load) against the
warm one.
"""

from __future__ import annotations

import gc
import time
from collections.abc import Callable

import numpy as np

from flowtwin.dynamics import (
    AdvanceSettings,
    ExtrusionParams,
    apply_advance,
    integrate,
    nominal_feed,
)
from flowtwin.firmware import Firmware
from flowtwin.gcode.moves import MOVE_DTYPE, MoveKind, MoveTable
from flowtwin.planner.timeline import PHASE_DTYPE, Timeline


def synthetic_print(n: int, seed: int = 7) -> tuple[MoveTable, Timeline]:
    """A planned print of ``n`` moves with exact trapezoids (see the module docstring)."""
    rng = np.random.default_rng(seed)
    accel = 3000.0
    kind_draw = rng.uniform(size=n)
    travel = kind_draw < 0.05
    eonly = (kind_draw >= 0.05) & (kind_draw < 0.10)
    extrude = ~(travel | eonly)
    length = rng.uniform(0.5, 20.0, n)
    angle = rng.uniform(0.0, 2 * np.pi, n)
    dx = np.where(eonly, 0.0, length * np.cos(angle))
    dy = np.where(eonly, 0.0, length * np.sin(angle))
    de = np.where(extrude, 0.0333 * length, 0.0)
    retract = np.where(np.arange(n) % 2 == 0, -0.8, 0.8)
    de = np.where(eonly, retract, de)
    path = np.where(eonly, np.abs(de), length)
    speed = np.where(eonly, 35.0, np.where(travel, 250.0, rng.uniform(20.0, 200.0, n)))
    # junction speeds: up to 5 mm/s between extrusions, 0 next to travels and retractions
    junction = rng.uniform(0.0, 5.0, n + 1)
    stopping = ~extrude
    junction[:-1][stopping] = 0.0
    junction[1:][stopping] = 0.0
    junction[0] = junction[-1] = 0.0
    v0, v1 = junction[:-1], junction[1:]
    vc = np.minimum(speed, np.sqrt((2 * accel * path + v0**2 + v1**2) / 2))
    ta = (vc - v0) / accel
    td = (vc - v1) / accel
    tc = np.maximum((path - (vc**2 - v0**2) / (2 * accel) - (vc**2 - v1**2) / (2 * accel)) / vc,
                    0.0)
    dur = ta + tc + td
    mv = np.zeros(n, dtype=MOVE_DTYPE)
    mv["x"] = np.cumsum(dx)
    mv["y"] = np.cumsum(dy)
    mv["de"] = de
    mv["e"] = np.cumsum(de)
    mv["feed_mm_s"] = speed
    mv["flow"] = 1.0
    mv["line"] = np.arange(1, n + 1)
    kind = np.where(extrude, int(MoveKind.EXTRUDE), 0)
    kind = np.where(travel, int(MoveKind.TRAVEL), kind)
    kind = np.where(eonly & (de < 0), int(MoveKind.RETRACT), kind)
    kind = np.where(eonly & (de > 0), int(MoveKind.EXTRUDE), kind)
    kind = np.where(eonly, kind, kind | int(MoveKind.XY))
    mv["kind"] = kind
    ph = np.zeros(n, dtype=PHASE_DTYPE)
    ph["t_start"] = np.concatenate(([0.0], np.cumsum(dur)[:-1]))
    ph["start_v"], ph["cruise_v"], ph["end_v"], ph["accel"] = v0, vc, v1, accel
    ph["accel_t"], ph["cruise_t"], ph["decel_t"] = ta, tc, td
    table = MoveTable(moves=mv, events=[], start_xyze=np.zeros(4), source="synthetic")
    return table, Timeline(phases=ph, total_time_s=float(dur.sum()))


_CPU: dict[str, float] = {}


def _timed(fn: Callable[[], object], key: str = "") -> tuple[float, object]:
    """Wall time of ``fn()`` (and its process CPU time under ``key`` in ``_CPU``)."""
    gc.collect()
    c0 = time.process_time()
    t0 = time.perf_counter()
    out = fn()
    wall = time.perf_counter() - t0
    if key:
        _CPU[key] = time.process_time() - c0
    return wall, out


def run(quick: bool = False) -> dict[str, object]:
    """Time every stage; print a table; return the figures."""
    n = 100_000 if quick else 1_500_000
    table, timeline = synthetic_print(n)
    hours = timeline.total_time_s / 3600.0
    params = ExtrusionParams.build(n, lag_k_s=0.06, compliance_mm_per_n=0.01)
    slip = ExtrusionParams.build(n, lag_k_s=0.06, compliance_mm_per_n=0.01, slip_offset=0.01,
                                 slip_gradient_per_n=0.0032, max_feed_force_n=25.0)
    klipper = AdvanceSettings(Firmware.KLIPPER, k_s=0.04)
    marlin = AdvanceSettings(Firmware.MARLIN, k_s=0.06)
    small_t, small_tl = synthetic_print(2000, seed=1)
    small_p = ExtrusionParams.build(2000, lag_k_s=0.06, compliance_mm_per_n=0.01)
    t_first, _ = _timed(lambda: integrate(nominal_feed(small_t, small_tl), small_p))
    t_second, _ = _timed(lambda: integrate(nominal_feed(small_t, small_tl), small_p))
    results: dict[str, object] = {"moves": n, "print_hours": round(hours, 2),
                                  "first_call_small_s": t_first, "warm_call_small_s": t_second}
    t, feed = _timed(lambda: nominal_feed(table, timeline), "nominal_feed_s")
    results["nominal_feed_s"] = t
    t, kfeed = _timed(lambda: apply_advance(feed, table, klipper), "klipper_advance_s")  # type: ignore[arg-type]
    results["klipper_advance_s"] = t
    t, _ = _timed(lambda: apply_advance(feed, table, marlin), "marlin_advance_s")  # type: ignore[arg-type]
    results["marlin_advance_s"] = t
    t, res = _timed(lambda: integrate(feed, params), "integrate_plain_s")  # type: ignore[arg-type]
    results["integrate_plain_s"] = t
    t, res_k = _timed(lambda: integrate(kfeed, params), "integrate_klipper_s")  # type: ignore[arg-type]
    results["integrate_klipper_s"] = t
    t, res_s = _timed(lambda: integrate(kfeed, slip), "integrate_klipper_slip_grind_s")  # type: ignore[arg-type]
    results["integrate_klipper_slip_grind_s"] = t
    results["segments_plain"] = feed.n_segments  # type: ignore[attr-defined]
    results["segments_klipper"] = kfeed.n_segments  # type: ignore[attr-defined]
    for name, r in (("plain", res), ("klipper", res_k), ("slip", res_s)):
        s = r.summary  # type: ignore[attr-defined]
        results[f"mass_balance_rel_{name}"] = abs(s.mass_balance_error_mm3) / s.fed_mm3
    results["grinding_moves"] = res_s.summary.grinding_moves  # type: ignore[attr-defined]
    print(f"{n} moves, {hours:.1f} h of printing; segments: {results['segments_plain']} "
          f"nominal, {results['segments_klipper']} with Klipper smoothing")
    print(f"first call in process (cache load) {t_first:.3f} s, warm {t_second:.4f} s")
    print(f"{'stage':<34}{'wall s':>9}{'cpu s':>9}{'moves/s (cpu)':>16}")
    for key in ("nominal_feed_s", "klipper_advance_s", "marlin_advance_s", "integrate_plain_s",
                "integrate_klipper_s", "integrate_klipper_slip_grind_s"):
        sec = float(results[key])  # type: ignore[arg-type]
        cpu = _CPU[key]
        results[key[:-2] + "_cpu_s"] = cpu
        print(f"{key:<34}{sec:>9.3f}{cpu:>9.3f}{n / cpu:>16,.0f}")
    print("mass balance |fed - out - Δstored| / fed: "
          + ", ".join(f"{k}: {results[f'mass_balance_rel_{k}']:.1e}"
                      for k in ("plain", "klipper", "slip")))
    return results


if __name__ == "__main__":
    run(quick=True)
