"""Marlin planner kernel: the closed-form look-ahead window against a simulation of the
block buffer, and physical invariants on random paths."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from flowtwin.gcode.moves import MOVE_DTYPE, Event, MoveTable
from flowtwin.planner.marlin import JerkVariant, MarlinSettings, plan_marlin

BIG = 1e9
V_MIN = 0.05


def buffer_simulation(length: np.ndarray, accel: np.ndarray, junction_v2: np.ndarray,
                      buffer_blocks: int | None) -> np.ndarray:
    """Entry speeds² as Marlin's ring buffer fixes them, by brute force.

    When block ``i`` starts executing, the buffer holds blocks ``i .. i + B - 2``; the
    exit of ``i`` is then fixed: the queued blocks are reverse-planned from a stop at the
    end of the last one, and block ``i`` can only accelerate from its (already fixed)
    entry. ``junction_v2[k]`` is the limit at the entry of block ``k``.
    """
    m = len(length)
    v2_min = V_MIN**2
    entry = np.empty(m + 1)
    entry[0] = min(junction_v2[0], v2_min)
    for i in range(m):
        last = m - 1 if buffer_blocks is None else min(i + buffer_blocks - 2, m - 1)
        nxt = v2_min
        for k in range(last, i, -1):
            nxt = min(junction_v2[k], nxt + 2 * accel[k] * length[k])
        if i == m - 1:
            nxt = v2_min
        entry[i + 1] = min(nxt, entry[i] + 2 * accel[i] * length[i])
    return entry


@pytest.mark.parametrize("buffer_blocks", [3, 4, 8, 16, None])
def test_look_ahead_window_matches_buffer_simulation(buffer_blocks: int | None) -> None:
    # Collinear moves along +X with random lengths, speeds, M204 P changes and M400
    # stops: with the reworked jerk rule a collinear junction is min(v_prev, v_next).
    rng = np.random.default_rng(7)
    m = 300
    length = rng.uniform(0.02, 3.0, m)
    feed = rng.uniform(5.0, 150.0, m)
    accel = rng.choice([300.0, 800.0, 2000.0], m)
    moves = np.zeros(m, MOVE_DTYPE)
    moves["x"] = np.cumsum(length)
    moves["feed_mm_s"] = feed
    moves["flow"] = 1.0
    moves["de"] = 0.03 * length             # printing moves (M204 P); same e/D, so the
                                            # E axis adds no jerk at the junctions
    moves["line"] = np.arange(1, m + 1)
    events = [Event(k, k, "M204", {"P": float(accel[k])}) for k in range(m)]
    stops = rng.choice(np.arange(1, m), 12, replace=False)
    events += [Event(int(k), int(k), "M400", {}) for k in stops]
    events.sort(key=lambda e: e.move_index)
    settings = MarlinSettings(
        max_feedrate_mm_s=(BIG,) * 4, max_acceleration_mm_s2=(BIG,) * 4,
        junction_deviation_mm=None, jerk_variant=JerkVariant.REWORKED,
        jerk_mm_s=(5.0, 5.0, 5.0, 5.0), minimum_planner_speed_mm_s=V_MIN,
        block_buffer_size=buffer_blocks)
    table = MoveTable(moves=moves, events=events, start_xyze=np.zeros(4))
    tl = plan_marlin(table, settings)

    junction_v2 = np.empty(m)
    junction_v2[0] = V_MIN**2
    junction_v2[1:] = np.minimum(feed[1:], feed[:-1]) ** 2
    junction_v2[stops] = V_MIN**2
    entry = buffer_simulation(length, accel, np.maximum(junction_v2, V_MIN**2),
                              buffer_blocks)
    expected_in = np.sqrt(np.minimum(entry[:-1], feed**2))
    expected_out = np.sqrt(np.minimum(entry[1:], feed**2))
    # float32 speeds in the timeline
    np.testing.assert_allclose(tl.phases["start_v"], expected_in, rtol=2e-6)
    np.testing.assert_allclose(tl.phases["end_v"], expected_out, rtol=2e-6)


def random_walk(seed: int, n: int = 400) -> MoveTable:
    """A printing-like path: random turns, lengths 0.05–20 mm, some travels, Z hops."""
    rng = np.random.default_rng(seed)
    heading = np.cumsum(rng.normal(0.0, 1.2, n))
    step = rng.uniform(0.05, 20.0, n)
    moves = np.zeros(n, MOVE_DTYPE)
    moves["x"] = np.cumsum(step * np.cos(heading))
    moves["y"] = np.cumsum(step * np.sin(heading))
    moves["z"] = np.repeat(0.2 * np.arange(n // 40 + 1), 40)[:n]
    printing = rng.random(n) < 0.8
    moves["de"] = np.where(printing, step * 0.035, 0.0)
    moves["feed_mm_s"] = rng.uniform(10.0, 250.0, n)
    moves["flow"] = 1.0
    moves["line"] = np.arange(1, n + 1)
    return MoveTable(moves=moves, events=[], start_xyze=np.zeros(4))


MODES = {
    "legacy": MarlinSettings(junction_deviation_mm=None),
    "reworked": MarlinSettings(junction_deviation_mm=None, jerk_variant=JerkVariant.REWORKED),
    "jd": MarlinSettings(junction_deviation_mm=0.02),
}


def directions(table: MoveTable) -> tuple[np.ndarray, np.ndarray]:
    """Axis deltas ``(n, 4)`` and path lengths ``(n,)`` (XYZ, or |E| for E-only)."""
    m = table.moves
    xyz = np.column_stack([m["x"], m["y"], m["z"]])
    d = np.empty((len(m), 4))
    d[:, :3] = np.diff(np.vstack([table.start_xyze[:3], xyz]), axis=0)
    d[:, 3] = m["de"] * m["flow"]
    length = np.linalg.norm(d[:, :3], axis=1)
    return d, np.where(length > 0, length, np.abs(d[:, 3]))


@pytest.mark.parametrize("mode", sorted(MODES))
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_paths_respect_kinematics_and_limits(mode: str, seed: int) -> None:
    settings = replace(MODES[mode], max_feedrate_mm_s=(200.0, 150.0, 12.0, 60.0),
                       max_acceleration_mm_s2=(2500.0, 1500.0, 300.0, 5000.0),
                       print_accel_mm_s2=1200.0, travel_accel_mm_s2=3000.0)
    table = random_walk(seed)
    tl = plan_marlin(table, settings)
    p = tl.phases
    d, length = directions(table)
    vi, vc, vo = (p[k].astype(np.float64) for k in ("start_v", "cruise_v", "end_v"))
    a = p["accel"].astype(np.float64)
    # Distance covered by the three phases is the move length (float32 speeds: 1e-5).
    dist = 0.5 * (vi + vc) * p["accel_t"] + vc * p["cruise_t"] + 0.5 * (vc + vo) * p["decel_t"]
    np.testing.assert_allclose(dist, length, rtol=1e-5)
    # Phases are consistent with the acceleration.
    np.testing.assert_allclose(vc - vi, a * p["accel_t"], rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(vc - vo, a * p["decel_t"], rtol=1e-5, atol=1e-4)
    # Requested feed, per-axis feed rates and accelerations are respected.
    tol = 1 + 1e-5
    assert np.all(vc <= table.moves["feed_mm_s"] * tol)
    axis_speed = vc[:, None] * np.abs(d) / length[:, None]
    assert np.all(axis_speed <= np.array(settings.max_feedrate_mm_s) * tol)
    axis_accel = a[:, None] * np.abs(d) / length[:, None]
    assert np.all(axis_accel <= np.array(settings.max_acceleration_mm_s2) * tol)
    assert np.all(a <= np.where(table.moves["de"] != 0, 1200.0, 3000.0) * tol)
    # Time line adds up.
    t = p["accel_t"] + p["cruise_t"] + p["decel_t"]
    np.testing.assert_allclose(p["t_start"][1:], p["t_start"][:-1] + t[:-1], rtol=1e-12)
    assert tl.total_time_s == pytest.approx(p["t_start"][-1] + t[-1], rel=1e-12)
    unit = d / length[:, None]
    jump = np.abs(vi[1:, None] * unit[1:] - vo[:-1, None] * unit[:-1])
    if mode == "reworked":
        # The rule this variant enforces: every axis changes speed by at most its jerk.
        np.testing.assert_allclose(vo[:-1], vi[1:], rtol=1e-6)
        assert np.all(jump <= np.array(settings.jerk_mm_s) * tol + 1e-4)
    if mode == "jd":
        np.testing.assert_allclose(vo[:-1], vi[1:], rtol=1e-6)
        # Marlin's JD unit vectors include E for moves that extrude.
        with_e = np.where(d[:, 3:] != 0, d, np.column_stack([d[:, :3], np.zeros(len(d))]))
        u = with_e / np.linalg.norm(with_e, axis=1)[:, None]
        cos_turn = np.clip(np.sum(u[1:] * u[:-1], axis=1), -1, 1)
        sin_half = np.sqrt(0.5 * (1 + cos_turn))
        with np.errstate(divide="ignore"):
            bound = a[1:] * 0.02 * sin_half / (1 - sin_half)
        assert np.all(vi[1:] ** 2 <= np.maximum(bound, V_MIN**2) * tol + 1e-6)


def test_legacy_reversal_allows_jerk_per_axis_magnitude() -> None:
    # A full reversal along X at 100 mm/s: the legacy rule counts max(|v_exit|, |v_entry|)
    # as the jerk, so the junction is the jerk itself (10 mm/s), not half of it.
    settings = MarlinSettings(junction_deviation_mm=None, jerk_mm_s=(10.0, 10.0, 0.3, 5.0),
                              max_feedrate_mm_s=(BIG,) * 4)
    moves = np.zeros(2, MOVE_DTYPE)
    moves["x"] = [50.0, 0.0]
    moves["feed_mm_s"] = 100.0
    moves["flow"] = 1.0
    tl = plan_marlin(MoveTable(moves=moves, events=[], start_xyze=np.zeros(4)), settings)
    assert tl.phases[0]["end_v"] == pytest.approx(10.0, rel=1e-6)
    reworked = plan_marlin(MoveTable(moves=moves, events=[], start_xyze=np.zeros(4)),
                           replace(settings, jerk_variant=JerkVariant.REWORKED))
    assert reworked.phases[0]["end_v"] == pytest.approx(5.0, rel=1e-6)
    assert math.isclose(float(reworked.phases[1]["start_v"]), 5.0, rel_tol=1e-6)
