"""The commanded feed built from a move table and its timeline."""

from __future__ import annotations

import numpy as np
import pytest

from flowtwin.dynamics import nominal_feed
from flowtwin.dynamics.feed import PHASE_GAP
from flowtwin.errors import DataError


def test_feed_integrates_to_de_times_flow(make_print, Move):
    moves = [Move(10, 0, de=0.5, v=60, v_end=20), Move(10, 8, de=0.4, v=40, flow=0.95),
             Move(10, 8, de=-0.8, v=35), Move(30, 8, v=150, dwell_after=0.25),
             Move(30, 8, de=0.8, v=35), Move(40, 8, 0.2, de=0.3, v=30)]
    mt, tl = make_print(moves, accel=1500)
    feed = nominal_feed(mt, tl, e_start_mm=5.0)
    seg = feed.segment_mm()
    per_move = np.bincount(feed.move[~feed.gap], weights=seg[~feed.gap], minlength=len(moves))
    expected = np.array([m.de * float(np.float32(m.flow)) for m in moves])  # flow is float32
    np.testing.assert_allclose(per_move, expected, rtol=0, atol=1e-12)
    assert feed.e_end_mm() == pytest.approx(5.0 + expected.sum(), abs=1e-12)
    # positions are continuous from segment to segment
    np.testing.assert_allclose(feed.e0_mm[1:], feed.e0_mm[:-1] + seg[:-1], atol=1e-12)
    # the dwell after the travel is a stop at rest
    stop = feed.gap & (feed.move == 3)
    assert feed.dt_s[stop].sum() == pytest.approx(0.25)
    assert np.all(feed.coef[stop] == 0.0)
    assert np.all(feed.phase[stop] == PHASE_GAP)


def test_extruder_follows_toolhead_speed(make_print, Move):
    # E speed = path speed · de·flow / L: at cruise 60 mm/s on 20 mm with 1 mm of filament
    mt, tl = make_print([Move(20, 0, de=1.0, v=60)], accel=1000)
    feed = nominal_feed(mt, tl)
    ph = tl.phases[0]
    t_mid = ph["t_start"] + ph["accel_t"] + 0.5 * ph["cruise_t"]
    assert feed.velocity_at(t_mid) == pytest.approx(60.0 / 20.0, rel=1e-6)
    t_acc = ph["t_start"] + 0.5 * ph["accel_t"]
    assert feed.velocity_at(t_acc) == pytest.approx(30.0 / 20.0, rel=1e-6)
    assert feed.velocity_at(-1.0) == 0.0
    assert feed.velocity_at(10.0) == 0.0


def test_extrude_only_move_has_its_own_trapezoid(make_print, Move):
    mt, tl = make_print([Move(0, 0, de=3.0, v=25)], accel=500)
    feed = nominal_feed(mt, tl)
    ph = tl.phases[0]
    t_mid = ph["t_start"] + ph["accel_t"] + 0.5 * ph["cruise_t"]
    assert feed.velocity_at(t_mid) == pytest.approx(25.0, rel=1e-6)
    assert feed.e_end_mm() == pytest.approx(3.0)


def test_tool_filter(make_print, Move):
    mt, tl = make_print([Move(10, 0, de=0.5), Move(20, 0, de=0.5)])
    mt.moves["tool"][1] = 1
    assert nominal_feed(mt, tl, tool=0).e_end_mm() == pytest.approx(0.5)
    assert nominal_feed(mt, tl, tool=1).e_end_mm() == pytest.approx(0.5)
    assert nominal_feed(mt, tl).e_end_mm() == pytest.approx(1.0)


def test_lead_and_tail(make_print, Move):
    mt, tl = make_print([Move(10, 0, de=0.5)])
    feed = nominal_feed(mt, tl, lead_s=0.1, tail_s=0.2)
    assert feed.t_begin_s == pytest.approx(-0.1)
    assert feed.t_end_s == pytest.approx(tl.end_time_s[-1] + 0.2)
    assert feed.move[0] == -1 and feed.gap[0]


def test_bad_timelines_raise(make_print, Move):
    mt, tl = make_print([Move(10, 0, de=0.5), Move(20, 0, de=0.5)])
    bad = tl.phases.copy()
    bad["t_start"][1] -= 0.01
    tl_bad = type(tl)(phases=bad)
    with pytest.raises(DataError, match="starts before the previous one ends"):
        nominal_feed(mt, tl_bad)
    frozen = tl.phases.copy()
    for f in ("accel_t", "cruise_t", "decel_t"):
        frozen[f][0] = 0.0
    with pytest.raises(DataError, match=r"test\.gcode:1"):
        nominal_feed(mt, type(tl)(phases=frozen))
    short = tl.phases[:1].copy()
    with pytest.raises(DataError, match="does not match"):
        nominal_feed(mt, type(tl)(phases=short))
