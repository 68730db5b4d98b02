"""Pressure-advance and acceleration commands: writing them, and reading them as each
firmware does.

Every firmware sets the advance factor ``K`` (seconds of filament lead per mm/s of
filament speed, the ``K_LA`` of [001 Eq. 11]) with its own command
(:class:`~flowtwin.firmware.kinds.PaSyntax`):

* Klipper ``SET_PRESSURE_ADVANCE [EXTRUDER=<name>] [ADVANCE=<K>] [SMOOTH_TIME=<t>]``:
  ``ADVANCE < 0`` and ``SMOOTH_TIME`` outside 0-0.2 s are rejected; ``M900``/``M572`` are
  unknown to Klipper.
* Marlin ``M900 [T<tool>] K<K>`` (LIN_ADVANCE), 0-10; without ``K`` it only reports.
* RepRapFirmware ``M572 D<extruder>[:<extruder>...] S<K>``.
* Prusa Buddy ``M572 S<K> W<t>``: ``S`` outside 0-10 or ``W`` outside 0-0.2 s are ignored
  with a message; missing words keep their value.

Values are written with at most five decimals (trailing zeros removed) for ``K`` and the
window, one for accelerations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from flowtwin.errors import GcodeError
from flowtwin.firmware.kinds import Firmware, PaSyntax
from flowtwin.gcode.emitter import format_number

if TYPE_CHECKING:  # the move table (numpy) is not needed to write or read a command
    from flowtwin.gcode.moves import Event

__all__ = [
    "ACCEL_MAX_MM_S2",
    "DEFAULT_SMOOTH_TIME_S",
    "MAX_K_S",
    "MAX_SMOOTH_TIME_S",
    "PA_CODES",
    "PaChange",
    "accel_command",
    "pa_command",
    "read_pa_command",
]

#: Klipper's default ``pressure_advance_smooth_time`` and Prusa's default ``M572 W``, s.
DEFAULT_SMOOTH_TIME_S = 0.040
#: Longest smoothing window Klipper (``maxval=.200``) and Prusa (0-0.2) accept, s.
MAX_SMOOTH_TIME_S = 0.200
#: Largest advance factor any of the firmwares accepts (Marlin ``M900 K`` 0-10), s.
MAX_K_S = 10.0
#: Largest acceleration flowtwin writes, mm/s² (far above any FFF printer).
ACCEL_MAX_MM_S2 = 1e6
#: Every command word that sets pressure advance on some firmware.
PA_CODES = frozenset(s.code for s in PaSyntax)

_K_DECIMALS = 5
_ACCEL_DECIMALS = 1


def pa_command(firmware: Firmware, k_s: float, *, smooth_time_s: float | None = None) -> str:
    """The command that sets the advance factor ``k_s`` (s) on ``firmware``.

    Parameters
    ----------
    firmware
        Target firmware.
    k_s
        Advance factor, s, ``0 <= k_s <= 10``.
    smooth_time_s
        Smoothing window, s (Klipper ``SMOOTH_TIME``, Prusa ``W``), ``0 < t <= 0.2``;
        ``None`` keeps the firmware's. Firmwares without a window refuse it.

    Returns
    -------
    str
        One G-code line without a line break (``"M572 S0.045 W0.03"``).

    Raises
    ------
    GcodeError
        ``k_s`` out of range, or a smoothing window for a firmware without one.
    """
    if not (math.isfinite(k_s) and 0.0 <= k_s <= MAX_K_S):
        raise GcodeError("advance factor out of range", field="k_s", value=k_s,
                         allowed=f"0 <= K <= {MAX_K_S:g} s")
    syntax = firmware.pa_syntax
    text = syntax.template.format(k=format_number(k_s, _K_DECIMALS))
    if smooth_time_s is None:
        return text
    if syntax.smooth_template is None:
        raise GcodeError(f"{firmware.value} has no advance smoothing window",
                         field="pa_smooth_time_s", value=smooth_time_s,
                         allowed="leave it out for " + ", ".join(
                             f.value for f in Firmware if not f.smooths_advance))
    if not (math.isfinite(smooth_time_s) and 0.0 < smooth_time_s <= MAX_SMOOTH_TIME_S):
        raise GcodeError("advance smoothing window out of range", field="pa_smooth_time_s",
                         value=smooth_time_s, allowed=f"0 < t <= {MAX_SMOOTH_TIME_S:g} s")
    return text + syntax.smooth_template.format(t=format_number(smooth_time_s, _K_DECIMALS))


def accel_command(firmware: Firmware, accel_mm_s2: float) -> str:
    """The command that sets the printing and travel acceleration (mm/s²) on ``firmware``
    (:attr:`Firmware.accel_template <flowtwin.firmware.kinds.Firmware.accel_template>`).

    Raises
    ------
    GcodeError
        A non-positive or absurd acceleration.
    """
    if not (math.isfinite(accel_mm_s2) and 0.0 < accel_mm_s2 <= ACCEL_MAX_MM_S2):
        raise GcodeError("acceleration out of range", field="accel_mm_s2", value=accel_mm_s2,
                         allowed=f"0 < a <= {ACCEL_MAX_MM_S2:g} mm/s²")
    return firmware.accel_template.format(a=format_number(accel_mm_s2, _ACCEL_DECIMALS))


@dataclass(frozen=True, slots=True)
class PaChange:
    """What an advance command the firmware accepted sets (``None``: unchanged).

    Attributes
    ----------
    k_s
        New advance factor, s.
    smooth_time_s
        New smoothing window, s.
    """

    k_s: float | None = None
    smooth_time_s: float | None = None


def _num(ev: Event, key: str, warnings: list[str], source: str) -> float | None:
    if key not in ev.params:
        return None
    val = ev.params[key]
    if isinstance(val, str):
        warnings.append(f"{source}:{ev.line}: {ev.code} {key}={val!r} is not a number; ignored")
        return None
    return float(val)


def read_pa_command(firmware: Firmware, ev: Event, *, tool: int, source: str,
                    warnings: list[str]) -> PaChange | None:
    """What the advance command ``ev`` does on ``firmware``, for extruder ``tool``.

    Parameters
    ----------
    firmware
        The firmware reading the command.
    ev
        An event whose code is ``firmware.pa_syntax.code``.
    tool
        The extruder modelled (0: the first).
    source
        File name for the messages.
    warnings
        Receives one message per rejected or malformed value (with its line).

    Returns
    -------
    PaChange or None
        ``None`` where the command does not act on ``tool`` (another extruder, a report
        only, or a value Marlin refuses); else the values it sets.
    """
    syntax = firmware.pa_syntax
    if syntax is PaSyntax.SET_PRESSURE_ADVANCE:
        name = ev.params.get("EXTRUDER")
        if name is not None and str(name) != ("extruder" if tool == 0 else f"extruder{tool}"):
            return None
        adv = _num(ev, "ADVANCE", warnings, source)
        smooth = _num(ev, "SMOOTH_TIME", warnings, source)
        if adv is not None and adv < 0.0:
            warnings.append(f"{source}:{ev.line}: ADVANCE={adv} < 0 rejected by Klipper")
            adv = None
        if smooth is not None and not (0.0 <= smooth <= MAX_SMOOTH_TIME_S):
            warnings.append(f"{source}:{ev.line}: SMOOTH_TIME={smooth} outside 0-0.2 s "
                            "rejected by Klipper")
            smooth = None
        return PaChange(adv, smooth)
    if syntax is PaSyntax.M900:
        t_sel = _num(ev, "T", warnings, source)
        if t_sel is not None and int(t_sel) != tool:
            return None
        k = _num(ev, "K", warnings, source)
        if k is None:
            return None  # M900 without K reports only
        if not (0.0 <= k <= MAX_K_S):
            warnings.append(f"{source}:{ev.line}: M900 K{k} out of range 0-10; ignored")
            return None
        return PaChange(k)
    if syntax is PaSyntax.M572_D:
        d_sel = ev.params.get("D")
        if d_sel is not None:
            wanted = {int(float(p)) for p in str(d_sel).split(":") if p.strip()}
            if tool not in wanted:
                return None
        s_val = _num(ev, "S", warnings, source)
        return PaChange(s_val if s_val is not None and s_val >= 0.0 else None)
    s_val = _num(ev, "S", warnings, source)
    w_val = _num(ev, "W", warnings, source)
    if s_val is not None and not (0.0 <= s_val <= MAX_K_S):
        warnings.append(f"{source}:{ev.line}: M572 S{s_val} out of range 0-10; ignored")
        s_val = None
    if w_val is not None and not (0.0 <= w_val <= MAX_SMOOTH_TIME_S):
        warnings.append(f"{source}:{ev.line}: M572 W{w_val} out of range 0-0.2; ignored")
        w_val = None
    return PaChange(s_val, w_val)
