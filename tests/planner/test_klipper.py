"""Klipper planner against analytic solutions of its own rules (Klipper toolhead.py).

Every expected value is derived in the test from the trapezoid kinematics
(``v² = v0² + 2·a·s``) and Klipper's documented junction rules (docs/Kinematics.md):
square_corner_velocity is the speed of a 90° corner, the centripetal limit
``v² = 2·d·a·tan(θ/2)/4`` (θ = interior angle), the extruder corner
``v = icv/|Δ(E/d)|``, the extrude-only limits ``max_velocity·4·nozzle²/filament_area``.
Tolerances: phases hold float32 speeds (rel 1e-6); times are float64 (rel 1e-12 unless
a float32 speed enters the expectation).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from flowtwin.errors import GcodeError
from flowtwin.gcode.moves import MOVE_DTYPE, Event, MoveTable
from flowtwin.planner.klipper import plan_klipper
from flowtwin.planner.klipper_config import KlipperExtruder, KlipperSettings
from flowtwin.planner.timeline import DWELL_FEATURE, time_by_feature, time_by_layer


def table(points, *, feed=100.0, de=0.0, flow=1.0, events=(), lines=None, start=(0, 0, 0),
          layer=None, feature=None, features=()):
    """A move table through ``points`` (end positions) with per-move or scalar columns."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    n = pts.shape[0]
    m = np.zeros(n, dtype=MOVE_DTYPE)
    m["x"], m["y"], m["z"] = pts[:, 0], pts[:, 1], pts[:, 2]
    m["de"] = de
    m["e"] = np.cumsum(np.broadcast_to(np.asarray(de, dtype=float), (n,)))
    m["feed_mm_s"] = feed
    m["flow"] = flow
    m["line"] = np.arange(1, n + 1) if lines is None else lines
    m["layer"] = -1 if layer is None else layer
    m["feature"] = -1 if feature is None else feature
    return MoveTable(moves=m, events=list(events), start_xyze=np.array([*start, 0.0]),
                     features=list(features), source="test.gcode")


def settings(**kw: Any) -> KlipperSettings:
    base: dict[str, Any] = dict(max_velocity=500.0, max_accel=1000.0,
                                square_corner_velocity=5.0, minimum_cruise_ratio=0.0)
    base.update(kw)
    return KlipperSettings(**base)


def trapezoid_time(d, v0, v1, vmax, a):
    """Time of one move from v0 to v1 with cruise ≤ vmax (pure trapezoid)."""
    vp2 = min(vmax * vmax, (2 * a * d + v0 * v0 + v1 * v1) / 2)
    vp = math.sqrt(vp2)
    accel_d = (vp2 - v0 * v0) / (2 * a)
    decel_d = (vp2 - v1 * v1) / (2 * a)
    return (vp - v0) / a + (vp - v1) / a + (d - accel_d - decel_d) / vp


def ev(move_index, code, line=0, **params):
    return Event(move_index, line, code, {k: v for k, v in params.items()})


# ------------------------------------------------------------------ single moves ---

def test_single_move_trapezoid():
    tl = plan_klipper(table([(100, 0, 0)]), settings())
    p = tl.phases[0]
    # accelerate 0→100 mm/s at 1000 mm/s² in 0.1 s over 5 mm, same to stop: 1 + 0.1 s
    assert p["accel_t"] == pytest.approx(0.1, rel=1e-12)
    assert p["cruise_t"] == pytest.approx(0.9, rel=1e-12)
    assert p["decel_t"] == pytest.approx(0.1, rel=1e-12)
    assert p["cruise_v"] == pytest.approx(100.0, rel=1e-7)
    assert p["start_v"] == 0.0 and p["end_v"] == 0.0
    assert tl.total_time_s == pytest.approx(1.1, rel=1e-12)


