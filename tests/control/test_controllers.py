"""Controllers: known answers, closed-loop convergence, limits, rate limits, anti-windup."""

from __future__ import annotations

import math

import pytest

from flowtwin.control.loop.controllers import (
    FeedForwardController,
    GreeffController,
    Limits,
    PIController,
    limit_command,
    make_controller,
    window_mean,
)
from flowtwin.errors import ProfileError
from flowtwin.firmware import Channel

WIDE = Limits(50.0, 150.0, 1000.0)  # rate limit out of the way


def test_limit_command_clamps_and_rate_limits() -> None:
    lim = Limits(50.0, 150.0, 10.0)
    assert limit_command(100.0, 80.0, 0.5, lim) == 95.0     # 10 %/s × 0.5 s
    assert limit_command(100.0, 80.0, 5.0, lim) == 80.0
    assert limit_command(60.0, 10.0, 100.0, lim) == 50.0    # floor
    assert limit_command(140.0, 500.0, 100.0, lim) == 150.0  # ceiling
    with pytest.raises(ValueError, match="non-finite"):
        limit_command(100.0, math.nan, 1.0, lim)


@pytest.mark.parametrize("bad", [(101.0, 150.0, 1.0), (50.0, 99.0, 1.0), (50.0, 150.0, 0.0)])
def test_limits_validated(bad: tuple[float, float, float]) -> None:
    with pytest.raises(ProfileError):
        Limits(*bad)


def test_window_mean_drops_old_samples() -> None:
    kept, mean = window_mean(((0.0, 1.0), (4.0, 0.0), (6.0, 0.5)), 6.0, 5.0)
    assert kept == ((4.0, 0.0), (6.0, 0.5)) and mean == 0.25


def test_greeff_known_answer_step() -> None:
    # [003 §2.3]: thresholded slip averaged over the window, used as the multiplier.
    c = GreeffController(threshold=0.02, window_s=5.0, limits=WIDE)
    st = c.initial_state()
    outs = {}
    for t in range(0, 16):
        slip = 0.01 if t < 10 else 0.2   # 1 % is below the threshold: counts as 0
        st, pct = c.update(st, float(t), slip)
        outs[t] = pct
    assert outs[9] == 100.0
    # window (7, 12] holds t = 8, 9 (0) and 10, 11, 12 (0.2): mean 0.12 -> 88 %
    assert outs[12] == pytest.approx(88.0, abs=1e-12)
    assert outs[15] == pytest.approx(80.0, abs=1e-12)


def test_greeff_returns_to_100_when_slip_vanishes() -> None:
    c = GreeffController(limits=WIDE)
    st = c.initial_state()
    for t in range(10):
        st, _ = c.update(st, float(t), 0.15)
    for t in range(10, 20):
        st, pct = c.update(st, float(t), 0.0)
    assert pct == 100.0


def test_greeff_respects_rate_limit() -> None:
    c = GreeffController(window_s=0.1, limits=Limits(50, 150, 4.0))
    st, _pct0 = c.initial_state(), 100.0
    st, _pct0 = c.update(st, 0.0, 0.0)
    st, pct1 = c.update(st, 0.5, 0.3)     # wants 70 %, may move 2 %
    assert pct1 == pytest.approx(98.0)


def test_feedforward_cancels_slip() -> None:
    c = FeedForwardController(limits=WIDE)
    st = c.initial_state()
    for t in range(10):
        st, pct = c.update(st, float(t), 0.1)
    assert pct == pytest.approx(100.0 / 0.9, rel=1e-12)
    # delivered fraction (1 - s) * m = 1
    assert (1 - 0.1) * pct / 100.0 == pytest.approx(1.0)
    with pytest.raises(ProfileError, match="flow multiplier only"):
        FeedForwardController(channel=Channel.SPEED)


def _run_speed_plant(c: PIController, s_at_100: float, steps: int, dt: float = 0.5,
                     st=None, t0: float = 0.0):
    """Plant: slip proportional to the speed multiplier (s = s_at_100 · u/100)."""
    st = st or c.initial_state()
    pct = st.pct
    for k in range(steps):
        slip = s_at_100 * pct / 100.0
        st, pct = c.update(st, t0 + k * dt, slip)
    return st, pct


def test_pi_speed_converges_to_setpoint() -> None:
    c = PIController(kp=2.0, ki=2.0, setpoint=0.024, limits=WIDE)
    _st, pct = _run_speed_plant(c, 0.03, 400)
    # equilibrium: 0.03 · u/100 = 0.024 -> u = 80 %
    assert pct == pytest.approx(80.0, abs=0.05)


def test_pi_flow_converges_to_feedforward_value() -> None:
    c = PIController(kp=0.5, ki=1.0, channel=Channel.FLOW, limits=WIDE)
    st = c.initial_state()
    for k in range(400):
        st, pct = c.update(st, 0.5 * k, 0.1)
    assert pct == pytest.approx(100.0 / 0.9, abs=0.05)
    assert st.integral_pct == pytest.approx(100.0 / 0.9 - 100.0, abs=0.05)


def _windup_recovery(anti_windup: bool) -> list[float]:
    lim = Limits(50.0, 150.0, 1000.0)
    c = PIController(kp=0.5, ki=1.0, setpoint=0.02, limits=lim, anti_windup=anti_windup)
    # 100 s of slip the loop cannot remove (wants < 50 %): output saturates at 50 %.
    st, pct = _run_speed_plant(c, 0.5, 200)
    assert pct == 50.0
    outs = []
    for k in range(20):                      # then the slip disappears
        st, pct = c.update(st, 100.0 + 0.5 * k, 0.0)
        outs.append(pct)
    return outs


def test_anti_windup_leaves_saturation_at_once() -> None:
    with_aw = _windup_recovery(True)
    without = _windup_recovery(False)
    # With anti-windup the integral stayed near its value at saturation: the output rises
    # within the first second. Without, the integral has grown by ~100·ki·e·100 s and the
    # output stays pinned at 50 % for the whole 10 s.
    assert with_aw[2] > 60.0
    assert max(without) == 50.0


def test_controllers_are_pure() -> None:
    c = PIController()
    st0 = c.initial_state()
    a = c.update(st0, 1.0, 0.1)
    b = c.update(st0, 1.0, 0.1)
    assert a == b and st0 == c.initial_state()


def test_make_controller() -> None:
    assert isinstance(make_controller("greeff"), GreeffController)
    assert make_controller("feedforward").channel is Channel.FLOW
    assert make_controller("pi", channel=Channel.FLOW).channel is Channel.FLOW
    with pytest.raises(ProfileError, match="unknown controller"):
        make_controller("bang-bang")
