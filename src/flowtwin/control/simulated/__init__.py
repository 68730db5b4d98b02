"""The twin as a printer: G-code printed physically in simulated, accelerated or real time.

:mod:`.twin` (the :class:`~flowtwin.control.printer.Printer`), :mod:`.job` (a planned
G-code in program time), :mod:`.runner` (printing it: heater, extruder, history),
:mod:`.extruder` (one step of the extrusion state equation), :mod:`.camera` (frames of
the drive, measured by vision).
"""