def test_short_move_triangle():
    tl = plan_klipper(table([(1, 0, 0)]), settings())
    # no cruise: peak v² = a·d; t = 2·sqrt(d/a)
    assert tl.total_time_s == pytest.approx(2 * math.sqrt(1 / 1000), rel=1e-12)
    assert tl.phases["cruise_v"][0] == pytest.approx(math.sqrt(1000.0), rel=1e-6)


@pytest.mark.parametrize("ratio", [0.3, 0.5])
def test_minimum_cruise_ratio_makes_short_moves_cruise(ratio):
    tl = plan_klipper(table([(1, 0, 0)]), settings(minimum_cruise_ratio=ratio))
    p = tl.phases[0]
    # smoothed peak v² = d·a·(1 − ratio): the move cruises over `ratio` of its length
    vc = math.sqrt(1000.0 * (1 - ratio))
    assert p["cruise_v"] == pytest.approx(vc, rel=1e-6)
    assert p["cruise_t"] * vc == pytest.approx(ratio * 1.0, rel=1e-6)
    assert tl.total_time_s == pytest.approx(2 * vc / 1000 + (1 - vc * vc / 1000) / vc,
                                            rel=1e-12)


def test_max_velocity_caps_feed():
    tl = plan_klipper(table([(100, 0, 0)], feed=1000.0), settings(max_velocity=50.0))
    assert tl.phases["cruise_v"][0] == pytest.approx(50.0)
    assert tl.total_time_s == pytest.approx(trapezoid_time(100, 0, 0, 50, 1000), rel=1e-12)


# ------------------------------------------------------------------ junctions ---

def test_collinear_moves_do_not_slow_down():
    split = plan_klipper(table([(50, 0, 0), (100, 0, 0)]), settings())
    assert split.phases["end_v"][0] == pytest.approx(100.0)
    assert split.total_time_s == pytest.approx(1.1, rel=1e-12)


@pytest.mark.parametrize("scv", [5.0, 2.0, 0.0])
def test_square_corner_velocity_is_the_90_degree_corner_speed(scv):
    tl = plan_klipper(table([(100, 0, 0), (100, 100, 0)]),
                      settings(square_corner_velocity=scv))
    assert tl.phases["end_v"][0] == pytest.approx(scv, abs=1e-5)
    assert tl.phases["start_v"][1] == pytest.approx(scv, abs=1e-5)
    expect = 2 * trapezoid_time(100, 0, scv, 100, 1000)
    assert tl.total_time_s == pytest.approx(expect, rel=1e-9)


def test_corner_speed_independent_of_accel():
    # junction deviation scv²(√2−1)/a times a: the 90° corner stays at scv after M204
    t = table([(100, 0, 0), (100, 100, 0)], events=[ev(0, "M204", 1, S=400.0)])
    tl = plan_klipper(t, settings())
    assert tl.phases["end_v"][0] == pytest.approx(5.0, rel=1e-6)
    assert tl.phases["accel"][0] == pytest.approx(400.0)


def test_centripetal_limit_on_short_segments():
    # 1 mm segments turning by 60°: interior angle θ = 120°, tan(θ/2) = √3;
    # v² = 2·d·a·tan(θ/2)/4 = 866 (junction deviation allows 6694 at scv = 50)
    phi = math.radians(60)
    pts = [(1, 0, 0), (1 + math.cos(phi), math.sin(phi), 0)]
    tl = plan_klipper(table(pts), settings(square_corner_velocity=50.0))
    v2 = 2 * 1.0 * 1000 * math.sqrt(3) / 4
    assert tl.phases["end_v"][0] == pytest.approx(math.sqrt(v2), rel=1e-6)


def test_extruder_instantaneous_corner_velocity():
    # straight line, but E/d jumps from 0.05 to 0: v = icv/0.05 = 20 mm/s
    t = table([(10, 0, 0), (20, 0, 0)], de=np.array([0.5, 0.0]))
    tl = plan_klipper(t, settings())
    assert tl.phases["end_v"][0] == pytest.approx(20.0, rel=1e-6)
    ex = KlipperExtruder(instantaneous_corner_velocity=3.0)
    tl3 = plan_klipper(t, settings(extruders=(ex,)))
    assert tl3.phases["end_v"][0] == pytest.approx(60.0, rel=1e-6)


