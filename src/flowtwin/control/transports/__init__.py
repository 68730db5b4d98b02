"""Printer hosts flowtwin talks to: OctoPrint, Moonraker (Klipper) and a Marlin serial port.

Each implements :class:`flowtwin.control.printer.Printer`; to add a host, add a module
here and a URL scheme in :mod:`flowtwin.control.connect` (docs/architecture.md).
"""
