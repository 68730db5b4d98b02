"""Calibration patterns: G-code that prints what a measurement needs.

:mod:`.base` (print settings, the writer over :mod:`flowtwin.gcode.emitter`, the result),
:mod:`.library` (every pattern by name), one module per pattern family (:mod:`.kline`,
:mod:`.chevron`, :mod:`.tower`, :mod:`.flow_rate`) and :mod:`.verify` (read back and plan).
"""