def test_reversal_stops():
    tl = plan_klipper(table([(10, 0, 0), (0, 0, 0)]), settings(square_corner_velocity=50.0))
    assert tl.phases["end_v"][0] == 0.0


# ------------------------------------------------------------------ E and Z limits ---

def ref_settings(**kw):
    """Reference printer A: derived extrude-only limits 79.82 mm/s, 798.2 mm/s²."""
    return settings(max_velocity=300.0, max_accel=3000.0, **kw)


def test_derived_extrude_only_limits():
    s = ref_settings()
    ratio = 4 * 0.4 ** 2 / (math.pi * 1.75 ** 2 / 4)
    assert s.max_extrude_only_velocity == pytest.approx(300 * ratio)
    assert s.max_extrude_only_accel == pytest.approx(3000 * ratio)
    assert s.max_extrude_only_velocity == pytest.approx(79.82, abs=0.005)  # README table


def test_extrude_only_move_stops_neighbours_and_uses_e_limits():
    s = ref_settings()
    t = table([(10, 0, 0), (10, 0, 0), (20, 0, 0)], de=np.array([0.0, -1.0, 0.0]),
              feed=np.array([100.0, 40.0, 100.0]))
    tl = plan_klipper(t, s)
    p = tl.phases
    assert p["end_v"][0] == 0.0 and p["start_v"][2] == 0.0   # no blending
    a_e = s.max_extrude_only_accel
    assert p["accel"][1] == pytest.approx(a_e, rel=1e-6)
    # 1 mm at 798 mm/s² peaks at sqrt(798) = 28 mm/s < 40: a triangle
    assert tl.move_time_s[1] == pytest.approx(2 * math.sqrt(1 / a_e), rel=1e-12)


def test_extrude_only_speed_limit():
    s = ref_settings()
    tl = plan_klipper(table([(0, 0, 0)], de=20.0, feed=100.0), s)   # peak would be 126
    assert tl.phases["cruise_v"][0] == pytest.approx(s.max_extrude_only_velocity, rel=1e-6)


def test_retract_during_travel_scaled_by_e_share():
    s = ref_settings()
    # 1 mm of XY with 5 mm of retraction: |E/d| = 5, v ≤ 79.8/5, a ≤ 798.2/5
    tl = plan_klipper(table([(1, 0, 0)], de=-5.0, feed=100.0), s)
    assert tl.phases["accel"][0] == pytest.approx(s.max_extrude_only_accel / 5, rel=1e-6)
    assert tl.phases["cruise_v"][0] <= s.max_extrude_only_velocity / 5 * (1 + 1e-6)


def test_flow_scales_extruder_distance():
    tl = plan_klipper(table([(0, 0, 0)], de=2.0, flow=0.5, feed=1.0), ref_settings())
    assert tl.total_time_s == pytest.approx(trapezoid_time(1.0, 0, 0, 1.0, 798.2),
                                            rel=1e-3)


def test_z_limits():
    s = settings(max_z_velocity=5.0, max_z_accel=100.0)
    tl = plan_klipper(table([(0, 0, 10)], feed=10.0), s)
    assert tl.total_time_s == pytest.approx(10 / 5 + 5 / 100, rel=1e-12)
    # 3-4-5 move: z_ratio = 5/4 scales both limits along the path
    tl = plan_klipper(table([(3, 0, 4)], feed=100.0), s)
    assert tl.phases["cruise_v"][0] == pytest.approx(6.25, rel=1e-6)
    assert tl.phases["accel"][0] == pytest.approx(125.0, rel=1e-6)


# ------------------------------------------------------------------ commands ---

