"""Supervisor: every exit path returns the twin printer to 100 % and logs why."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import pytest

from flowtwin.control.loop.clock import SimClock
from flowtwin.control.loop.controllers import GreeffController, Limits, PIController, WindowState
from flowtwin.control.loop.log import ControlLog
from flowtwin.control.loop.measurement import Measurement, SyntheticSlipSource
from flowtwin.control.loop.supervisor import FaultKind, LoopSettings, Status, run_control
from flowtwin.control.simulated.twin import TwinPrinter
from flowtwin.firmware import Channel, Firmware


def _rig(*, firmware: Firmware = Firmware.MARLIN, duration_s: float = 30.0, seed: int = 3,
         **source_opts):
    clk = SimClock()
    twin = TwinPrinter(clk, firmware=firmware, effect_delay_s=0.5)
    src = SyntheticSlipSource(clk, duration_s=duration_s, seed=seed,
                              factors=lambda: twin.factors_at(clk.now()), **source_opts)
    return clk, twin, src


def _multipliers_sent(twin: TwinPrinter, mcode: str) -> list[tuple[float, str]]:
    return [(t, g) for t, g in twin.received if g.startswith(mcode)]


def test_normal_run_reduces_slip_and_restores() -> None:
    clk, twin, src = _rig()
    log = ControlLog()
    s = run_control(twin, src, GreeffController(), clock=clk,
                    settings=LoopSettings(duration_s=30.0), log_to=log)
    assert s.restored and s.faults == ()
    assert s.final_factors is not None and s.final_factors.speed_pct == 100.0
    assert _multipliers_sent(twin, "M220")[-1][1] == "M220 S100"
    assert s.samples == 60                         # 2 Hz for 30 s
    assert s.multiplier_min_pct < 90.0             # acted during the high-slip third
    assert [r["event"] for r in log.rows][-3:] == ["restore", "read", "end"]
    # Open loop (limits pinned at 100 %) on the same seeded signal: more slip.
    clk2, twin2, src2 = _rig()
    s_open = run_control(twin2, src2, GreeffController(limits=Limits(100.0, 100.0, 1.0)),
                         clock=clk2, settings=LoopSettings(duration_s=30.0))
    assert s.mean_slip is not None and s_open.mean_slip is not None
    assert s.mean_slip < s_open.mean_slip - 0.01


@dataclass(frozen=True)
class _CrashAt:
    """A controller that works like Greeff's until ``t_crash_s``, then raises (a bug)."""

    t_crash_s: float
    inner: GreeffController = field(default_factory=GreeffController)

    @property
    def channel(self) -> Channel:
        return self.inner.channel

    @property
    def limits(self) -> Limits:
        return self.inner.limits

    def initial_state(self) -> WindowState:
        return self.inner.initial_state()

    def update(self, state: WindowState, t_s: float, slip: float) -> tuple[WindowState, float]:
        if t_s >= self.t_crash_s:
            raise ZeroDivisionError("injected crash")
        return self.inner.update(state, t_s, slip)


def test_crash_in_loop_restores_100_and_logs() -> None:
    clk, twin, src = _rig()
    log = ControlLog()
    with pytest.raises(ZeroDivisionError, match="injected crash"):
        run_control(twin, src, _CrashAt(15.0), clock=clk,
                    settings=LoopSettings(duration_s=30.0), log_to=log)
    assert twin.held_factors().speed_pct == 100.0
    assert min(float(g.split("S")[1]) for _, g in _multipliers_sent(twin, "M220")) < 100.0
    faults = log.events("fault")
    assert len(faults) == 1 and faults[0]["detail"].startswith("crash: ZeroDivisionError")
    assert log.events("restore")[0]["gcode"] == "M220 S100"
    assert log.events("end")[0]["detail"] == "restored=True"


def test_interrupt_restores_100() -> None:
    clk, twin, src = _rig()
    log = ControlLog()

    def stop(st: Status) -> None:
        if st.t_s > 12.0:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_control(twin, src, GreeffController(), clock=clk,
                    settings=LoopSettings(duration_s=30.0), log_to=log, on_status=stop)
    assert twin.held_factors().speed_pct == 100.0
    assert [r["detail"] for r in log.events("fault")] == ["interrupted: interrupted"]


def test_lost_camera_ends_run_at_100() -> None:
    clk, twin, src = _rig(lost_after_s=14.0)
    s = run_control(twin, src, GreeffController(), clock=clk,
                    settings=LoopSettings(duration_s=30.0))
    assert [f.kind for f in s.faults] == [FaultKind.CAMERA_LOST]
    assert s.faults[0].t_s == pytest.approx(14.0, abs=0.5)
    assert s.duration_s < 15.0 and s.restored
    # at 14 s the slip was high, so the multiplier was below 100 until the safe state
    safe = [g for t, g in twin.received if t >= 14.0]
    assert safe[0] == "M220 S100"


def test_stale_measurements_trigger_watchdog() -> None:
    clk, twin, src = _rig(stop_after_s=15.0)
    s = run_control(twin, src, GreeffController(), clock=clk,
                    settings=LoopSettings(duration_s=30.0, watchdog_s=2.0))
    assert [f.kind for f in s.faults] == [FaultKind.STALE]
    # last fresh sample at 14.5 s; the watchdog fires at the first tick past 16.5 s
    assert 16.5 < s.faults[0].t_s <= 17.0
    after = [(t, g) for t, g in twin.received if t >= 16.5]
    assert after[0][1] == "M220 S100"
    assert twin.factors_at(20.0).speed_pct == 100.0   # held in the safe state
    assert s.restored


