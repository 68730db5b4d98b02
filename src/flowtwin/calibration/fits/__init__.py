"""Fits: measurements to profile parameters, with standard errors.

:mod:`.fitting` (least-squares helpers), :mod:`.lagmodel` and :mod:`.lagfit` (the twin as a
forward model of bead widths, the lag fit), :mod:`.kfit` (the advance factor), :mod:`.slipfit`
(the drive's slip law [000]), :mod:`.viscosity_fit` [002], :mod:`.strand_fit` [004].
"""