def test_m204_forms():
    pts = [(100, 0, 0), (200, 0, 0), (300, 0, 0), (400, 0, 0)]
    events = [ev(1, "M204", 2, S=500.0), ev(2, "M204", 3, P=200.0),
              ev(3, "M204", 4, P=800.0, T=600.0)]
    tl = plan_klipper(table(pts, events=events), settings())
    assert list(tl.phases["accel"]) == pytest.approx([1000.0, 500.0, 500.0, 600.0])
    assert any("invalid M204" in w for w in tl.warnings)
    with pytest.raises(GcodeError, match="M204 parameter S") as info:
        plan_klipper(table(pts, events=[ev(1, "M204", 7, S=0.0)]), settings())
    assert info.value.line == 7


def test_set_velocity_limit():
    pts = [(100, 0, 0), (200, 0, 0)]
    t = table(pts, feed=200.0, events=[
        ev(1, "SET_VELOCITY_LIMIT", 2, VELOCITY=50.0, ACCEL=2000.0, ACCEL_TO_DECEL=10.0)])
    tl = plan_klipper(t, settings())
    assert tl.phases["cruise_v"][1] == pytest.approx(50.0)
    assert tl.phases["accel"][1] == pytest.approx(2000.0)
    assert any("ACCEL_TO_DECEL" in w for w in tl.warnings)
    corner = table([(100, 0, 0), (100, 100, 0)],
                   events=[ev(0, "SET_VELOCITY_LIMIT", 1, SQUARE_CORNER_VELOCITY=10.0)])
    assert plan_klipper(corner, settings()).phases["end_v"][0] == pytest.approx(10.0)
    ratio = table([(1, 0, 0)], events=[ev(0, "SET_VELOCITY_LIMIT", 1,
                                          MINIMUM_CRUISE_RATIO=0.5)])
    vc = plan_klipper(ratio, settings()).phases["cruise_v"][0]
    assert vc == pytest.approx(math.sqrt(500.0), rel=1e-6)


def test_g4_dwell_stops_and_waits():
    pts = [(100, 0, 0), (200, 0, 0)]
    one = trapezoid_time(100, 0, 0, 100, 1000)
    tl = plan_klipper(table(pts, events=[ev(1, "G4", 2, P=500.0)]), settings())
    assert tl.phases["end_v"][0] == 0.0
    assert tl.total_time_s == pytest.approx(2 * one + 0.5, rel=1e-12)
    assert tl.phases["t_start"][1] == pytest.approx(one + 0.5, rel=1e-12)
    # Klipper reads only P (ms): G4 S5 is a stop without dwell
    tl = plan_klipper(table(pts, events=[ev(1, "G4", 2, S=5.0)]), settings())
    assert tl.total_time_s == pytest.approx(2 * one, rel=1e-12)
    with pytest.raises(GcodeError, match="G4 parameter P"):
        plan_klipper(table(pts, events=[ev(1, "G4", 2, P=-1.0)]), settings())


def test_m400_stops():
    tl = plan_klipper(table([(50, 0, 0), (100, 0, 0)], events=[ev(1, "M400", 2)]),
                      settings())
    assert tl.phases["end_v"][0] == 0.0
    assert tl.total_time_s == pytest.approx(2 * trapezoid_time(50, 0, 0, 100, 1000))


@pytest.mark.parametrize(("pa", "kfd"), [(0.0, 0.001), (0.04, 0.020)])
def test_motors_off_dwell(pa, kfd):
    ex = KlipperExtruder(pressure_advance=pa, pressure_advance_smooth_time=0.04)
    s = settings(extruders=(ex,))
    assert s.kin_flush_delay == pytest.approx(kfd)
    one = trapezoid_time(100, 0, 0, 100, 1000)
    tl = plan_klipper(table([(100, 0, 0)], events=[ev(1, "M84", 2)]), s)
    # 2 x 0.1 s dwell plus the 2 x kin_flush_delay restart after the step flush
    assert tl.total_time_s == pytest.approx(one + 0.2 + 2 * kfd, rel=1e-12)
    noop = plan_klipper(table([(100, 0, 0)], events=[ev(1, "M84", 2, E="")]), s)
    assert noop.total_time_s == pytest.approx(one, rel=1e-12)
    # nothing moved since the last flush: no restart gap
    first = plan_klipper(table([(100, 0, 0)], events=[ev(0, "M18", 1)]), s)
    assert first.total_time_s == pytest.approx(one + 0.2, rel=1e-12)


