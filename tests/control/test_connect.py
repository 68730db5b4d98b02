"""Printer URLs and the rule that only the given host is contacted."""

from __future__ import annotations

import httpx
import pytest

from flowtwin.control.connect import open_printer
from flowtwin.control.loop.clock import SimClock
from flowtwin.control.simulated.twin import TwinPrinter
from flowtwin.control.transports._net import guarded_client, websocket_url
from flowtwin.control.transports.credentials import ApiKey
from flowtwin.control.transports.marlin_serial import SerialPrinter
from flowtwin.control.transports.moonraker import MoonrakerPrinter
from flowtwin.control.transports.octoprint import OctoPrintPrinter
from flowtwin.errors import PrinterConnectionError, ProfileError
from flowtwin.firmware import Firmware

KEY = ApiKey("k" * 32, origin="test")


def test_octoprint_url() -> None:
    p = open_printer("octoprint://127.0.0.1:5000?port=VIRTUAL", api_key=KEY)
    assert isinstance(p, OctoPrintPrinter)
    assert (p.base_url, p.port, p.firmware) == ("http://127.0.0.1:5000", "VIRTUAL",
                                                Firmware.MARLIN)
    q = open_printer("octoprints://printer.local?firmware=klipper", api_key=KEY)
    assert isinstance(q, OctoPrintPrinter)
    assert (q.base_url, q.firmware) == ("https://printer.local", Firmware.KLIPPER)
    with pytest.raises(ProfileError, match="needs an API key"):
        open_printer("octoprint://127.0.0.1:5000")


def test_moonraker_serial_twin_urls() -> None:
    m = open_printer("moonraker://[::1]:7125")
    assert isinstance(m, MoonrakerPrinter) and m.base_url == "http://[::1]:7125"
    assert m.firmware is Firmware.KLIPPER
    s = open_printer("serial:///dev/ttyUSB0?baud=250000")
    assert isinstance(s, SerialPrinter) and (s.port, s.baudrate) == ("/dev/ttyUSB0", 250000)
    t = open_printer("twin?firmware=klipper&delay=0.5", clock=SimClock())
    assert isinstance(t, TwinPrinter) and t.firmware is Firmware.KLIPPER
    assert t.effect_delay_s == 0.5
    assert isinstance(open_printer("twin", clock=SimClock()), TwinPrinter)


@pytest.mark.parametrize(("url", "match"), [
    ("http://127.0.0.1:5000", "unknown printer URL scheme"),
    ("octoprint://user:pw@127.0.0.1:5000", "credentials in the printer URL"),
    ("octoprint://127.0.0.1:5000?apikey=abc", "unknown printer URL parameter"),
    ("moonraker://", "no host"),
    ("serial://", "no device"),
    ("serial:///dev/ttyUSB0?baud=fast", "baud must be an integer"),
])
def test_bad_urls(url: str, match: str) -> None:
    with pytest.raises(ProfileError, match=match):
        open_printer(url, api_key=KEY, clock=SimClock())


def test_password_not_echoed_in_error() -> None:
    with pytest.raises(ProfileError) as exc:
        open_printer("octoprint://user:hunter2@127.0.0.1:5000", api_key=KEY)
    assert "hunter2" not in str(exc.value)


def test_guarded_client_refuses_other_hosts() -> None:
    with guarded_client("http://127.0.0.1:9") as client:
        with pytest.raises(PrinterConnectionError, match="other than the one given"):
            client.get("http://example.org/")
        with pytest.raises(PrinterConnectionError, match="other than the one given"):
            client.get("http://127.0.0.1:10/")          # same host, other port
        with pytest.raises(httpx.TransportError):        # the given one is tried (closed)
            client.get("/api/version")
        assert client.trust_env is False                 # no proxy from the environment
        assert client.follow_redirects is False


def test_websocket_url_same_host() -> None:
    assert websocket_url("http://127.0.0.1:5000", "/sockjs/websocket") == \
        "ws://127.0.0.1:5000/sockjs/websocket"
    assert websocket_url("https://h:443", "/websocket") == "wss://h:443/websocket"
