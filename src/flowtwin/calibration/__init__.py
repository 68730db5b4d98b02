"""Calibration: test patterns, fits that turn measurements into profile parameters.

Quick start::

    from flowtwin.calibration import PrintSettings, generate_pattern, verify_pattern
    from flowtwin.firmware import Firmware

    pattern = generate_pattern("kline", PrintSettings(firmware=Firmware.MARLIN),
                               {"k_start": 0.0, "k_end": 0.1, "k_step": 0.01})
    check = verify_pattern(pattern, printer="generic-marlin")   # read back and plan
    assert check.ok                                             # test speeds reached

Patterns (:mod:`~flowtwin.calibration.patterns.catalog`): K-factor lines, Ellis-style chevrons, a
PA tower, extrusion-multiplier blocks, a max-volumetric-speed ramp and a flow line, for
every firmware of :mod:`flowtwin.firmware`, every bead from [001 Eq. 7]. Fits: the lag ``K``
(dead time, gain) from widths along test lines by fitting the twin
(:mod:`~flowtwin.calibration.fits.lagfit`, :mod:`~flowtwin.calibration.fits.kfit`) or from an
image of a K-line pattern (:mod:`~flowtwin.calibration.image.kimage`, tested on images from
:mod:`~flowtwin.calibration.image.twin_render`), the slip law from test-stand records
(:mod:`~flowtwin.calibration.fits.slipfit`), the viscosity law from a temperature sweep
(:mod:`~flowtwin.calibration.fits.viscosity_fit`), strand shape from profile points [004]
(:mod:`~flowtwin.calibration.fits.strand_fit`), OrcaSlicer's adaptive pressure-advance table
(:mod:`~flowtwin.calibration.tuning.adaptive_pa`), and the firmware's advance settings from the
twin (:mod:`~flowtwin.calibration.tuning.advance_settings`). See docs/calibration.md.

Layout: :mod:`~flowtwin.calibration.patterns` (test-pattern G-code),
:mod:`~flowtwin.calibration.image` (measurement of photos and images),
:mod:`~flowtwin.calibration.fits` (measurements to parameters),
:mod:`~flowtwin.calibration.tuning` (firmware settings); ``csvdata`` and ``fragment`` read the
measurement tables and write profile fragments; ``guide`` says what to measure.

Lag from a measured width profile::

    from flowtwin.calibration import fit_k, read_width_profiles

    fit, _ = fit_k(read_width_profiles("widths.csv"), k_la_s=0.0, machine="tronvoll2019")
    print(fit.k_s, "±", fit.k_err_s)
"""

from typing import TYPE_CHECKING

from flowtwin._lazy import lazy_exports

#: Every name loads on first use: the fits need the dynamics, scipy, OpenCV or the test
#: stand, the patterns the firmware model and numpy; importing the package (or one of its
#: small modules, such as ``fragment``, as ``flowtwin calibrate --help`` does) stays fast.
_LAZY = {
    "render_fragment": "fragment", "write_fragment": "fragment",
    "PATTERN_KINDS": "patterns.catalog", "generate_pattern": "patterns.catalog",
    "pattern_params": "patterns.catalog",
    "PaSetting": "patterns.pattern", "Pattern": "patterns.pattern",
    "PrintSettings": "patterns.pattern", "TestSegment": "patterns.pattern",
    "write_pattern": "patterns.pattern",
    "Column": "csvdata", "Table": "csvdata", "read_table": "csvdata",
    "read_table_text": "csvdata",
    "AdaptivePaTable": "tuning.adaptive_pa", "append_measurement": "tuning.adaptive_pa",
    "parse_orca_model": "tuning.adaptive_pa", "read_orca_model": "tuning.adaptive_pa",
    "table_from_measurements": "tuning.adaptive_pa", "write_orca_model": "tuning.adaptive_pa",
    "StrandCalibration": "fits.strand_fit", "fit_strand": "fits.strand_fit",
    "ViscosityFit": "fits.viscosity_fit", "ViscositySweep": "fits.viscosity_fit",
    "apparent_viscosity_pa_s": "fits.viscosity_fit", "fit_viscosity_law": "fits.viscosity_fit",
    "sweep_from_table": "fits.viscosity_fit",
    "PatternCheck": "patterns.verify", "SegmentCheck": "patterns.verify",
    "verify_pattern": "patterns.verify",
    "fit_k": "fits.kfit", "kline_for_machine": "fits.kfit",
    "KLineImageResult": "image.kimage", "LineReading": "image.kimage",
    "analyse_kline_image": "image.kimage",
    "LagFit": "fits.lagfit", "WidthProfile": "fits.lagfit", "fit_lag": "fits.lagfit",
    "read_width_profiles": "fits.lagfit",
    "LagModel": "fits.lagmodel", "LagParams": "fits.lagmodel", "TestLine": "fits.lagmodel",
    "lag_model": "fits.lagmodel",
    "ImageConditions": "image.twin_render", "RenderedImage": "image.twin_render",
    "render_pattern_image": "image.twin_render",
    "SlipCalibration": "fits.slipfit", "fit_slip_records": "fits.slipfit",
    "AdvanceFit": "tuning.advance_settings", "adaptive_pa_table": "tuning.advance_settings",
    "best_pressure_advance": "tuning.advance_settings",
}

if TYPE_CHECKING:
    from flowtwin.calibration.csvdata import Column, Table, read_table, read_table_text
    from flowtwin.calibration.fits.kfit import fit_k, kline_for_machine
    from flowtwin.calibration.fits.lagfit import LagFit, WidthProfile, fit_lag, read_width_profiles
    from flowtwin.calibration.fits.lagmodel import LagModel, LagParams, TestLine, lag_model
    from flowtwin.calibration.fits.slipfit import SlipCalibration, fit_slip_records
    from flowtwin.calibration.fits.strand_fit import StrandCalibration, fit_strand
    from flowtwin.calibration.fits.viscosity_fit import (
        ViscosityFit,
        ViscositySweep,
        apparent_viscosity_pa_s,
        fit_viscosity_law,
        sweep_from_table,
    )
    from flowtwin.calibration.fragment import render_fragment, write_fragment
    from flowtwin.calibration.image.kimage import KLineImageResult, LineReading, analyse_kline_image
    from flowtwin.calibration.image.twin_render import (
        ImageConditions,
        RenderedImage,
        render_pattern_image,
    )
    from flowtwin.calibration.patterns.catalog import (
        PATTERN_KINDS,
        generate_pattern,
        pattern_params,
    )
    from flowtwin.calibration.patterns.pattern import (
        PaSetting,
        Pattern,
        PrintSettings,
        TestSegment,
        write_pattern,
    )
    from flowtwin.calibration.patterns.verify import PatternCheck, SegmentCheck, verify_pattern
    from flowtwin.calibration.tuning.adaptive_pa import (
        AdaptivePaTable,
        append_measurement,
        parse_orca_model,
        read_orca_model,
        table_from_measurements,
        write_orca_model,
    )
    from flowtwin.calibration.tuning.advance_settings import (
        AdvanceFit,
        adaptive_pa_table,
        best_pressure_advance,
    )


__getattr__, __dir__ = lazy_exports(__name__, {name: f"{__name__}.{module}"
                                               for name, module in _LAZY.items()})


__all__ = [
    "PATTERN_KINDS",
    "AdaptivePaTable",
    "AdvanceFit",
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
    "adaptive_pa_table",
    "analyse_kline_image",
    "apparent_viscosity_pa_s",
    "append_measurement",
    "best_pressure_advance",
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