def two_tools(pa=0.0):
    exs = tuple(KlipperExtruder(name=name, pressure_advance=pa)
                for name in ("extruder", "extruder1"))
    return settings(extruders=exs)


def test_tool_change_gap_and_stop():
    s = two_tools()
    pts = [(50, 0, 0), (100, 0, 0)]
    half = trapezoid_time(50, 0, 0, 100, 1000)
    tl = plan_klipper(table(pts, events=[ev(1, "T1", 2)]), s)
    assert tl.phases["end_v"][0] == 0.0
    assert tl.total_time_s == pytest.approx(2 * half + 2 * 0.001, rel=1e-12)
    assert any("restart" in d[2] for d in tl.dwell_s)
    act = plan_klipper(table(pts, events=[ev(1, "ACTIVATE_EXTRUDER", 2,
                                             EXTRUDER="extruder1")]), s)
    assert act.total_time_s == pytest.approx(tl.total_time_s, rel=1e-12)
    with_pa = plan_klipper(table(pts, events=[ev(1, "T1", 2)]), two_tools(pa=0.04))
    assert with_pa.total_time_s == pytest.approx(2 * half + 2 * 0.020, rel=1e-12)


@pytest.mark.parametrize("code", ["T0", "T5", "T255", "T1000"])
def test_pseudo_and_active_tools_do_nothing(code):
    tl = plan_klipper(table([(50, 0, 0), (100, 0, 0)], events=[ev(1, code, 2)]), two_tools())
    assert tl.phases["end_v"][0] == pytest.approx(100.0)
    assert tl.total_time_s == pytest.approx(1.1, rel=1e-12)


def test_unknown_extruder_name_is_an_error():
    with pytest.raises(GcodeError, match="extruder the printer does not have"):
        plan_klipper(table([(1, 0, 0)], events=[ev(0, "ACTIVATE_EXTRUDER", 3,
                                                    EXTRUDER="extruder9")]), two_tools())


def test_tool_change_resets_extrude_factor():
    # gcode_move sets the extrude factor to 100 % on ACTIVATE_EXTRUDER, until an M221
    de, flow = np.array([2.0, 2.0, 2.0]), 0.5
    pts = [(0, 0, 0)] * 3
    events = [ev(1, "T1", 2), ev(2, "M221", 3, S=50.0)]
    tl = plan_klipper(table(pts, de=de, flow=flow, feed=1.0, events=events), two_tools())
    # extrude-only moves at 1 mm/s: time ≈ length + 1/a (a = 798 mm/s² at 300/3000 base)
    lengths = tl.move_time_s - 1.0 / two_tools().max_extrude_only_accel
    assert lengths == pytest.approx([1.0, 2.0, 1.0], rel=1e-9)


def test_set_pressure_advance_new_smoothing_flushes():
    s = settings()
    one = trapezoid_time(100, 0, 0, 100, 1000)
    pts = [(100, 0, 0), (200, 0, 0)]
    same = plan_klipper(table(pts, events=[ev(1, "SET_PRESSURE_ADVANCE", 2,
                                              SMOOTH_TIME=0.04)]), s)
    assert same.total_time_s == pytest.approx(1.1 + 1.0, rel=1e-12)   # PA 0: no change
    on = plan_klipper(table(pts, events=[ev(1, "SET_PRESSURE_ADVANCE", 2,
                                            ADVANCE=0.05)]), s)
    # flush with the old 1 ms window, restart after the new 20 ms one
    assert on.total_time_s == pytest.approx(2 * one + 0.001 + 0.020, rel=1e-12)


