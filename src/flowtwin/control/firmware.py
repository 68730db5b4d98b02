"""Per-firmware encoding of the multiplier commands and parsing of their reports.

The closed loop acts through the speed multiplier (``M220``) and the flow multiplier
(``M221``) [003 §2.3]. Their semantics differ between firmwares, and getting them wrong
silently changes the print:

* **Marlin** reads ``S`` as an integer (``parser.value_int()``: ``M221 S95.7`` sets 95 %).
  A bare ``M221`` *reports* ``echo:E0 Flow: 95%``; a bare ``M220`` reports ``FR:95%``.
  Pressure advance is ``M900 K`` (needs LIN_ADVANCE).
* **Klipper** reads ``S`` as a float (``M221 S95.5`` sets 95.5 %). A bare ``M221`` or
  ``M220`` **resets the factor to 100 %** (seen on a real klippy host, NOTES.md), so it must
  never be used as a query: read ``gcode_move.extrude_factor`` / ``speed_factor`` instead.
  Klipper has no ``M900``; pressure advance is ``SET_PRESSURE_ADVANCE ADVANCE=``.

This module is pure: strings in, strings or numbers out.
"""

from __future__ import annotations

import math
import re
from enum import StrEnum

from flowtwin.errors import FlowtwinError, GcodeError

__all__ = [
    "Channel",
    "Firmware",
    "applied_percent",
    "check_command",
    "encode_factor",
    "encode_pressure_advance",
    "parse_factor_report",
    "query_command",
]

#: Range a multiplier command may carry (percent). Marlin clamps M220 to 10-999; both
#: firmwares reject or misbehave at 0. The controller limits are much tighter (50-150 %).
FACTOR_RANGE_PCT = (1.0, 999.0)


class Firmware(StrEnum):
    """Firmware family behind a printer connection (decides command encoding)."""

    MARLIN = "marlin"
    KLIPPER = "klipper"


class Channel(StrEnum):
    """Which multiplier a command acts on."""

    SPEED = "speed"  #: M220, feed-rate multiplier (moves and extrusion together)
    FLOW = "flow"    #: M221, extrusion multiplier (E only)

    @property
    def mcode(self) -> str:
        """The M-code of this channel (``"M220"`` or ``"M221"``)."""
        return "M220" if self is Channel.SPEED else "M221"


def applied_percent(firmware: Firmware, pct: float) -> float:
    """The multiplier (percent) the firmware will apply when asked for ``pct``.

    Marlin stores an integer percentage; flowtwin rounds to the nearest integer, halves
    up, before sending (Marlin itself would truncate ``95.7`` to 95). Klipper keeps a
    float; flowtwin sends three decimals.

    Parameters
    ----------
    firmware
        Firmware family.
    pct
        Requested multiplier in percent.

    Returns
    -------
    float
        The multiplier in percent that the printer ends up using.
    """
    _check_pct(pct)
    if firmware is Firmware.MARLIN:
        return float(math.floor(pct + 0.5))  # half up, not banker's rounding
    return round(float(pct), 3)


def encode_factor(firmware: Firmware, channel: Channel, pct: float) -> str:
    """G-code that sets ``channel`` to ``pct`` percent on ``firmware``.

    Parameters
    ----------
    firmware
        Firmware family.
    channel
        Speed (``M220``) or flow (``M221``).
    pct
        Multiplier in percent, within 1-999.

    Returns
    -------
    str
        ``"M221 S95"`` (Marlin, integer) or ``"M221 S95.5"`` (Klipper, float).

    Raises
    ------
    FlowtwinError
        ``pct`` is not finite or outside 1-999 %.
    """
    value = applied_percent(firmware, pct)
    if firmware is Firmware.MARLIN:
        return f"{channel.mcode} S{int(value)}"
    text = f"{value:.3f}".rstrip("0").rstrip(".")
    return f"{channel.mcode} S{text}"