def test_lost_connection_reconnects_and_resumes() -> None:
    clk, twin, src = _rig()
    log = ControlLog()
    dropped: list[float] = []

    def drop(st: Status) -> None:
        if st.t_s >= 12.0 and not dropped:
            dropped.append(st.t_s)
            twin.refuse_connects = 2            # host down for two attempts (2 s)
            twin.drop_connection()

    s = run_control(twin, src, GreeffController(), clock=clk,
                    settings=LoopSettings(duration_s=30.0, reconnect_interval_s=1.0),
                    log_to=log, on_status=drop)
    assert [f.kind for f in s.faults] == [FaultKind.CONNECTION_LOST]
    assert log.events("recovered")[0]["detail"] == "reconnected after 3 attempt(s)"
    assert twin.connects == 2
    # first command after the reconnect is the safe state, then control resumes
    t_rec = float(log.events("recovered")[0]["t_s"])
    later = [g for t, g in twin.received if t >= t_rec - 1e-9]
    assert later[0] == "M220 S100" and any(g != "M220 S100" for g in later[1:])
    assert s.restored


def test_reconnect_gives_up_and_reports_not_restored() -> None:
    clk, twin, src = _rig()

    def drop(st: Status) -> None:
        if st.t_s >= 5.0 and twin.refuse_connects == 0:
            twin.refuse_connects = 10**6
            twin.drop_connection()

    s = run_control(twin, src, GreeffController(), clock=clk,
                    settings=LoopSettings(duration_s=60.0, reconnect_timeout_s=5.0),
                    on_status=drop)
    assert [f.kind for f in s.faults] == [FaultKind.CONNECTION_LOST,
                                           FaultKind.RECONNECT_FAILED]
    assert not s.restored and s.final_factors is None


def test_flow_channel_on_klipper_twin_sends_floats() -> None:
    clk, twin, src = _rig(firmware=Firmware.KLIPPER)
    s = run_control(twin, src, PIController(channel=Channel.FLOW), clock=clk,
                    settings=LoopSettings(duration_s=30.0))
    flows = [g for _, g in _multipliers_sent(twin, "M221")]
    assert any("." in g for g in flows)          # float multipliers on Klipper
    assert s.multiplier_max_pct > 105.0 and s.restored
    assert twin.held_factors().flow_pct == 100.0


def test_settings_validated() -> None:
    from flowtwin.errors import FlowtwinError
    with pytest.raises(FlowtwinError, match="watchdog shorter"):
        LoopSettings(duration_s=10.0, period_s=1.0, watchdog_s=0.5)


class _Scripted:
    """A source replaying a script of (from time, kind) measurements once per tick."""

    def __init__(self, clk: SimClock, script: list[tuple[float, str]]) -> None:
        self.clk = clk
        self.script = script

    def read(self) -> Measurement | None:
        now = self.clk.now()
        kind = [k for t, k in self.script if now >= t][-1]
        if kind == "slip":
            return Measurement(now, 0.3)
        if kind == "idle":
            return Measurement(now, math.nan, valid=False, idle=True)
        return None

    def close(self) -> None:
        pass


def test_idle_measurements_hold_the_multiplier_without_a_fault() -> None:
    # a heater wait: the camera sees the gear at rest for 20 s — not a stale camera
    clk = SimClock()
    twin = TwinPrinter(clk)
    src = _Scripted(clk, [(0.0, "slip"), (10.0, "idle"), (30.0, "slip")])
    log = ControlLog()
    s = run_control(twin, src, GreeffController(), clock=clk,
                    settings=LoopSettings(duration_s=40.0, watchdog_s=2.0), log_to=log)
    assert s.faults == () and s.restored
    held = {g for t, g in twin.received if 10.5 <= t < 30.0}
    assert held == set()                              # nothing sent while idle
    assert twin.factors_at(29.9).speed_pct == 70.0    # 100 (1 - 0.3), held
    assert len(log.events("idle")) == 40              # 2 Hz for 20 s
    assert s.samples == 40                            # idle is not a sample
    # the same silence without idle reports is a stale camera
    clk2 = SimClock()
    twin2 = TwinPrinter(clk2)
    src2 = _Scripted(clk2, [(0.0, "slip"), (10.0, "none"), (30.0, "slip")])
    s2 = run_control(twin2, src2, GreeffController(), clock=clk2,
                     settings=LoopSettings(duration_s=40.0, watchdog_s=2.0))
    assert [f.kind for f in s2.faults] == [FaultKind.STALE]


def test_stop_condition_ends_the_run_normally() -> None:
    clk, twin, src = _rig()
    log = ControlLog()
    s = run_control(twin, src, GreeffController(), clock=clk,
                    settings=LoopSettings(duration_s=60.0), log_to=log,
                    stop=lambda: clk.now() >= 12.0)
    assert s.duration_s == pytest.approx(12.0) and s.faults == () and s.restored
    assert [r["event"] for r in log.rows][-4:] == ["done", "restore", "read", "end"]
    assert s.to_dict()["final_multiplier_restored"] is True
