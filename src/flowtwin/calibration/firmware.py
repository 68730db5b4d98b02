"""G-code dialects of the firmwares the calibration patterns target.

Each firmware sets the advance factor ``K`` (seconds of filament lead per mm/s of
filament speed, the ``K_LA`` of [001 Eq. 11]) with its own command:

=================  ============================================  ===========================
firmware           advance command                               acceleration command
=================  ============================================  ===========================
Klipper            ``SET_PRESSURE_ADVANCE ADVANCE=<K>``          ``SET_VELOCITY_LIMIT ACCEL=``
                   (``SMOOTH_TIME=<s>`` optional)
Marlin 2           ``M900 K<K>`` (LIN_ADVANCE, LA 1.5)           ``M204 P<a> T<a>``
RepRapFirmware     ``M572 D0 S<K>``                              ``M204 P<a> T<a>``
Prusa (Buddy)      ``M572 S<K> W<smooth>`` (W optional, s)       ``M204 P<a> T<a>``
=================  ============================================  ===========================

"Prusa" here is Prusa's current 32-bit firmware (MK4/MK3.9/XL/MINI/Core One, "Buddy"),
whose ``M572`` takes ``S`` (advance) and ``W`` (smoothing window, default 0.04 s) and no
``D``. The 8-bit Prusa-Firmware of the MK3S and MK2.5 uses Marlin's ``M900 K``: generate
those patterns with :attr:`Firmware.MARLIN`.

Klipper rejects ``M204`` with only ``P`` or only ``T`` (``P`` and ``T`` together use their
minimum), so Klipper patterns set the acceleration with ``SET_VELOCITY_LIMIT``; Marlin,
RepRapFirmware and Prusa read ``M204 P`` (printing) and ``T`` (travel).
"""

from __future__ import annotations

from enum import Enum

from flowtwin.errors import CalibrationError

__all__ = ["Firmware", "accel_command", "format_number", "pa_command", "parse_firmware"]


class Firmware(Enum):
    """Firmware families a calibration pattern can be written for."""

    KLIPPER = "klipper"
    MARLIN = "marlin"
    REPRAPFIRMWARE = "reprapfirmware"
    PRUSA = "prusa"

    @property
    def smooths_advance(self) -> bool:
        """True where the advance command takes a smoothing window (Klipper, Prusa)."""
        return self in (Firmware.KLIPPER, Firmware.PRUSA)

    @property
    def default_printer(self) -> str:
        """Built-in printer profile used to check a pattern when none is named."""
        return "generic-klipper" if self is Firmware.KLIPPER else "generic-marlin"


#: Largest advance factor any of the firmwares accepts (Marlin: ``M900 K`` 0–10).
MAX_K_S = 10.0


def parse_firmware(name: str | Firmware) -> Firmware:
    """Return the :class:`Firmware` named ``name`` (case-insensitive; ``rrf`` accepted).

    Raises
    ------
    CalibrationError
        Unknown name (the message lists the allowed ones).
    """
    if isinstance(name, Firmware):
        return name
    key = name.strip().lower()
    if key == "rrf":
        key = "reprapfirmware"
    for fw in Firmware:
        if fw.value == key:
            return fw
    raise CalibrationError("unknown firmware", field="firmware", value=name,
                           allowed=", ".join(f.value for f in Firmware))


def format_number(value: float, decimals: int = 5) -> str:
    """``value`` with at most ``decimals`` decimals, trailing zeros removed (``0.05``, ``0``)."""
    text = f"{value:.{decimals}f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def pa_command(firmware: Firmware, k_s: float, *, smooth_time_s: float | None = None) -> str:
    """The command that sets the advance factor ``k_s`` (s) on ``firmware``.

    Parameters
    ----------
    firmware
        Target firmware.
    k_s
        Advance factor, s, ``0 <= k_s <= 10``.
    smooth_time_s
        Smoothing window, s (Klipper ``SMOOTH_TIME``, Prusa ``W``); ``None`` keeps the
        firmware's setting. Marlin and RepRapFirmware do not smooth: giving it is an error.

    Returns
    -------
    str
        One G-code line without a line break.

    Raises
    ------
    CalibrationError
        ``k_s`` out of range, or a smoothing window for a firmware without one.
    """
    if not 0.0 <= k_s <= MAX_K_S:
        raise CalibrationError("advance factor out of range", field="k_s", value=k_s,
                               allowed=f"0 <= K <= {MAX_K_S:g} s")
    if smooth_time_s is not None:
        if not firmware.smooths_advance:
            raise CalibrationError(f"{firmware.value} has no advance smoothing window",
                                   field="pa_smooth_time_s", value=smooth_time_s,
                                   allowed="leave it out for marlin and reprapfirmware")
        if not 0.0 < smooth_time_s <= 0.2:
            raise CalibrationError("advance smoothing window out of range",
                                   field="pa_smooth_time_s", value=smooth_time_s,
                                   allowed="0 < t <= 0.2 s")
    k = format_number(k_s)
    if firmware is Firmware.KLIPPER:
        text = f"SET_PRESSURE_ADVANCE ADVANCE={k}"
        return text if smooth_time_s is None else \
            f"{text} SMOOTH_TIME={format_number(smooth_time_s)}"
    if firmware is Firmware.MARLIN:
        return f"M900 K{k}"
    if firmware is Firmware.REPRAPFIRMWARE:
        return f"M572 D0 S{k}"
    text = f"M572 S{k}"
    return text if smooth_time_s is None else f"{text} W{format_number(smooth_time_s)}"


def accel_command(firmware: Firmware, accel_mm_s2: float) -> str:
    """The command that sets the printing and travel acceleration (mm/s²).

    Raises
    ------
    CalibrationError
        A non-positive or absurd acceleration.
    """
    if not 0.0 < accel_mm_s2 <= 1e6:
        raise CalibrationError("acceleration out of range", field="accel_mm_s2",
                               value=accel_mm_s2, allowed="0 < a <= 1e6 mm/s²")
    a = format_number(accel_mm_s2, 1)
    if firmware is Firmware.KLIPPER:
        return f"SET_VELOCITY_LIMIT ACCEL={a}"
    return f"M204 P{a} T{a}"
