"""The speed (``M220``) and flow (``M221``) multipliers: encoding, reports, guards.

The closed loop acts through these two multipliers [003 §2.3]. Their semantics differ
between firmwares, and getting them wrong silently changes the print:

* **Marlin** reads ``S`` as an integer (``parser.value_int()``: ``M221 S95.7`` sets 95 %).
  A bare ``M221`` *reports* ``echo:E0 Flow: 95%``; a bare ``M220`` reports ``FR:95%``.
* **Klipper** reads ``S`` as a float (``M221 S95.5`` sets 95.5 %). A bare ``M221`` or
  ``M220`` **resets the factor to 100 %** (seen on a real klippy host), so it must never be
  used as a query: read ``gcode_move.extrude_factor`` / ``speed_factor`` instead. Klipper
  has no ``M900``.
* RepRapFirmware, Prusa and Repetier: flowtwin does not model their multiplier commands
  (:attr:`Firmware.factor_decimals <flowtwin.firmware.kinds.Firmware.factor_decimals>` is
  ``None``); encoding one for them is refused rather than guessed.

Pure: strings in, strings or numbers out. Commands are read with the reader's word parser
(:func:`flowtwin.gcode.words.parse_line`).
"""

from __future__ import annotations

import math
import re
from enum import StrEnum

from flowtwin.errors import FlowtwinError, GcodeError
from flowtwin.firmware.kinds import Firmware
from flowtwin.gcode.emitter import format_number
from flowtwin.gcode.words import ParsedLine, parse_line

__all__ = [
    "FACTOR_RANGE_PCT",
    "Channel",
    "applied_percent",
    "check_command",
    "check_factor_commands",
    "encode_factor",
    "parse_factor_report",
    "query_command",
    "read_factor_command",
]

#: Range a multiplier command may carry (percent). Marlin clamps M220 to 10-999; both
#: firmwares reject or misbehave at 0. The controller limits are much tighter (50-150 %).
FACTOR_RANGE_PCT = (1.0, 999.0)


class Channel(StrEnum):
    """Which multiplier a command acts on."""

    SPEED = "speed"  #: M220, feed-rate multiplier (moves and extrusion together)
    FLOW = "flow"    #: M221, extrusion multiplier (E only)

    @property
    def mcode(self) -> str:
        """The M-code of this channel (``"M220"`` or ``"M221"``)."""
        return "M220" if self is Channel.SPEED else "M221"


def check_factor_commands(firmware: Firmware) -> Firmware:
    """``firmware`` if flowtwin models its ``M220``/``M221`` commands.

    Raises
    ------
    FlowtwinError
        It does not (the message names the firmwares it does).
    """
    if firmware.factor_decimals is None:
        supported = ", ".join(f.value for f in Firmware if f.factor_decimals is not None)
        raise FlowtwinError(f"flowtwin does not model the M220/M221 commands of "
                            f"{firmware.label}", field="firmware", value=firmware.value,
                            allowed=supported)
    return firmware


def _decimals(firmware: Firmware) -> int:
    decimals = check_factor_commands(firmware).factor_decimals
    assert decimals is not None
    return decimals


def applied_percent(firmware: Firmware, pct: float) -> float:
    """The multiplier (percent) the firmware will apply when asked for ``pct``.

    Marlin stores an integer percentage; flowtwin rounds to the nearest integer, halves
    up, before sending (Marlin itself would truncate ``95.7`` to 95). Klipper keeps a
    float; flowtwin sends three decimals.

    Raises
    ------
    FlowtwinError
        ``pct`` is not finite or outside 1-999 %, or the firmware's multipliers are not
        modelled.
    """
    _check_pct(pct)
    decimals = _decimals(firmware)
    if decimals == 0:
        return float(math.floor(pct + 0.5))  # half up, not banker's rounding
    return round(float(pct), decimals)