def query_command(firmware: Firmware, channel: Channel) -> str:
    """G-code that asks the firmware to report ``channel`` (Marlin only).

    Raises
    ------
    FlowtwinError
        On Klipper: a bare ``M220``/``M221`` resets the factor to 100 %; read
        ``gcode_move.speed_factor`` / ``extrude_factor`` through Moonraker instead.
    """
    if firmware is Firmware.KLIPPER:
        raise FlowtwinError(
            f"a bare {channel.mcode} resets the factor to 100 % on Klipper; it cannot be "
            "used as a query", field="firmware", value=str(firmware),
            allowed="read gcode_move.speed_factor/extrude_factor (Moonraker objects query)")
    return channel.mcode


_FLOW_RE = re.compile(r"^(?:echo:\s*)?E(\d+)\s+Flow:\s*(-?\d+(?:\.\d+)?)\s*%", re.IGNORECASE)
_FR_RE = re.compile(r"^(?:echo:\s*)?FR:\s*(-?\d+(?:\.\d+)?)\s*%", re.IGNORECASE)


def parse_factor_report(firmware: Firmware, line: str) -> tuple[Channel, float] | None:
    """Parse a firmware's multiplier report line.

    Parameters
    ----------
    firmware
        Firmware family. Klipper never reports multipliers on the console (returns None).
    line
        One received line, e.g. ``"echo:E0 Flow: 95%"`` or ``"FR:90%"`` (Marlin).

    Returns
    -------
    tuple of (Channel, float) or None
        The channel and its value in percent, or None if the line is no such report.
    """
    if firmware is not Firmware.MARLIN:
        return None
    text = line.strip()
    m = _FLOW_RE.match(text)
    if m:
        return Channel.FLOW, float(m.group(2))
    m = _FR_RE.match(text)
    if m:
        return Channel.SPEED, float(m.group(1))
    return None


_BARE_FACTOR_RE = re.compile(r"^\s*(M22[01])(?:\s+T\d+)?\s*(?:;.*)?$", re.IGNORECASE)
_M900_RE = re.compile(r"^\s*M900\b", re.IGNORECASE)


def check_command(firmware: Firmware, line: str) -> str:
    """Refuse G-code that would do something other than intended on ``firmware``.

    On Klipper a bare ``M220``/``M221`` resets the factor (a query on Marlin) and ``M900``
    is unknown. Multi-line text is refused on every firmware (one command per call).

    Returns
    -------
    str
        The stripped command.

    Raises
    ------
    GcodeError
        The command is refused; the message says what to use instead.
    """
    text = line.strip()
    if not text or "\n" in text or "\r" in text:
        raise GcodeError("exactly one non-empty G-code command per call", value=line,
                         allowed="a single line")
    if firmware is Firmware.KLIPPER:
        m = _BARE_FACTOR_RE.match(text)
        if m:
            raise GcodeError(
                f"a bare {m.group(1).upper()} resets the factor to 100 % on Klipper",
                value=text, allowed=f"{m.group(1).upper()} S<percent>; read factors "
                "from gcode_move")
        if _M900_RE.match(text):
            raise GcodeError("Klipper has no M900", value=text,
                             allowed="SET_PRESSURE_ADVANCE ADVANCE=<s>")
    return text


def encode_pressure_advance(firmware: Firmware, k_s: float) -> str:
    """G-code that sets the pressure/linear advance factor ``k_s`` (seconds) [001].

    Marlin: ``M900 K<k>`` (LIN_ADVANCE 1.5, K in mm of filament per mm/s, i.e. s);
    Klipper: ``SET_PRESSURE_ADVANCE ADVANCE=<k>``.
    """
    if not math.isfinite(k_s) or not 0.0 <= k_s <= 10.0:
        raise FlowtwinError("pressure advance out of range", field="k_s", value=k_s,
                            allowed="0 <= K <= 10 s")
    text = f"{k_s:.4f}".rstrip("0").rstrip(".") or "0"
    if firmware is Firmware.MARLIN:
        return f"M900 K{text}"
    return f"SET_PRESSURE_ADVANCE ADVANCE={text}"


def _check_pct(pct: float) -> None:
    lo, hi = FACTOR_RANGE_PCT
    if not isinstance(pct, int | float) or not math.isfinite(pct) or not lo <= pct <= hi:
        raise FlowtwinError("multiplier out of range", field="percent", value=pct,
                            allowed=f"{lo:g} <= percent <= {hi:g}")
