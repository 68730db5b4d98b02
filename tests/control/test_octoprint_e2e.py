"""End to end against a real OctoPrint 1.11.8 server and its virtual printer."""

from __future__ import annotations

import json
import logging
import os
import threading
from pathlib import Path

import httpx
import pytest
import typer
from typer.testing import CliRunner

from flowtwin.cli import control as control_cli
from flowtwin.control.loop.clock import RealClock
from flowtwin.control.loop.controllers import GreeffController, Limits
from flowtwin.control.loop.log import ControlLog
from flowtwin.control.loop.measurement import SyntheticSlipSource
from flowtwin.control.loop.supervisor import FaultKind, LoopSettings, Status, run_control
from flowtwin.control.transports.credentials import ApiKey
from flowtwin.control.transports.octoprint import OctoPrintPrinter
from flowtwin.errors import GcodeError, PrinterConnectionError
from flowtwin.firmware import Firmware

pytestmark = [pytest.mark.service, pytest.mark.xdist_group("octoprint")]


def _printer(server, **kw) -> OctoPrintPrinter:
    return OctoPrintPrinter(server.url, api_key=ApiKey(server.api_key, origin="test"),
                            port="VIRTUAL", **kw)


def test_send_multipliers_and_see_them_acknowledged(octoprint_server) -> None:
    p = _printer(octoprint_server)
    p.connect()
    try:
        r = p.set_flow_factor(95.4)
        assert r.ok and r.gcode == "M221 S95"       # Marlin encoding: integer
        assert p.set_speed_factor(90).ok
        f = p.read_factors()
        # the virtual printer never reports M220/M221: acknowledged values are returned
        assert (f.speed_pct, f.flow_pct, f.source) == (90.0, 95.0, "commanded")
        assert 0.0 < r.latency_s < p.ack_timeout_s
    finally:
        p.close()
    log = octoprint_server.serial_log()
    i = log.index("Send: M221 S95")
    assert "Recv: ok" in log[i:]
    assert "Send: M220 S90" in log


def test_klipper_behind_octoprint_never_sends_a_bare_m221(octoprint_server) -> None:
    p = _printer(octoprint_server, firmware=Firmware.KLIPPER)
    p.connect()
    try:
        assert p.set_flow_factor(97.25).gcode == "M221 S97.25"
        with pytest.raises(GcodeError, match="resets the factor"):
            p.send_gcode("M221")
        assert p.read_factors().flow_pct == 97.25   # no query sent on Klipper
    finally:
        p.close()
    log = octoprint_server.serial_log()
    assert "Send: M221 S97.25" in log
    tail = log[log.index("Send: M221 S97.25"):]
    assert "Send: M221\n" not in tail and not tail.rstrip().endswith("Send: M221")


def test_wrong_key_is_rejected_without_showing_it(octoprint_server) -> None:
    p = OctoPrintPrinter(octoprint_server.url, api_key=ApiKey("WRONG" * 6, origin="test"))
    with pytest.raises(PrinterConnectionError, match="rejected the API key") as exc:
        p.connect()
    assert "WRONG" not in str(exc.value)
    p.close()


def test_control_run_survives_a_dropped_connection(octoprint_server, tmp_path: Path,
                                                    caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.DEBUG)
    clock = RealClock()
    p = _printer(octoprint_server)
    src = SyntheticSlipSource(clock, duration_s=6.0, rate_hz=10.0, seed=7, noise=0.005)
    dropped = threading.Event()
    admin = httpx.Client(base_url=octoprint_server.url, trust_env=False,
                         headers={"X-Api-Key": octoprint_server.api_key})

    def drop(st: Status) -> None:
        if st.t_s >= 3.0 and not dropped.is_set():
            dropped.set()   # OctoPrint drops its printer connection mid-run
            r = admin.post("/api/connection", json={"command": "disconnect"})
            assert r.status_code == 204

    with ControlLog(tmp_path / "run.csv") as log:
        s = run_control(p, src, GreeffController(limits=Limits(50, 150, 100.0)), clock=clock,
                        settings=LoopSettings(duration_s=6.0, period_s=0.25,
                                              reconnect_interval_s=0.5),
                        log_to=log, on_status=drop)
    admin.close()
    assert dropped.is_set()
    assert [f.kind for f in s.faults] == [FaultKind.CONNECTION_LOST]
    assert log.events("recovered"), "no recovery logged"
    t_rec = float(log.events("recovered")[0]["t_s"])
    # control resumed after the reconnect: acknowledged commands other than 100 %
    resumed = [r for r in log.events("command") if float(r["t_s"]) > t_rec]
    assert resumed and all(r["ack"] == "1" for r in resumed)
    assert s.restored and s.multiplier_min_pct < 95.0
    assert log.events("restore")[0]["gcode"] == "M220 S100"
    serial = octoprint_server.serial_log()
    assert serial.rstrip().count("Send: M220 S100") >= 3   # start, after reconnect, end
    # the key appears nowhere: CSV, log records
    csv_text = (tmp_path / "run.csv").read_text()
    assert "connection_lost" in csv_text
    assert octoprint_server.api_key not in csv_text
    assert octoprint_server.api_key not in caplog.text


def test_cli_json_against_octoprint(octoprint_server, tmp_path: Path) -> None:
    keyfile = tmp_path / "key"
    keyfile.write_text(octoprint_server.api_key + "\n")
    os.chmod(keyfile, 0o600)
    app = typer.Typer()
    control_cli.register(app)

    @app.callback()
    def _root() -> None:
        pass

    url = f"octoprint://127.0.0.1:{octoprint_server.port}?port=VIRTUAL"
    out = tmp_path / "cli.csv"
    result = CliRunner().invoke(app, [
        "control", "--printer", url, "--synthetic", "--duration", "3", "--period", "0.25",
        "--controller", "feedforward", "--api-key-file", str(keyfile), "--json",
        "--log", str(out)])
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["restored"] is True and summary["channel"] == "flow"
    # each acknowledged command waits for OctoPrint's 2 Hz push batch, so the sample count
    # depends on latency; the loop must have run and acted
    assert summary["samples"] >= 2 and summary["commands"] >= 2
    assert summary["multiplier_max_pct"] > 100.0
    assert summary["final_factors"]["flow_pct"] == 100.0
    for text in (result.stdout, result.output, out.read_text()):
        assert octoprint_server.api_key not in text
    # a key file readable by others is refused before anything is contacted
    os.chmod(keyfile, 0o644)
    bad = CliRunner().invoke(app, ["control", "--printer", url, "--synthetic",
                                   "--api-key-file", str(keyfile)])
    assert bad.exit_code != 0 and "chmod 600" in str(bad.exception)
