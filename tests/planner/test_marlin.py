"""Marlin planner model against analytic answers (trapezoids, jerk, JD, limits, stops)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import pytest

from flowtwin.errors import GcodeError, ProfileError
from flowtwin.gcode.moves import MOVE_DTYPE, Event, MoveTable
from flowtwin.planner.marlin import (
    JerkVariant,
    MarlinSettings,
    marlin_settings_from_slicer_config,
    plan_marlin,
)
from flowtwin.planner.timeline import time_by_feature, time_by_layer

# Limits so high they never bind, unless a test lowers one on purpose.
BIG = 1e9
FREE = MarlinSettings(max_feedrate_mm_s=(BIG,) * 4, max_acceleration_mm_s2=(BIG,) * 4,
                      print_accel_mm_s2=1000.0, retract_accel_mm_s2=1000.0,
                      travel_accel_mm_s2=1000.0, jerk_mm_s=(10.0, 10.0, 10.0, 10.0),
                      junction_deviation_mm=None, minimum_planner_speed_mm_s=1e-6,
                      block_buffer_size=None)
# Float32 speeds in the timeline: 1e-6 relative.
RTOL = 1e-6


def table(points: Sequence[tuple[float, ...]], feed: float | list[float] = 50.0,
          de: list[float] | None = None, events: list[Event] | None = None,
          tools: list[int] | None = None) -> MoveTable:
    """Moves to each (x, y[, z]) point from the origin."""
    m = np.zeros(len(points), MOVE_DTYPE)
    m["x"] = [p[0] for p in points]
    m["y"] = [p[1] for p in points]
    m["z"] = [p[2] if len(p) > 2 else 0.0 for p in points]
    m["feed_mm_s"] = feed
    m["flow"] = 1.0
    m["line"] = np.arange(1, len(points) + 1)
    if de is not None:
        m["de"] = de
        m["e"] = np.cumsum(de)
    if tools is not None:
        m["tool"] = tools
    return MoveTable(moves=m, events=events or [], start_xyze=np.zeros(4), source="t.gcode")


def trapezoid_time(length: float, v_in: float, v_nom: float, v_out: float, a: float) -> float:
    """Closed-form duration of one trapezoid/triangle block."""
    v_peak = min(v_nom, math.sqrt((2 * a * length + v_in**2 + v_out**2) / 2))
    d_acc = (v_peak**2 - v_in**2) / (2 * a)
    d_dec = (v_peak**2 - v_out**2) / (2 * a)
    return (v_peak - v_in) / a + (v_peak - v_out) / a + (length - d_acc - d_dec) / v_peak


def test_single_move_trapezoid() -> None:
    tl = plan_marlin(table([(100.0, 0.0)], 50.0), FREE)
    ph = tl.phases[0]
    # accelerate 0 → 50 mm/s at 1000 mm/s² (0.05 s, 1.25 mm), cruise 97.5 mm, decelerate.
    assert ph["accel_t"] == pytest.approx(0.05, rel=1e-6)
    assert ph["decel_t"] == pytest.approx(0.05, rel=1e-6)
    assert ph["cruise_t"] == pytest.approx(97.5 / 50.0, rel=1e-6)
    assert tl.total_time_s == pytest.approx(2.05, rel=1e-6)
    assert tl.firmware == "marlin"


def test_single_move_with_default_minimum_planner_speed() -> None:
    s = replace(FREE, minimum_planner_speed_mm_s=0.05)
    tl = plan_marlin(table([(100.0, 0.0)], 50.0), s)
    assert tl.phases[0]["start_v"] == pytest.approx(0.05, rel=RTOL)
    assert tl.phases[0]["end_v"] == pytest.approx(0.05, rel=RTOL)
    assert tl.total_time_s == pytest.approx(trapezoid_time(100, 0.05, 50, 0.05, 1000), rel=1e-9)


def test_short_move_is_a_triangle() -> None:
    tl = plan_marlin(table([(1.0, 0.0)], 100.0), FREE)
    ph = tl.phases[0]
    assert ph["cruise_v"] == pytest.approx(math.sqrt(1000.0 * 1.0), rel=RTOL)
    assert ph["cruise_t"] == pytest.approx(0.0, abs=1e-12)
    assert tl.total_time_s == pytest.approx(2 * math.sqrt(1.0 / 1000.0), rel=1e-6)


@pytest.mark.parametrize("settings", [
    FREE, replace(FREE, jerk_variant=JerkVariant.REWORKED),
    replace(FREE, junction_deviation_mm=0.05)])
def test_collinear_moves_do_not_slow_down(settings: MarlinSettings) -> None:
    tl = plan_marlin(table([(50.0, 0.0), (100.0, 0.0)], 50.0), settings)
    assert tl.phases[0]["end_v"] == pytest.approx(50.0, rel=RTOL)
    assert tl.phases[1]["start_v"] == pytest.approx(50.0, rel=RTOL)
    assert tl.total_time_s == pytest.approx(2.05, rel=1e-6)


@pytest.mark.parametrize("variant", list(JerkVariant))
def test_classic_jerk_axis_aligned_corner(variant: JerkVariant) -> None:
    # +X then +Y at 100 mm/s, jerk 10: each axis changes by 100 → scale 10/100.
    s = replace(FREE, jerk_variant=variant)
    tl = plan_marlin(table([(100.0, 0.0), (100.0, 100.0)], 100.0), s)
    assert tl.phases[0]["end_v"] == pytest.approx(10.0, rel=RTOL)
    assert tl.phases[1]["start_v"] == pytest.approx(10.0, rel=RTOL)


def test_classic_jerk_diagonal_corner_variants_differ() -> None:
    # (+X+Y) then (-X+Y) at 100 mm/s: X reverses from +70.7 to -70.7 mm/s.
    pts = [(100.0, 100.0), (0.0, 200.0)]
    vx = 100.0 / math.sqrt(2.0)
    legacy = plan_marlin(table(pts, 100.0), FREE)
    # Legacy: an axis reversal counts max(|v_exit|, |v_entry|) = 70.7 → v_j = 100·10/70.7.
    assert legacy.phases[0]["end_v"] == pytest.approx(100.0 * 10.0 / vx, rel=RTOL)
    reworked = plan_marlin(table(pts, 100.0), replace(FREE, jerk_variant=JerkVariant.REWORKED))
    # Reworked: the signed difference 2·70.7 → v_j = 100·10/141.4.
    assert reworked.phases[0]["end_v"] == pytest.approx(100.0 * 10.0 / (2 * vx), rel=RTOL)


def test_legacy_safe_speed_lets_a_slow_block_jump_up() -> None:
    # 5 mm/s then 100 mm/s along X: both safe speeds (5 and 10) exceed 0.99 v_j, so the
    # junction takes the new block's safe speed 10 mm/s; the slow block ends at its 5 mm/s.
    tl = plan_marlin(table([(10.0, 0.0), (110.0, 0.0)], [5.0, 100.0]), FREE)
    assert tl.phases[0]["end_v"] == pytest.approx(5.0, rel=RTOL)
    assert tl.phases[1]["start_v"] == pytest.approx(10.0, rel=RTOL)
    reworked = plan_marlin(table([(10.0, 0.0), (110.0, 0.0)], [5.0, 100.0]),
                           replace(FREE, jerk_variant=JerkVariant.REWORKED))
    assert reworked.phases[1]["start_v"] == pytest.approx(5.0, rel=RTOL)


def jd_speed(accel: float, jd: float, turn_rad: float) -> float:
    """Grbl/Marlin JD junction speed for a turn of ``turn_rad`` between two directions."""
    sin_half = math.sqrt(0.5 * (1.0 + math.cos(turn_rad)))   # sin(θ/2), θ = π - turn
    return math.sqrt(accel * jd * sin_half / (1.0 - sin_half))


@pytest.mark.parametrize("turn_deg", [30.0, 90.0, 135.0])
def test_junction_deviation_corner_speed(turn_deg: float) -> None:
    s = replace(FREE, junction_deviation_mm=0.05)
    t = math.radians(turn_deg)
    pts = [(100.0, 0.0), (100.0 + 100.0 * math.cos(t), 100.0 * math.sin(t))]
    tl = plan_marlin(table(pts, 200.0), s)
    assert tl.phases[0]["end_v"] == pytest.approx(jd_speed(1000.0, 0.05, t), rel=1e-5)


def test_junction_deviation_small_segment_arc_cap() -> None:
    # A 0.5 mm block turning 20°: JD_HANDLE_SMALL_SEGMENTS caps v² at L·a/φ. Marlin's
    # φ comes from a polynomial with ±0.033 rad error, so the speed is checked within
    # the range that error allows.
    s = replace(FREE, junction_deviation_mm=0.05)
    phi = math.radians(20.0)
    end = (10.0 + 0.5 * math.cos(phi), 0.5 * math.sin(phi))
    far = (end[0] + 100.0 * math.cos(phi), end[1] + 100.0 * math.sin(phi))
    pts = [(10.0, 0.0), end, far]
    tl = plan_marlin(table(pts, 200.0), s)
    v = float(tl.phases[0]["end_v"])
    assert jd_speed(1000.0, 0.05, phi) > math.sqrt(0.5 * 1000.0 / (phi - 0.033))
    assert math.sqrt(0.5 * 1000.0 / (phi + 0.033)) <= v <= math.sqrt(0.5 * 1000.0 / (phi - 0.033))
    free = plan_marlin(table(pts, 200.0), replace(s, jd_small_segments=False))
    assert free.phases[0]["end_v"] > v


def test_junction_deviation_reversal_stops() -> None:
    s = replace(FREE, junction_deviation_mm=0.05, minimum_planner_speed_mm_s=0.05)
    tl = plan_marlin(table([(10.0, 0.0), (0.0, 0.0)], 50.0), s)
    assert tl.phases[0]["end_v"] == pytest.approx(0.05, rel=RTOL)


def test_per_axis_acceleration_limit_on_a_diagonal() -> None:
    s = replace(FREE, max_acceleration_mm_s2=(500.0, BIG, BIG, BIG))
    tl = plan_marlin(table([(100.0, 100.0)], 50.0), s)
    # a·|dx|/L ≤ 500 with |dx|/L = 1/√2 → a = 500·√2 < M204 1000.
    assert tl.phases[0]["accel"] == pytest.approx(500.0 * math.sqrt(2.0), rel=RTOL)


def test_per_axis_feedrate_limit_scales_the_move() -> None:
    s = replace(FREE, max_feedrate_mm_s=(50.0, BIG, BIG, BIG))
    tl = plan_marlin(table([(100.0, 100.0)], 100.0), s)
    # X would run at 70.7 mm/s; scaled to 50 → path speed 50·√2.
    assert tl.phases[0]["cruise_v"] == pytest.approx(50.0 * math.sqrt(2.0), rel=RTOL)


def test_extrude_only_move_uses_e_feedrate_limit_and_retract_accel() -> None:
    s = replace(FREE, max_feedrate_mm_s=(BIG, BIG, BIG, 40.0), retract_accel_mm_s2=700.0)
    tl = plan_marlin(table([(0.0, 0.0)], 100.0, de=[-5.0]), s)
    ph = tl.phases[0]
    assert ph["cruise_v"] == pytest.approx(40.0, rel=RTOL)
    assert ph["accel"] == pytest.approx(700.0, rel=RTOL)
    assert tl.total_time_s == pytest.approx(trapezoid_time(5.0, 0, 40, 0, 700), rel=1e-5)


def test_m221_flow_scales_the_e_axis_limit() -> None:
    # 10 mm in X with 10 mm of E at 50 mm/s: the E motor would run at 50 · flow mm/s.
    s = replace(FREE, max_feedrate_mm_s=(BIG, BIG, BIG, 40.0))
    t = table([(10.0, 0.0)], 50.0, de=[10.0])
    assert plan_marlin(t, s).phases[0]["cruise_v"] == pytest.approx(40.0, rel=RTOL)
    t.moves["flow"] = 0.5
    assert plan_marlin(t, s).phases[0]["cruise_v"] == pytest.approx(50.0, rel=RTOL)


def test_m204_selects_print_travel_and_retract_acceleration() -> None:
    s = replace(FREE, print_accel_mm_s2=800.0, travel_accel_mm_s2=2000.0,
                retract_accel_mm_s2=500.0)
    pts = [(20.0, 0.0), (40.0, 0.0), (40.0, 0.0), (60.0, 0.0)]
    tl = plan_marlin(table(pts, 50.0, de=[0.0, 1.0, -1.0, -0.5]), s)
    # travel → T; XY with E → P; E only → R; XY with retraction (wipe) → P.
    np.testing.assert_allclose(tl.phases["accel"], [2000.0, 800.0, 500.0, 800.0], rtol=RTOL)


def test_m204_events_apply_from_where_they_appear() -> None:
    events = [Event(1, 2, "M204", {"P": 600.0}), Event(2, 3, "M204", {"S": 1500.0}),
              Event(3, 4, "M204", {"T": 2500.0})]
    pts = [(10.0, 0.0), (20.0, 0.0), (30.0, 0.0), (40.0, 0.0), (50.0, 0.0)]
    tl = plan_marlin(table(pts, 50.0, de=[0.1, 0.1, 0.1, 0.1, 0.0], events=events), FREE)
    # S sets both P and T (Marlin 2); the last move is a travel.
    np.testing.assert_allclose(tl.phases["accel"], [1000, 600, 1500, 1500, 2500], rtol=RTOL)


def test_m201_m203_m205_events() -> None:
    events = [Event(1, 2, "M201", {"X": 250.0}), Event(1, 2, "M203", {"X": 20.0}),
              Event(1, 2, "M205", {"T": 30.0})]
    tl = plan_marlin(table([(10.0, 0.0), (20.0, 0.0)], [50.0, 5.0], events=events), FREE)
    # M205 T raises the 5 mm/s travel to 30, M203 X caps it at 20; M201 X caps a at 250.
    assert tl.phases[1]["cruise_v"] == pytest.approx(20.0, rel=RTOL)
    assert tl.phases[1]["accel"] == pytest.approx(250.0, rel=RTOL)
    assert tl.phases[0]["accel"] == pytest.approx(1000.0, rel=RTOL)


def test_g4_dwell_stops_and_adds_time() -> None:
    pts = [(100.0, 0.0), (200.0, 0.0)]
    base = plan_marlin(table(pts, 50.0), FREE)
    ev = [Event(1, 2, "G4", {"P": 500.0})]
    tl = plan_marlin(table(pts, 50.0, events=ev), FREE)
    assert tl.phases[0]["end_v"] == pytest.approx(1e-6, rel=1e-3)
    assert tl.total_time_s == pytest.approx(2 * 2.05 + 0.5, rel=1e-6)
    assert base.total_time_s == pytest.approx(4.05, rel=1e-6)
    assert tl.phases[1]["t_start"] == pytest.approx(2.05 + 0.5, rel=1e-6)
    assert tl.dwell_s == [(1, pytest.approx(0.5), "G4 line 2")]
    both = plan_marlin(table(pts, 50.0, events=[Event(1, 2, "G4", {"P": 500.0, "S": 2.0})]),
                       FREE)
    assert both.total_time_s == pytest.approx(2 * 2.05 + 2.0, rel=1e-6)  # S wins


@pytest.mark.parametrize("code", ["M400", "M109", "G28"])
def test_synchronising_commands_stop_without_time(code: str) -> None:
    tl = plan_marlin(table([(100.0, 0.0), (200.0, 0.0)], 50.0,
                           events=[Event(1, 2, code, {})]), FREE)
    assert tl.total_time_s == pytest.approx(4.1, rel=1e-6)


def test_tool_change_and_stop_after_lines_stop() -> None:
    pts = [(100.0, 0.0), (200.0, 0.0), (300.0, 0.0)]
    tl = plan_marlin(table(pts, 50.0, tools=[0, 1, 1]), FREE, stop_after_lines=[2])
    np.testing.assert_allclose(tl.phases["end_v"], [1e-6, 1e-6, 1e-6], rtol=1e-3)
    assert tl.total_time_s == pytest.approx(3 * 2.05, rel=1e-6)


def test_stop_times_layers_and_features() -> None:
    # Moves on lines 1, 3, 5; dwells of 1 s (line 2) and 2 s (line 4) between them.
    pts = [(100.0, 0.0), (200.0, 0.0), (300.0, 0.0)]
    t = table(pts, 50.0, events=[Event(1, 2, "G4", {"S": 1.0}), Event(2, 4, "G4", {"S": 2.0})])
    t.moves["line"] = [1, 3, 5]
    t.moves["layer"] = [0, 0, 1]
    t.moves["feature"] = [0, 1, 1]
    t.features = ["Perimeter", "Infill"]
    tl = plan_marlin(t, FREE, stop_after_lines=[0, 2, 3])
    # Each move is a full 2.05 s trapezoid (stops or not, it starts and ends at rest).
    assert tl.stop_times_s == pytest.approx({0: 0.0, 2: 2.05 + 1.0, 3: 2 * 2.05 + 1.0})
    assert tl.time_at_line(4) == pytest.approx(2 * 2.05 + 1.0)
    assert tl.total_time_s == pytest.approx(3 * 2.05 + 3.0)
    np.testing.assert_array_equal(tl.lines, [1, 3, 5])
    assert time_by_layer(tl, t) == pytest.approx({0: 2 * 2.05 + 1.0, 1: 2.05 + 2.0})
    by_feature = time_by_feature(tl, t)
    assert by_feature["Perimeter"] == pytest.approx(2.05)
    assert by_feature["Infill"] == pytest.approx(2 * 2.05)
    assert sum(by_feature.values()) == pytest.approx(tl.total_time_s)


def test_reverse_pass_brakes_before_a_short_final_move() -> None:
    tl = plan_marlin(table([(100.0, 0.0), (100.2, 0.0)], 50.0), FREE)
    # The 0.2 mm block must stop at its end: entry ≤ sqrt(2·a·0.2).
    assert tl.phases[0]["end_v"] == pytest.approx(math.sqrt(2 * 1000.0 * 0.2), rel=1e-5)


def test_forward_pass_limits_a_short_first_move() -> None:
    tl = plan_marlin(table([(0.2, 0.0), (100.0, 0.0)], 50.0), FREE)
    assert tl.phases[0]["end_v"] == pytest.approx(math.sqrt(2 * 1000.0 * 0.2), rel=1e-5)


def test_look_ahead_window_limits_speed_on_tiny_segments() -> None:
    # 200 collinear 0.05 mm segments at 300 mm/s: with 16 blocks the exit of the running
    # block is planned over 14 queued blocks that must be able to stop:
    # v² = v_min² + 2·a·14·0.05.
    n = 200
    pts = [(0.05 * (i + 1), 0.0) for i in range(n)]
    s = replace(FREE, block_buffer_size=16)
    tl = plan_marlin(table(pts, 300.0), s)
    assert tl.phases[n // 2]["start_v"] == pytest.approx(math.sqrt(2 * 1000 * 14 * 0.05),
                                                       rel=1e-5)
    unlimited = plan_marlin(table(pts, 300.0), replace(s, block_buffer_size=None))
    assert unlimited.phases[n // 2]["start_v"] == pytest.approx(
        math.sqrt(2 * 1000 * 0.05 * n / 2), rel=1e-5)


def test_lin_advance_caps_acceleration() -> None:
    s = replace(FREE, lin_advance=True, jerk_mm_s=(10.0, 10.0, 10.0, 5.0))
    ev = [Event(0, 1, "M900", {"K": 0.2})]
    # e/D = 0.4/10 = 0.04 → a ≤ 5 / (0.2 · 0.04) = 625 < 1000.
    pts = [(10.0, 0.0), (20.0, 0.0), (20.0, 0.0)]
    tl = plan_marlin(table(pts, 50.0, de=[0.4, 35.0, 1.0], events=ev), s)
    assert tl.phases[0]["accel"] == pytest.approx(625.0, rel=RTOL)
    assert tl.phases[1]["accel"] == pytest.approx(1000.0, rel=RTOL)   # e/D = 3.5 > 3
    without = plan_marlin(table(pts, 50.0, de=[0.4, 35.0, 1.0], events=ev), FREE)
    assert without.phases[0]["accel"] == pytest.approx(1000.0, rel=RTOL)
    assert any("LIN_ADVANCE" in w for w in without.warnings)


def test_lin_advance_k_change_drains_the_planner() -> None:
    s = replace(FREE, lin_advance=True)
    ev = [Event(1, 2, "M900", {"K": 0.05})]
    tl = plan_marlin(table([(100.0, 0.0), (200.0, 0.0)], 50.0, events=ev), s)
    assert tl.phases[0]["end_v"] == pytest.approx(1e-6, rel=1e-3)


def test_junction_deviation_lin_advance_uses_jd_e_jerk() -> None:
    # HAS_LINEAR_E_JERK: E-jerk = sqrt(sqrt(0.5)·JD·amax_E / (1 - sqrt(0.5))).
    amax_e = 4000.0
    s = replace(FREE, lin_advance=True, linear_advance_k=0.1, junction_deviation_mm=0.02,
                max_acceleration_mm_s2=(BIG, BIG, BIG, amax_e), print_accel_mm_s2=1e4)
    e_jerk = math.sqrt(math.sqrt(0.5) * 0.02 * amax_e / (1 - math.sqrt(0.5)))
    tl = plan_marlin(table([(10.0, 0.0)], 50.0, de=[0.5]), s)
    assert tl.phases[0]["accel"] == pytest.approx(e_jerk / (0.1 * 0.05), rel=RTOL)


def test_slowdown_option_lengthens_short_segments() -> None:
    s = replace(FREE, slowdown_moves_queued=4, min_segment_time_s=0.02,
                print_accel_mm_s2=1e7, travel_accel_mm_s2=1e7)
    tl = plan_marlin(table([(0.1, 0.0)], 100.0), s)
    # t = 1 ms < 20 ms → t + 2·(20 - 1)/4 ms = 10.5 ms → 0.1 mm / 10.5 ms.
    assert tl.phases[0]["cruise_v"] == pytest.approx(0.1 / 0.0105, rel=1e-5)


def test_zero_length_moves_take_no_time_and_keep_junctions() -> None:
    a = plan_marlin(table([(100.0, 0.0), (100.0, 100.0)], 100.0), FREE)
    b = plan_marlin(table([(100.0, 0.0), (100.0, 0.0), (100.0, 100.0)], 100.0), FREE)
    assert b.total_time_s == pytest.approx(a.total_time_s, rel=1e-12)
    assert b.phases[1]["accel_t"] + b.phases[1]["cruise_t"] + b.phases[1]["decel_t"] == 0.0


def test_bad_feed_and_bad_settings_commands_name_the_line() -> None:
    with pytest.raises(GcodeError, match=r"t\.gcode:1.*feed rate"):
        plan_marlin(table([(10.0, 0.0)], 0.0), FREE)
    with pytest.raises(GcodeError, match=r"t\.gcode:7 \[M204 P\].*stall"):
        plan_marlin(table([(10.0, 0.0)], 10.0, events=[Event(0, 7, "M204", {"P": 0.0})]),
                    FREE)
    with pytest.raises(GcodeError, match="M205 X"):
        FREE.updated_from_event(Event(0, 3, "M205", {"X": -1.0}))


def test_settings_events_and_ignored_parameters() -> None:
    s = FREE.updated_from_events([
        Event(0, 1, "M201", {"X": 100.0, "E": 900.0}), Event(0, 2, "M203", {"Z": 7.0}),
        Event(0, 3, "M205", {"B": 5000.0, "S": 1.0, "J": 0.1}),
        Event(0, 4, "M106", {"S": 255.0})])
    assert s.max_acceleration_mm_s2 == (100.0, BIG, BIG, 900.0)
    assert s.max_feedrate_mm_s[2] == 7.0
    assert s.min_segment_time_s == pytest.approx(0.005)
    assert s.min_feedrate_mm_s == 1.0
    assert s.junction_deviation_mm is None          # classic-jerk build ignores J
    jd = replace(FREE, junction_deviation_mm=0.02).updated_from_event(
        Event(0, 1, "M205", {"J": 0.08, "X": 3.0}))
    assert jd.junction_deviation_mm == 0.08 and jd.jerk_mm_s == FREE.jerk_mm_s
    assert FREE.updated_from_event(Event(0, 1, "M106", {})) is FREE


def test_settings_validation() -> None:
    with pytest.raises(ProfileError, match="print_accel_mm_s2"):
        MarlinSettings(print_accel_mm_s2=0.0)
    with pytest.raises(ProfileError, match="block_buffer_size"):
        MarlinSettings(block_buffer_size=2)
    with pytest.raises(ProfileError, match="max_feedrate_mm_s"):
        MarlinSettings(max_feedrate_mm_s=(1.0, 2.0, 3.0))  # type: ignore[arg-type]


def test_settings_from_prusaslicer_and_orca_config_keys() -> None:
    prusa = {"machine_max_acceleration_x": "4000,2500", "machine_max_acceleration_y": "4000",
             "machine_max_acceleration_z": "200", "machine_max_acceleration_e": "2500",
             "machine_max_feedrate_x": "300,160", "machine_max_feedrate_e": "100",
             "machine_max_jerk_x": "8", "machine_max_jerk_e": "10",
             "machine_max_acceleration_extruding": "4000,2500",
             "machine_max_acceleration_retracting": "1200",
             "machine_max_acceleration_travel": "0", "machine_min_travel_rate": "5",
             "machine_limits_usage": "emit_to_gcode"}
    s = marlin_settings_from_slicer_config({"slicer_config": prusa})
    assert s is not None
    assert s.max_acceleration_mm_s2 == (4000.0, 4000.0, 200.0, 2500.0)
    assert s.max_feedrate_mm_s[0] == 300.0 and s.max_feedrate_mm_s[3] == 100.0
    assert s.jerk_mm_s[0] == 8.0 and s.jerk_mm_s[3] == 10.0
    assert (s.print_accel_mm_s2, s.retract_accel_mm_s2, s.travel_accel_mm_s2) == (
        4000.0, 1200.0, 4000.0)       # travel 0 → the extruding value
    assert s.min_travel_feedrate_mm_s == 5.0
    assert s.classic_jerk
    orca = {"machine_max_speed_x": "500,200", "machine_max_acceleration_travel": "9000",
            "machine_max_junction_deviation": "0.013,0.013"}
    o = marlin_settings_from_slicer_config(orca)
    assert o is not None and o.max_feedrate_mm_s[0] == 500.0
    assert o.travel_accel_mm_s2 == 9000.0 and o.junction_deviation_mm == 0.013
    assert marlin_settings_from_slicer_config({"slicer_config": {"layer_height": "0.2"}}) is None
    assert marlin_settings_from_slicer_config(
        {**prusa, "machine_limits_usage": "ignore"}) is None
    with pytest.raises(ProfileError, match="machine_max_jerk_x"):
        marlin_settings_from_slicer_config({"machine_max_jerk_x": "fast"})
    with pytest.raises(ProfileError, match="machine_max_feedrate_x"):
        marlin_settings_from_slicer_config({"machine_max_feedrate_x": "0"})
