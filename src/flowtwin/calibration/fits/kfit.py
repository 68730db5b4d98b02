"""The advance factor from widths measured along test lines: the API behind ``fit-k``.

Two ways to say which line was measured:

* **a G-code file** and the line number of each test line's first extruding move (a
  K-line, a flow line, any straight line of a print); each test line runs over the
  consecutive extruding moves from there, and its advance factor is whatever the profile
  and the file's own commands set;
* **the K-line's parameters** (:class:`~flowtwin.calibration.patterns.kline.KLineParams` speeds and
  lengths, :class:`~flowtwin.calibration.patterns.pattern.PrintSettings` bead and
  acceleration) and the advance factor it was printed with: the line is generated as
  ``flowtwin calibrate pattern kline`` writes it, for the machine's firmware.

Either way the twin is planned on the machine's printer and fitted to the widths
(:func:`~flowtwin.calibration.fits.lagfit.fit_lag`).
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import replace

from flowtwin.calibration.fits.lagfit import LagFit, WidthProfile, fit_lag
from flowtwin.calibration.fits.lagmodel import DEFAULT_MACHINE, LagModel, lag_model
from flowtwin.calibration.patterns.kline import KLineParams, kline_pattern
from flowtwin.calibration.patterns.pattern import Pattern, PrintSettings
from flowtwin.errors import CalibrationError
from flowtwin.firmware import Firmware
from flowtwin.profiles.machine import Machine, load_machine

__all__ = ["fit_k", "kline_for_machine", "machine_for_pattern", "pattern_firmware"]

def pattern_firmware(machine: Machine) -> Firmware:
    """The firmware a pattern for ``machine`` is written for: its printer's."""
    return machine.printer.firmware


def machine_for_pattern(pattern: Pattern,
                        machine: Machine | str | os.PathLike[str] | None) -> Machine:
    """The set-up a printed ``pattern`` is read against (object, built-in name or default).

    Raises
    ------
    CalibrationError
        The pattern was written for another firmware than the set-up's printer (its advance
        commands would have been ignored on that printer).
    """
    m = machine if isinstance(machine, Machine) else load_machine(machine or DEFAULT_MACHINE)
    if pattern.settings.firmware is not pattern_firmware(m):
        raise CalibrationError("the pattern is written for another firmware than the "
                               "machine's printer: its advance commands would be ignored",
                               field="firmware", value=pattern.settings.firmware.value,
                               allowed=f"{pattern_firmware(m).value} (printer "
                                       f"{m.printer.name})")
    return m


def kline_for_machine(machine: Machine, settings: PrintSettings, params: KLineParams
                      ) -> Pattern:
    """The K-line pattern written for ``machine``'s firmware (other settings as given)."""
    return kline_pattern(replace(settings, firmware=pattern_firmware(machine)), params)


def fit_k(profiles: Sequence[WidthProfile] | Mapping[int | None, WidthProfile], *,
          gcode: str | os.PathLike[str] | bytes | None = None,
          gcode_lines: Sequence[int] | None = None,
          settings: PrintSettings | None = None, kline: KLineParams | None = None,
          k_la_s: float = 0.0, machine: Machine | str | os.PathLike[str] | None = None,
          fit_dead_time: bool = False, fit_gain: bool = False, slip: bool = False,
          end_margin_mm: float = 1.0) -> tuple[LagFit, LagModel]:
    """Fit the lag to width profiles of test lines.

    Parameters
    ----------
    profiles
        One profile per test line; a mapping keyed by G-code line (as
        :func:`~flowtwin.calibration.fits.lagfit.read_width_profiles` returns it) supplies
        ``gcode_lines`` itself.
    gcode
        The G-code that printed the lines (path or bytes); ``None``: a K-line from
        ``settings``/``kline``.
    gcode_lines
        First-move line of each test line (with ``gcode``, unless the mapping has them).
    settings, kline
        Bead, acceleration and K-line geometry of a generated line (defaults: [001
        Table I]'s 0.48 mm lines on 0.2 mm layers, 20/40/20 mm at 20/70 mm/s).
    k_la_s
        Advance factor the generated line was printed with, s.
    machine
        Set-up (planner, column, slip); default the lag model's.
    fit_dead_time, fit_gain, slip, end_margin_mm
        See :func:`~flowtwin.calibration.fits.lagfit.fit_lag` and
        :func:`~flowtwin.calibration.fits.lagmodel.lag_model`.

    Returns
    -------
    fit : LagFit
    model : LagModel

    Raises
    ------
    CalibrationError
        Contradictory or missing line information, or a degenerate fit.
    """
    m = machine if isinstance(machine, Machine) else load_machine(machine or DEFAULT_MACHINE)
    if isinstance(profiles, Mapping):
        keys = list(profiles)
        profs = list(profiles.values())
        if keys != [None]:
            if gcode_lines is not None:
                raise CalibrationError("the profile file names its G-code lines: leave out "
                                       "the line numbers", field="gcode_line")
            gcode_lines = [int(k) for k in keys if k is not None]
    else:
        profs = list(profiles)
    if gcode is None:
        if gcode_lines is not None:
            raise CalibrationError("G-code line numbers need the G-code file",
                                   field="gcode", allowed="give the G-code, or no lines")
        if len(profs) != 1:
            raise CalibrationError("a generated K-line is one test line: give one profile",
                                   field="profiles", value=len(profs), allowed="1")
        params = replace(kline or KLineParams(), k_start=k_la_s, k_end=k_la_s, k_step=0.01,
                         mark_every=0)
        pattern = kline_for_machine(m, settings or PrintSettings(), params)
        first = pattern.segments[0].line
        model = lag_model(pattern.text().encode(), [first], machine=m, slip=slip)
    else:
        if gcode_lines is None or len(gcode_lines) != len(profs):
            raise CalibrationError("give the G-code line of each test line's first move",
                                   field="gcode_line", value=None if gcode_lines is None
                                   else len(gcode_lines),
                                   allowed=f"{len(profs)} line number(s)")
        layer = None if settings is None else settings.layer_height_mm
        model = lag_model(gcode, gcode_lines, machine=m, slip=slip, layer_height_mm=layer)
    fit = fit_lag(model, profs, fit_dead_time=fit_dead_time, fit_gain=fit_gain,
                  end_margin_mm=end_margin_mm)
    return fit, model
