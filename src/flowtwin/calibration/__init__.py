"""Calibration: test patterns, fits that turn measurements into profile parameters.

Quick start::

    from flowtwin.calibration import Firmware, PrintSettings, generate_pattern, verify_pattern

    pattern = generate_pattern("kline", PrintSettings(firmware=Firmware.MARLIN),
                               {"k_start": 0.0, "k_end": 0.1, "k_step": 0.01})
    check = verify_pattern(pattern, printer="generic-marlin")   # read back and plan
    assert check.ok                                             # test speeds reached

Patterns (:mod:`~flowtwin.calibration.patterns`): K-factor lines, Ellis-style chevrons, a
PA tower, extrusion-multiplier blocks, a max-volumetric-speed ramp and a flow line, for
Klipper, Marlin, RepRapFirmware and Prusa, every bead from [001 Eq. 7]. Fits: viscosity
law from a temperature sweep (:mod:`~flowtwin.calibration.viscosity_fit`), strand shape
from profile points [004] (:mod:`~flowtwin.calibration.strand_fit`), OrcaSlicer's adaptive
pressure-advance table (:mod:`~flowtwin.calibration.adaptive_pa`). See docs/calibration.md.
"""

from flowtwin.calibration.adaptive_pa import (
    AdaptivePaTable,
    parse_orca_model,
    read_orca_model,
    table_from_measurements,
    write_orca_model,
)
from flowtwin.calibration.csvdata import Column, Table, read_table, read_table_text
from flowtwin.calibration.firmware import Firmware, accel_command, pa_command, parse_firmware
from flowtwin.calibration.fragment import render_fragment, write_fragment
from flowtwin.calibration.pattern_base import (
    PaSetting,
    Pattern,
    PrintSettings,
    TestSegment,
    write_pattern,
)
from flowtwin.calibration.patterns import PATTERN_KINDS, generate_pattern, pattern_params
from flowtwin.calibration.strand_fit import StrandCalibration, fit_strand
from flowtwin.calibration.verify import PatternCheck, SegmentCheck, verify_pattern
from flowtwin.calibration.viscosity_fit import (
    ViscosityFit,
    ViscositySweep,
    apparent_viscosity_pa_s,
    fit_viscosity_law,
    sweep_from_table,
)

__all__ = [
    "PATTERN_KINDS",
    "AdaptivePaTable",
    "Column",
    "Firmware",
    "PaSetting",
    "Pattern",
    "PatternCheck",
    "PrintSettings",
    "SegmentCheck",
    "StrandCalibration",
    "Table",
    "TestSegment",
    "ViscosityFit",
    "ViscositySweep",
    "accel_command",
    "apparent_viscosity_pa_s",
    "fit_strand",
    "fit_viscosity_law",
    "generate_pattern",
    "pa_command",
    "parse_firmware",
    "parse_orca_model",
    "pattern_params",
    "read_orca_model",
    "read_table",
    "read_table_text",
    "render_fragment",
    "sweep_from_table",
    "table_from_measurements",
    "verify_pattern",
    "write_fragment",
    "write_orca_model",
    "write_pattern",
]