def encode_factor(firmware: Firmware, channel: Channel, pct: float) -> str:
    """G-code that sets ``channel`` to ``pct`` percent on ``firmware``.

    Returns
    -------
    str
        ``"M221 S95"`` (Marlin, integer) or ``"M221 S95.5"`` (Klipper, float).

    Raises
    ------
    FlowtwinError
        As :func:`applied_percent`.
    """
    value = applied_percent(firmware, pct)
    decimals = _decimals(firmware)
    text = str(int(value)) if decimals == 0 else format_number(value, decimals)
    return f"{channel.mcode} S{text}"


def query_command(firmware: Firmware, channel: Channel) -> str:
    """G-code that asks the firmware to report ``channel`` (Marlin only).

    Raises
    ------
    FlowtwinError
        On Klipper: a bare ``M220``/``M221`` resets the factor to 100 %; read
        ``gcode_move.speed_factor`` / ``extrude_factor`` through Moonraker instead. On a
        firmware whose reports flowtwin does not read.
    """
    if firmware is Firmware.KLIPPER:
        raise FlowtwinError(
            f"a bare {channel.mcode} resets the factor to 100 % on Klipper; it cannot be "
            "used as a query", field="firmware", value=str(firmware),
            allowed="read gcode_move.speed_factor/extrude_factor (Moonraker objects query)")
    if firmware is not Firmware.MARLIN:
        raise FlowtwinError(f"flowtwin does not read the {channel.mcode} report of "
                            f"{firmware.label}", field="firmware", value=str(firmware),
                            allowed="marlin")
    return channel.mcode


# Marlin's console reports (responses, not G-code)
_FLOW_RE = re.compile(r"^(?:echo:\s*)?E(\d+)\s+Flow:\s*(-?\d+(?:\.\d+)?)\s*%", re.IGNORECASE)
_FR_RE = re.compile(r"^(?:echo:\s*)?FR:\s*(-?\d+(?:\.\d+)?)\s*%", re.IGNORECASE)


def parse_factor_report(firmware: Firmware, line: str) -> tuple[Channel, float] | None:
    """Parse a firmware's multiplier report line (Marlin's; others return ``None``).

    Parameters
    ----------
    firmware
        Firmware family. Klipper never reports multipliers on the console.
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


def read_factor_command(line: str | ParsedLine) -> tuple[Channel, float | None] | None:
    """The multiplier an ``M220``/``M221`` line addresses and its ``S`` value.

    Returns
    -------
    tuple of (Channel, float or None) or None
        The channel and ``S`` (``None`` for a bare command or a non-number), or ``None``
        when the line is no multiplier command.
    """
    parsed = line if isinstance(line, ParsedLine) else parse_line(line)
    if parsed.code not in ("M220", "M221"):
        return None
    channel = Channel.SPEED if parsed.code == "M220" else Channel.FLOW
    s = parsed.params.get("S")
    return channel, (s if isinstance(s, float) else None)


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
        The command is refused, or is not valid G-code; the message says what to use
        instead.
    """
    text = line.strip()
    if not text or "\n" in text or "\r" in text:
        raise GcodeError("exactly one non-empty G-code command per call", value=line,
                         allowed="a single line")
    if firmware is Firmware.KLIPPER:
        parsed = parse_line(text)
        if parsed.code in ("M220", "M221") and "S" not in parsed.params:
            raise GcodeError(
                f"a bare {parsed.code} resets the factor to 100 % on Klipper",
                value=text, allowed=f"{parsed.code} S<percent>; read factors from gcode_move")
        if parsed.code == "M900":
            raise GcodeError("Klipper has no M900", value=text,
                             allowed="SET_PRESSURE_ADVANCE ADVANCE=<s>")
    return text


def _check_pct(pct: float) -> None:
    lo, hi = FACTOR_RANGE_PCT
    if not isinstance(pct, int | float) or not math.isfinite(pct) or not lo <= pct <= hi:
        raise FlowtwinError("multiplier out of range", field="percent", value=pct,
                            allowed=f"{lo:g} <= percent <= {hi:g}")
