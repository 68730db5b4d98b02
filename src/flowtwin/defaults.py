"""The names flowtwin uses when a user gives none (a light module: the CLI reads these to
show its options' defaults without importing the numerical packages)."""

from __future__ import annotations

__all__ = ["DEFAULT_MACHINE", "DEFAULT_PRINTER"]

#: The set-up used when none is given: docs/spec.md §4's reference (roller #3 at 80 N, E3D V6
#: 0.4, PLA 4043D 1.75 mm at 215 °C) on Tronvoll's Prusa i3 MK2.5 [001].
DEFAULT_MACHINE = "tronvoll2019"

#: Printer used by ``plan`` when none is given.
DEFAULT_PRINTER = "generic-klipper"