def test_g28_moves_the_start_to_position_endstop():
    s = settings(position_endstop=(5.0, 0.0, 0.0), position_min=(0.0, 0.0, 0.0),
                 position_max=(200.0, 200.0, 200.0))
    t = table([(100, 0, 0), (5, 50, 0)], events=[ev(1, "G28", 2, X="")])
    tl = plan_klipper(t, s)
    # after G28 X the head is at X5 (not X100): the second move is 50 mm along Y only
    assert tl.move_time_s[1] == pytest.approx(trapezoid_time(50, 0, 0, 100, 1000))
    assert tl.phases["end_v"][0] == 0.0


# ------------------------------------------------------------------ stops, totals ---

def test_stop_after_lines_and_time_at_line():
    pts = [(50, 0, 0), (100, 0, 0), (150, 0, 0)]
    tl = plan_klipper(table(pts, lines=[3, 5, 7]), settings(), stop_after_lines=[0, 5])
    half = trapezoid_time(50, 0, 0, 100, 1000)
    assert tl.stop_times_s[0] == 0.0
    assert tl.time_at_line(5) == pytest.approx(trapezoid_time(100, 0, 0, 100, 1000))
    assert tl.phases["end_v"][1] == 0.0
    assert tl.total_time_s == pytest.approx(tl.time_at_line(5) + half)
    assert tl.time_at_line(3) == pytest.approx(tl.end_time_s[0])
    assert tl.time_at_line(1) == 0.0


def test_zero_length_move_takes_no_time():
    tl = plan_klipper(table([(10, 0, 0), (10, 0, 0), (20, 0, 0)]), settings())
    assert tl.move_time_s[1] == 0.0
    assert tl.phases["end_v"][0] == pytest.approx(100.0)


def test_totals_by_layer_and_feature_add_up():
    pts = [(10, 0, 0), (10, 10, 0), (20, 10, 0.2), (20, 20, 0.2)]
    t = table(pts, de=np.array([0.5, 0.5, 0.0, 0.5]), layer=np.array([0, 0, 1, 1]),
              feature=np.array([0, 1, -1, 0]), features=["wall", "infill"],
              events=[ev(2, "G4", 3, P=250.0)])
    tl = plan_klipper(t, settings())
    by_layer = time_by_layer(tl, t)
    by_feature = time_by_feature(tl, t)
    assert sum(by_layer.values()) == pytest.approx(tl.total_time_s, rel=1e-12)
    assert sum(by_feature.values()) == pytest.approx(tl.total_time_s, rel=1e-12)
    assert by_feature[DWELL_FEATURE] == pytest.approx(0.25)
    assert set(by_feature) == {"wall", "infill", "unknown", DWELL_FEATURE}
    assert by_layer[1] == pytest.approx(tl.move_time_s[2:].sum() + 0.25)


