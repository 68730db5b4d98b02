"""Builders of small planned prints for the dynamics tests.

The real reader and planner are other packages; these tests need exactly known
trapezoids, so they build the move table and the timeline directly.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pytest

from flowtwin.dynamics.feed import CommandedFeed
from flowtwin.gcode.moves import MOVE_DTYPE, Event, MoveKind, MoveTable
from flowtwin.planner.timeline import PHASE_DTYPE, Timeline


@dataclass(frozen=True)
class Mv:
    """One test move: absolute end X/Y/Z, relative E, requested speed, end speed."""

    x: float
    y: float
    z: float = 0.0
    de: float = 0.0
    v: float = 50.0
    v_end: float = 0.0
    flow: float = 1.0
    dwell_after: float = 0.0


def trapezoid(length: float, v0: float, vc: float, v1: float,
              accel: float) -> tuple[float, float, float, float]:
    """Phase times and the reached cruise speed of a trapezoid (triangle if short)."""
    da = (vc * vc - v0 * v0) / (2.0 * accel)
    dd = (vc * vc - v1 * v1) / (2.0 * accel)
    if da + dd > length:
        vc = math.sqrt((2.0 * accel * length + v0 * v0 + v1 * v1) / 2.0)
        da = (vc * vc - v0 * v0) / (2.0 * accel)
        dd = (vc * vc - v1 * v1) / (2.0 * accel)
    ta = (vc - v0) / accel
    td = (vc - v1) / accel
    tc = (length - da - dd) / vc if vc > 0 else 0.0
    return ta, max(tc, 0.0), td, vc


def build(moves: Sequence[Mv], *, accel: float = 1000.0, events: Sequence[Event] = (),
          start: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
          t0: float = 0.0) -> tuple[MoveTable, Timeline]:
    """Move table and timeline of ``moves`` (start speed of a move = end speed of the last)."""
    n = len(moves)
    mv = np.zeros(n, dtype=MOVE_DTYPE)
    ph = np.zeros(n, dtype=PHASE_DTYPE)
    px, py, pz, pe = start
    v_prev = 0.0
    t = t0
    for i, m in enumerate(moves):
        dx, dy, dz = m.x - px, m.y - py, m.z - pz
        path = math.sqrt(dx * dx + dy * dy + dz * dz)
        kind = 0
        if m.de > 0:
            kind |= MoveKind.EXTRUDE
        elif m.de < 0:
            kind |= MoveKind.RETRACT
        else:
            kind |= MoveKind.TRAVEL
        if dx or dy:
            kind |= MoveKind.XY
        if dz:
            kind |= MoveKind.Z
        length = path if path > 0 else abs(m.de)
        ta, tc, td, vc = trapezoid(length, v_prev, m.v, m.v_end, accel)
        pe += m.de
        row = mv[i]
        row["line"] = i + 1
        row["x"], row["y"], row["z"], row["e"], row["de"] = m.x, m.y, m.z, pe, m.de
        row["feed_mm_s"], row["flow"], row["tool"], row["kind"] = m.v, m.flow, 0, int(kind)
        row["feature"], row["layer"] = -1, 0
        prow = ph[i]
        prow["t_start"], prow["start_v"], prow["cruise_v"], prow["end_v"] = t, v_prev, vc, m.v_end
        prow["accel"], prow["accel_t"], prow["cruise_t"], prow["decel_t"] = accel, ta, tc, td
        t += ta + tc + td + m.dwell_after
        v_prev = m.v_end
        px, py, pz = m.x, m.y, m.z
    table = MoveTable(moves=mv, events=list(events), start_xyze=np.array(start, dtype=float),
                      source="test.gcode", n_lines=n)
    return table, Timeline(phases=ph, total_time_s=t - t0)


@pytest.fixture
def make_print() -> Callable[..., tuple[MoveTable, Timeline]]:
    """The :func:`build` function."""
    return build


@pytest.fixture(name="Move")
def move_class() -> type[Mv]:
    """The :class:`Mv` test-move record."""
    return Mv


@pytest.fixture
def rng() -> np.random.Generator:
    """Seeded generator (every test gets the same stream)."""
    return np.random.default_rng(20240601)


def feed_of(dt: Sequence[float], coef: Sequence[Sequence[float]], *, t_begin: float = 0.0,
            gap: Sequence[bool] | None = None) -> CommandedFeed:
    """A commanded feed with one move per segment (or stop where ``gap`` is True)."""
    dt_a = np.asarray(dt, dtype=float)
    c = np.zeros((len(dt_a), 4))
    for i, row in enumerate(coef):
        c[i, : len(row)] = row
    seg = dt_a * (c[:, 0] + dt_a * (c[:, 1] / 2 + dt_a * (c[:, 2] / 3 + dt_a * c[:, 3] / 4)))
    e0 = np.concatenate(([0.0], np.cumsum(seg)[:-1]))
    t0 = t_begin + np.concatenate(([0.0], np.cumsum(dt_a)[:-1]))
    g = np.zeros(len(dt_a), dtype=bool) if gap is None else np.asarray(gap, dtype=bool)
    move = np.cumsum(~g) - 1
    mt0 = t0[~g]
    mt1 = (t0 + dt_a)[~g]
    return CommandedFeed(t0_s=t0, dt_s=dt_a, coef=c, e0_mm=e0, move=move.astype(np.int64),
                         gap=g, phase=np.zeros(len(dt_a), dtype=np.int8), move_t0_s=mt0,
                         move_t1_s=mt1, move_de_mm=seg[~g])


@pytest.fixture
def make_feed() -> Callable[..., CommandedFeed]:
    """The :func:`feed_of` function."""
    return feed_of
