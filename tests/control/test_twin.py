"""The twin as a simulated printer: firmware semantics, effect delay, connection loss."""

from __future__ import annotations

import pytest

from flowtwin.control.loop.clock import AcceleratedClock, SimClock
from flowtwin.control.printer import CommandRejected, ConnectionLost, Printer
from flowtwin.control.simulated.twin import TwinPrinter
from flowtwin.errors import FlowtwinError, GcodeError
from flowtwin.firmware import Firmware


def test_is_a_printer() -> None:
    assert isinstance(TwinPrinter(SimClock()), Printer)


def test_marlin_semantics_integer_and_report() -> None:
    p = TwinPrinter(SimClock(), firmware=Firmware.MARLIN)
    p.connect()
    assert p.execute("M221 S95.7").ok          # strtol: 95
    assert p.read_factors().flow_pct == 95.0
    assert p.execute("M221").lines == ("echo:E0 Flow: 95%",)
    assert p.read_factors().flow_pct == 95.0    # the query does not change it
    assert p.execute("M220").lines == ("FR:100%",)


def test_klipper_semantics_float_and_bare_reset() -> None:
    p = TwinPrinter(SimClock(), firmware=Firmware.KLIPPER)
    p.connect()
    p.set_flow_factor(95.5)
    assert p.read_factors().flow_pct == 95.5
    p.execute("M221")                           # what Klipper does with a bare M221
    assert p.read_factors().flow_pct == 100.0
    with pytest.raises(GcodeError):             # ... which the connection refuses to send
        p.send_gcode("M221")
    with pytest.raises(CommandRejected, match="above 0"):
        p.execute("M221 S0")
    assert p.execute("M900 K0.05").lines == ('// Unknown command:"M900"',)


def test_effect_delay_applies_later() -> None:
    clk = SimClock()
    p = TwinPrinter(clk, effect_delay_s=1.5)
    p.connect()
    clk.advance(10.0)
    p.set_speed_factor(80)
    assert p.read_factors().speed_pct == 80.0             # acknowledged at once
    assert p.factors_at(clk.now() + 1.4).speed_pct == 100.0  # queued moves still at 100
    assert p.factors_at(clk.now() + 1.5).speed_pct == 80.0
    clk.advance(0.5)
    p.set_speed_factor(90)                                # supersedes the pending one
    assert p.factors_at(clk.now() + 1.0).speed_pct == 80.0
    assert p.factors_at(clk.now() + 1.5).speed_pct == 90.0


def test_drop_and_reconnect_resets_like_marlin() -> None:
    p = TwinPrinter(SimClock(), reset_on_connect=True)
    p.connect()
    p.set_flow_factor(90)
    p.drop_connection()
    with pytest.raises(ConnectionLost):
        p.set_flow_factor(91)
    p.connect()
    assert p.read_factors().flow_pct == 100.0


def test_accelerated_clock_runs_faster() -> None:
    clk = AcceleratedClock(1000.0)
    t0 = clk.now()
    clk.sleep(2.0)  # 2 ms of wall time
    assert clk.now() - t0 >= 2.0
    with pytest.raises(FlowtwinError, match="speed-up"):
        AcceleratedClock(0.0)
