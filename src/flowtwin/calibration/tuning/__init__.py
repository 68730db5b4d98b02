"""Firmware tuning: advance settings for the printer instead of a rewritten G-code.

:mod:`.adaptive_pa` (OrcaSlicer's adaptive pressure-advance table and its file format),
:mod:`.advance_settings` (the best advance factor and an adaptive table from the twin).
"""
