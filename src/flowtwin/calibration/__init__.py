"""Calibration: test patterns, fits that turn measurements into profile parameters.

Quick start::

    from flowtwin.calibration import PrintSettings, generate_pattern, verify_pattern
    from flowtwin.firmware import Firmware

    pattern = generate_pattern("kline", PrintSettings(firmware=Firmware.MARLIN),
                               {"k_start": 0.0, "k_end": 0.1, "k_step": 0.01})
    check = verify_pattern(pattern, printer="generic-marlin")   # read back and plan
    assert check.ok                                             # test speeds reached

Patterns (:mod:`~flowtwin.calibration.patterns`): K-factor lines, Ellis-style chevrons, a
PA tower, extrusion-multiplier blocks, a max-volumetric-speed ramp and a flow line, for
every firmware of :mod:`flowtwin.firmware`, every bead from [001 Eq. 7]. Fits: the lag ``K``
(dead time, gain) from widths along test lines by fitting the twin
(:mod:`~flowtwin.calibration.lagfit`, :mod:`~flowtwin.calibration.kfit`) or from an image of
a K-line pattern (:mod:`~flowtwin.calibration.kimage`, tested on images from
:mod:`~flowtwin.calibration.render`), the slip law from test-stand records
(:mod:`~flowtwin.calibration.slipfit`), the viscosity law from a temperature sweep
(:mod:`~flowtwin.calibration.viscosity_fit`), strand shape from profile points [004]
(:mod:`~flowtwin.calibration.strand_fit`), OrcaSlicer's adaptive pressure-advance table
(:mod:`~flowtwin.calibration.adaptive_pa`). See docs/calibration.md.

Lag from a measured width profile::

    from flowtwin.calibration import fit_k, read_width_profiles

    fit, _ = fit_k(read_width_profiles("widths.csv"), k_la_s=0.0, machine="tronvoll2019")
    print(fit.k_s, "±", fit.k_err_s)
"""

from typing import TYPE_CHECKING, Any

from flowtwin.calibration.adaptive_pa import (
    AdaptivePaTable,
    append_measurement,
    parse_orca_model,
    read_orca_model,
    table_from_measurements,
    write_orca_model,
)
from flowtwin.calibration.csvdata import Column, Table, read_table, read_table_text
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

#: The fits that need the dynamics, OpenCV or the test stand load on first use, so that
#: importing the package (and ``flowtwin --help``) stays fast.
_LAZY = {
    "fit_k": "kfit", "kline_for_machine": "kfit",
    "KLineImageResult": "kimage", "LineReading": "kimage", "analyse_kline_image": "kimage",
    "LagFit": "lagfit", "WidthProfile": "lagfit", "fit_lag": "lagfit",
    "read_width_profiles": "lagfit",
    "LagModel": "lagmodel", "LagParams": "lagmodel", "TestLine": "lagmodel",
    "lag_model": "lagmodel",
    "ImageConditions": "render", "RenderedImage": "render", "render_pattern_image": "render",
    "SlipCalibration": "slipfit", "fit_slip_records": "slipfit",
}

if TYPE_CHECKING:
    from flowtwin.calibration.kfit import fit_k, kline_for_machine
    from flowtwin.calibration.kimage import KLineImageResult, LineReading, analyse_kline_image
    from flowtwin.calibration.lagfit import LagFit, WidthProfile, fit_lag, read_width_profiles
    from flowtwin.calibration.lagmodel import LagModel, LagParams, TestLine, lag_model
    from flowtwin.calibration.render import ImageConditions, RenderedImage, render_pattern_image
    from flowtwin.calibration.slipfit import SlipCalibration, fit_slip_records


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(f"{__name__}.{module}"), name)


__all__ = [
    "PATTERN_KINDS",
    "AdaptivePaTable",
    "Column",
    "ImageConditions",
    "KLineImageResult",
    "LagFit",
    "LagModel",
    "LagParams",
    "LineReading",
    "PaSetting",
    "Pattern",
    "PatternCheck",
    "PrintSettings",
    "RenderedImage",
    "SegmentCheck",
    "SlipCalibration",
    "StrandCalibration",
    "Table",
    "TestLine",
    "TestSegment",
    "ViscosityFit",
    "ViscositySweep",
    "WidthProfile",
    "analyse_kline_image",
    "apparent_viscosity_pa_s",
    "append_measurement",
    "fit_k",
    "fit_lag",
    "fit_slip_records",
    "fit_strand",
    "fit_viscosity_law",
    "generate_pattern",
    "kline_for_machine",
    "lag_model",
    "parse_orca_model",
    "pattern_params",
    "read_orca_model",
    "read_table",
    "read_table_text",
    "read_width_profiles",
    "render_fragment",
    "render_pattern_image",
    "sweep_from_table",
    "table_from_measurements",
    "verify_pattern",
    "write_fragment",
    "write_orca_model",
    "write_pattern",
]
