"""Open a printer connection from a URL.

=========================================  ===============================================
``octoprint://HOST:PORT[?port=VIRTUAL]``   OctoPrint over http (``octoprints://`` = https);
                                           ``port`` = serial port OctoPrint should open if
                                           it is not connected; ``firmware=klipper`` when a
                                           Klipper printer sits behind it
``moonraker://HOST:PORT``                  Moonraker over http (``moonrakers://`` = https)
``serial:///dev/ttyUSB0[?baud=250000]``    Marlin on a serial port
``twin[?firmware=klipper&delay=0.5]``      the twin as a simulated printer
=========================================  ===============================================

Only the host in the URL is ever contacted. User names or passwords in the URL are refused
(a secret in a URL ends up in logs and shell history); keys come from
:func:`~flowtwin.control.transports.credentials.load_api_key`.
"""

from __future__ import annotations

from urllib.parse import parse_qs, urlsplit

from flowtwin.control.loop.clock import Clock
from flowtwin.control.printer import Printer
from flowtwin.control.simulated.twin import TwinPrinter
from flowtwin.control.transports.credentials import ApiKey
from flowtwin.control.transports.marlin_serial import SerialPrinter
from flowtwin.control.transports.moonraker import MoonrakerPrinter
from flowtwin.control.transports.octoprint import OctoPrintPrinter
from flowtwin.errors import ProfileError
from flowtwin.firmware import Firmware

__all__ = ["SCHEMES", "open_printer"]

SCHEMES = ("octoprint", "octoprints", "moonraker", "moonrakers", "serial", "twin")
_ALLOWED_QUERY = {
    "octoprint": {"port", "firmware"}, "moonraker": set(), "serial": {"baud"},
    "twin": {"firmware", "delay"},
}


def open_printer(url: str, *, api_key: ApiKey | None = None, clock: Clock | None = None,
                 firmware: Firmware | None = None) -> Printer:
    """Make a (not yet connected) :class:`~flowtwin.control.printer.Printer` for ``url``.

    Parameters
    ----------
    url
        Printer URL (see the module docstring).
    api_key
        Key for OctoPrint (required) or Moonraker (optional).
    clock
        Clock of the twin (required for ``twin``).
    firmware
        Override the firmware (OctoPrint and the twin; Moonraker is always Klipper and a
        serial port always Marlin).

    Raises
    ------
    ProfileError
        Unknown scheme, missing host or key, credentials in the URL, unknown parameter.
    """
    text = url.strip()
    if text == "twin" or text.startswith("twin?"):
        text = "twin://" + text[4:]
    parts = urlsplit(text)
    scheme = parts.scheme.lower()
    if scheme not in SCHEMES:
        raise ProfileError("unknown printer URL scheme", field="--printer", value=url,
                           allowed=", ".join(f"{s}://" for s in SCHEMES))
    base = scheme.rstrip("s") if scheme in ("octoprints", "moonrakers") else scheme
    if parts.username or parts.password:
        raise ProfileError("credentials in the printer URL are refused (they would be "
                           "logged)", field="--printer", value=f"{scheme}://***@{parts.hostname}",
                           allowed="an API key from a 0600 file or the environment")
    query = {k: v[-1] for k, v in parse_qs(parts.query, keep_blank_values=True).items()}
    extra = set(query) - _ALLOWED_QUERY[base]
    if extra:
        raise ProfileError("unknown printer URL parameter", field="--printer",
                           value=sorted(extra), allowed=", ".join(sorted(_ALLOWED_QUERY[base]))
                           or "none")
    fw = firmware or (Firmware.parse(query["firmware"]) if "firmware" in query else None)
    if base in ("octoprint", "moonraker"):
        if not parts.hostname:
            raise ProfileError("printer URL has no host", field="--printer", value=url,
                               allowed=f"{scheme}://HOST:PORT")
        http = "https" if scheme.endswith("s") else "http"
        netloc = parts.hostname if parts.port is None else f"{parts.hostname}:{parts.port}"
        if ":" in parts.hostname:  # IPv6 literal
            netloc = f"[{parts.hostname}]" + ("" if parts.port is None else f":{parts.port}")
        base_url = f"{http}://{netloc}"
        if base == "octoprint":
            if api_key is None:
                raise ProfileError("OctoPrint needs an API key", field="api key",
                                   allowed="--api-key-file FILE (chmod 600) or the "
                                   "FLOWTWIN_API_KEY environment variable")
            return OctoPrintPrinter(base_url, api_key=api_key,
                                    firmware=fw or Firmware.MARLIN, port=query.get("port"))
        if fw not in (None, Firmware.KLIPPER):
            raise ProfileError("Moonraker always fronts Klipper", field="firmware",
                               value=str(fw), allowed="klipper")
        return MoonrakerPrinter(base_url, api_key=api_key)
    if base == "serial":
        if not parts.path:
            raise ProfileError("serial URL has no device", field="--printer", value=url,
                               allowed="serial:///dev/ttyUSB0")
        if fw not in (None, Firmware.MARLIN):
            raise ProfileError("the serial connection speaks Marlin's protocol",
                               field="firmware", value=str(fw), allowed="marlin")
        try:
            baud = int(query.get("baud", "115200"))
        except ValueError:
            raise ProfileError("baud must be an integer", field="baud",
                               value=query.get("baud")) from None
        return SerialPrinter(parts.path, baudrate=baud)
    if clock is None:
        raise ProfileError("the twin printer needs a clock", field="clock")
    try:
        delay = float(query.get("delay", "0"))
    except ValueError:
        raise ProfileError("delay must be a number of seconds", field="delay",
                           value=query.get("delay")) from None
    return TwinPrinter(clock, firmware=fw or Firmware.MARLIN, effect_delay_s=delay)
