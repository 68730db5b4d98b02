"""The firmware model: the firmware kinds and everything that differs between them.

* :mod:`~flowtwin.firmware.kinds`: :class:`Firmware` (the one firmware enum), its planner
  family, pressure-advance algorithm, advance command syntax and multiplier precision;
* :mod:`~flowtwin.firmware.advance`: writing and reading the pressure-advance and
  acceleration commands, their ranges and defaults;
* :mod:`~flowtwin.firmware.factors`: the ``M220``/``M221`` multipliers (encoding, Marlin's
  reports, commands refused on Klipper);
* :mod:`~flowtwin.firmware.nonlinear`: nonlinear extrusion (``M592``): which firmware scales
  E with the extrusion speed, by which formula.

Planning (:mod:`flowtwin.planner.plan_file`), the dynamics' pressure advance, the calibration
patterns, the twin's firmware settings and the closed loop all read the firmware from
here. To add a firmware, see :mod:`flowtwin.firmware.kinds`.

Example
-------
>>> from flowtwin.firmware import Firmware, pa_command
>>> pa_command(Firmware.parse("rrf"), 0.045)
'M572 D0 S0.045'
"""

from __future__ import annotations

from flowtwin.firmware.advance import (
    ACCEL_MAX_MM_S2,
    DEFAULT_SMOOTH_TIME_S,
    MAX_K_S,
    MAX_SMOOTH_TIME_S,
    PA_CODES,
    PaChange,
    accel_command,
    pa_command,
    read_pa_command,
)
from flowtwin.firmware.factors import (
    FACTOR_RANGE_PCT,
    Channel,
    applied_percent,
    check_command,
    check_factor_commands,
    encode_factor,
    parse_factor_report,
    query_command,
    read_factor_command,
)
from flowtwin.firmware.kinds import AdvanceAlgorithm, Firmware, PaSyntax, PlannerFamily
from flowtwin.firmware.nonlinear import NonlinearFormula, nonlinear_command, nonlinear_formula

__all__ = [
    "ACCEL_MAX_MM_S2",
    "DEFAULT_SMOOTH_TIME_S",
    "FACTOR_RANGE_PCT",
    "MAX_K_S",
    "MAX_SMOOTH_TIME_S",
    "PA_CODES",
    "AdvanceAlgorithm",
    "Channel",
    "Firmware",
    "NonlinearFormula",
    "PaChange",
    "PaSyntax",
    "PlannerFamily",
    "accel_command",
    "applied_percent",
    "check_command",
    "check_factor_commands",
    "encode_factor",
    "nonlinear_command",
    "nonlinear_formula",
    "pa_command",
    "parse_factor_report",
    "query_command",
    "read_factor_command",
    "read_pa_command",
]