def random_table(rng, n):
    """Zig-zags with short and long segments, E-only moves, Z hops, M204/G4 events."""
    steps = rng.normal(size=(n, 3)) * rng.choice([0.2, 3.0, 40.0], size=(n, 1))
    steps[:, 2] *= rng.random(n) < 0.05
    eonly = rng.random(n) < 0.05
    steps[eonly] = 0.0
    pts = np.cumsum(steps, axis=0)
    de = np.where(eonly, rng.choice([-1.0, 1.0], n) * rng.random(n) * 2,
                  np.abs(steps[:, 0]) * 0.03 * (rng.random(n) < 0.7))
    feed = rng.choice([5.0, 30.0, 120.0, 400.0], size=n)
    events = [ev(int(i), "M204", int(i) + 1, S=float(rng.choice([500.0, 3000.0, 8000.0])))
              for i in rng.choice(n, size=n // 20, replace=False)]
    events += [ev(int(i), "G4", int(i) + 1, P=10.0) for i in rng.choice(n, 3, replace=False)]
    events.sort(key=lambda e: e.move_index)
    return table(pts, de=de, feed=feed, events=events, lines=np.arange(1, n + 1) * 2)


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("ratio", [0.0, 0.5])
def test_lazy_flush_gives_the_same_plan(seed, ratio):
    rng = np.random.default_rng(seed)
    t = random_table(rng, 3000)
    s = settings(minimum_cruise_ratio=ratio, max_accel=3000.0)
    lazy = plan_klipper(t, s, lazy_flush=True)
    full = plan_klipper(t, s)
    for name in ("start_v", "cruise_v", "end_v", "accel_t", "cruise_t", "decel_t"):
        np.testing.assert_allclose(lazy.phases[name], full.phases[name], rtol=1e-9,
                                   atol=1e-12)
    assert lazy.total_time_s == pytest.approx(full.total_time_s, rel=1e-12)


def test_plan_is_consistent():
    """Profiles cover each move's length, speeds join, accelerations stay in bounds."""
    rng = np.random.default_rng(7)
    t = random_table(rng, 2000)
    s = settings(minimum_cruise_ratio=0.3, max_accel=3000.0)
    tl = plan_klipper(t, s)
    p = tl.phases
    sv, cv, evl = (p[k].astype(float) for k in ("start_v", "cruise_v", "end_v"))
    dist = (p["accel_t"] * (sv + cv) / 2 + p["cruise_t"] * cv + p["decel_t"] * (cv + evl) / 2)
    pts = np.stack([t.moves["x"], t.moves["y"], t.moves["z"]], axis=1)
    d_xyz = np.linalg.norm(np.diff(np.vstack([[0, 0, 0], pts]), axis=0), axis=1)
    length = np.where(d_xyz > 1e-9, d_xyz, np.abs(t.moves["de"]))
    np.testing.assert_allclose(dist, length, rtol=1e-5, atol=1e-9)   # float32 speeds
    assert np.all(cv <= t.moves["feed_mm_s"] * (1 + 1e-6))
    assert np.all(p["accel_t"] >= 0) and np.all(p["cruise_t"] >= -1e-12)
    moved = length > 0
    # speeds join between consecutive moves (a stop shows as 0 on both sides)
    k = np.flatnonzero(moved[:-1] & moved[1:])
    np.testing.assert_allclose(evl[k], sv[k + 1], rtol=1e-6, atol=1e-6)
    ends = p["t_start"] + tl.move_time_s
    assert np.all(p["t_start"][1:] >= ends[:-1] - 1e-9)   # moves never overlap
    gaps = sum(d[1] for d in tl.dwell_s)
    assert tl.total_time_s == pytest.approx(tl.move_time_s.sum() + gaps, rel=1e-12)


# ------------------------------------------------------------------ errors ---

def test_moves_klipper_refuses():
    s = ref_settings()
    with pytest.raises(GcodeError, match="Extrude only move too long") as info:
        plan_klipper(table([(0, 0, 0)], de=60.0, lines=[42]), s)
    assert info.value.line == 42
    with pytest.raises(GcodeError, match="maximum extrusion"):
        plan_klipper(table([(1, 0, 0)], de=2.0), s)   # 2 mm of filament per mm: 3.7 mm²
    bounded = ref_settings(position_min=(0.0, 0.0, 0.0), position_max=(200.0, 200.0, 200.0))
    with pytest.raises(GcodeError, match="Move out of range: X"):
        plan_klipper(table([(250, 0, 0)]), bounded)
    with pytest.raises(GcodeError, match="no extruder"):
        plan_klipper(table([(1, 0, 0)], de=0.01), settings(extruders=()))
    with pytest.raises(GcodeError, match="positive speed"):
        plan_klipper(table([(1, 0, 0)], feed=0.0), s)
