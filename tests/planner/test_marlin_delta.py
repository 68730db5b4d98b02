"""Marlin on a delta: Marlin's segmentation rule, tower geometry and tower limits, analytic.

Known answers: the segment count ``max(1, trunc(S·L/F))`` of Marlin's
``line_to_destination_kinematic``; carriage heights from the rod geometry
(``z + sqrt(rod² − d²)``, ``d`` the horizontal distance to the tower); a block's nominal
speed ``F·min(1, vmax/|F·Δh_i/L|)`` over the towers; junction deviation on the
cartesian direction (straight segments keep their speed).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from flowtwin.errors import GcodeError, ProfileError
from flowtwin.gcode.moves import MOVE_DTYPE, Event, MoveTable
from flowtwin.planner.marlin import MarlinSettings, plan_marlin
from flowtwin.planner.marlin_delta import (
    SEGMENTED_KEY,
    MarlinDelta,
    segment_moves,
    tower_distances,
)
from flowtwin.planner.plan_file import plan_gcode
from flowtwin.profiles import load_builtin, profile_from_dict

KOSSEL = MarlinDelta(radius_mm=97.0, diagonal_rod_mm=218.0, segments_per_second=80.0,
                     printable_radius_mm=90.0, height_mm=320.0)
BIG = 1e9


def moves(points: list[tuple[float, float, float]], feed: float | list[float] = 50.0,
          de: list[float] | None = None, events: list[Event] | None = None,
          start: tuple[float, float, float] = (0.0, 0.0, 10.0)) -> MoveTable:
    m = np.zeros(len(points), MOVE_DTYPE)
    for i, col in enumerate("xyz"):
        m[col] = [p[i] for p in points]
    m["feed_mm_s"] = feed
    m["flow"] = 1.0
    m["line"] = np.arange(1, len(points) + 1)
    if de is not None:
        m["de"] = de
        m["e"] = np.cumsum(de)
    return MoveTable(moves=m, events=events or [], start_xyze=np.array([*start, 0.0]),
                     source="d.gcode")


def settings(delta: MarlinDelta = KOSSEL, **kw: object) -> MarlinSettings:
    base: dict[str, object] = dict(
        max_feedrate_mm_s=(BIG,) * 4, max_acceleration_mm_s2=(BIG,) * 4,
        print_accel_mm_s2=1000.0, retract_accel_mm_s2=1000.0, travel_accel_mm_s2=1000.0,
        junction_deviation_mm=0.013, minimum_planner_speed_mm_s=1e-6,
        block_buffer_size=None, delta=delta)
    base.update(kw)
    return MarlinSettings(**base)  # type: ignore[arg-type]


@pytest.mark.parametrize(("length", "feed", "count"), [
    (10.0, 10.0, 80),        # 1 s at 80 segments/s
    (10.0, 100.0, 8),
    (1.0, 100.0, 1),         # 0.8 -> at least one
    (12.3, 40.0, 24),        # 24.6 truncated
])
def test_segment_count_follows_marlins_rule(length, feed, count):
    seg = segment_moves(moves([(length, 0.0, 10.0)], feed=feed, de=[2.0]), KOSSEL)
    assert len(seg) == count == max(1, math.trunc(80.0 * length / feed))
    x = seg.moves["x"]
    assert x[-1] == length and np.allclose(np.diff(np.concatenate(([0.0], x))),
                                           length / count)
    assert seg.moves["de"].sum() == pytest.approx(2.0, abs=1e-12)
    assert seg.moves["e"][-1] == 2.0
    assert seg.metadata[SEGMENTED_KEY] == 80.0


def test_moves_without_xy_are_not_cut():
    seg = segment_moves(moves([(0.0, 0.0, 30.0), (0.0, 0.0, 30.0)], feed=5.0,
                              de=[0.0, 5.0]), KOSSEL)
    assert len(seg) == 2                           # Z only, E only: one block each


def test_events_point_at_the_first_segment_of_their_move():
    t = moves([(10.0, 0.0, 10.0), (20.0, 0.0, 10.0)], feed=10.0,
              events=[Event(1, 2, "M400"), Event(2, 3, "G4", {"P": 100.0})])
    seg = segment_moves(t, KOSSEL)
    assert [e.move_index for e in seg.events] == [80, 160]
    assert len(seg) == 160


def test_tower_distances_from_the_rod_geometry():
    r, rod = KOSSEL.radius_mm, KOSSEL.diagonal_rod_mm
    # pure Z: every carriage moves as far as the effector
    assert np.allclose(tower_distances(moves([(0.0, 0.0, 40.0)]), KOSSEL), 30.0)
    # from the centre towards tower C (90°) by y: d_C = r - y, d_A = d_B = |(r cos30, y + r/2)|
    y = 40.0
    got = tower_distances(moves([(0.0, y, 10.0)]), KOSSEL)[0]
    h0 = math.sqrt(rod**2 - r**2)
    h_c = math.sqrt(rod**2 - (r - y) ** 2) - h0
    h_ab = math.sqrt(rod**2 - (r * math.cos(math.radians(30))) ** 2 - (y + r / 2) ** 2) - h0
    assert got == pytest.approx([h_ab, h_ab, h_c], rel=1e-12)


def test_block_speed_is_limited_by_the_towers():
    # one block (Z-only: not cut) at 200 mm/s: every carriage moves dz -> 100 mm/s
    t = segment_moves(moves([(0.0, 0.0, 60.0)], feed=200.0), KOSSEL)
    s = settings(max_feedrate_mm_s=(100.0, 100.0, 100.0, BIG))
    assert plan_marlin(t, s).phases["cruise_v"][0] == pytest.approx(100.0, rel=1e-6)
    # an XY segment near the edge: nominal = F·min(1, vmax/max_i |F·Δh_i/L|)
    # (moving away from tower C near the far edge: its carriage runs ~1.4x the head)
    t = moves([(0.0, -70.0, 10.0), (0.0, -85.0, 10.0)], feed=[300.0, 300.0])
    slow = replace(KOSSEL, segments_per_second=1.0)
    t = segment_moves(t, slow)
    assert len(t) == 2
    dh = tower_distances(t, KOSSEL)[1]
    length = 15.0
    vmax = 150.0
    want = 300.0 * min(1.0, vmax / np.max(np.abs(dh) * 300.0 / length))
    assert want < 299.0                            # the towers do bind here
    got = plan_marlin(t, settings(slow, max_feedrate_mm_s=(vmax, vmax, vmax, BIG),
                                  print_accel_mm_s2=1e7, travel_accel_mm_s2=1e7))
    assert got.phases["cruise_v"][1] == pytest.approx(want, rel=1e-6)


def test_straight_segments_keep_their_speed_with_junction_deviation():
    """JD works on the cartesian direction: a straight move cut into 120 segments takes the
    time of one trapezoid (the towers' speeds change from segment to segment)."""
    t = segment_moves(moves([(0.0, 60.0, 10.0)], feed=40.0), KOSSEL)
    assert len(t) == 120
    tl = plan_marlin(t, settings())
    v, a, length = 40.0, 1000.0, 60.0
    want = length / v + v / a
    assert tl.total_time_s == pytest.approx(want, rel=1e-6)


def test_classic_jerk_sees_the_towers():
    """With classic jerk on the towers the same straight move slows at segment joints
    where a carriage's speed changes by more than the jerk."""
    t = segment_moves(moves([(0.0, -85.0, 10.0), (0.0, 85.0, 10.0)], feed=150.0), KOSSEL)
    jd = plan_marlin(t, settings()).total_time_s
    cj = plan_marlin(t, settings(junction_deviation_mm=None,
                                 jerk_mm_s=(0.05, 0.05, 0.05, 5.0))).total_time_s
    assert cj > jd * 1.05


def test_unsegmented_table_and_far_moves_are_refused():
    t = moves([(10.0, 0.0, 10.0)])
    with pytest.raises(GcodeError, match="segment_moves"):
        plan_marlin(t, settings())
    with pytest.raises(GcodeError, match="printable radius") as info:
        segment_moves(moves([(10.0, 0.0, 10.0), (80.0, 60.0, 10.0)]), KOSSEL)
    assert info.value.line == 2
    with pytest.raises(ProfileError, match="reach"):
        MarlinDelta(radius_mm=97.0, diagonal_rod_mm=150.0, segments_per_second=80.0,
                    printable_radius_mm=90.0, height_mm=320.0)


def test_builtin_kossel_profile_plans_a_generated_print(tmp_path):
    from flowtwin.gcode.generator import PrintSpec, write_print

    profile = load_builtin("anycubic-kossel")
    assert profile.marlin is not None and profile.marlin.delta is not None
    assert profile.marlin.delta.segments_per_second == 80.0
    assert profile.home_position_mm.z == profile.marlin.delta.height_mm == 320.0
    path = tmp_path / "p.gcode"
    write_print(path, PrintSpec(center_xy_mm=(0.0, 0.0), layers=3))
    result = plan_gcode(path, printer="anycubic-kossel")
    assert result.table.metadata[SEGMENTED_KEY] == 80.0
    assert len(result.timeline.phases) == len(result.table) > 2000
    summary = result.summary()
    assert summary.total_time_s > 30.0
    # the same file on a cartesian with the same limits: the towers make it differ
    cart = profile.model_dump(mode="json")
    cart["marlin"].pop("delta")
    cart["name"] = "kossel-as-cartesian"
    other = plan_gcode(path, printer=profile_from_dict(cart, "printer"))
    assert other.summary().total_time_s != pytest.approx(summary.total_time_s, rel=1e-3)
