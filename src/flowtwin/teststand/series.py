"""The test series of Nienhaus et al. [000 §3] and the names of the slip-gradient laws a
drive under test can follow (:mod:`~flowtwin.teststand.model` says what each law is).

Kept apart from the model (which needs numpy) so that ``flowtwin teststand --help`` can show
them as its defaults without loading it.
"""

from __future__ import annotations

from enum import StrEnum

__all__ = ["PAPER_PINCH_FORCES_N", "PAPER_SPEEDS_MM_S", "SlipLaw"]

#: Feed velocities of the test series, mm/s [000 §3].
PAPER_SPEEDS_MM_S: tuple[float, ...] = (0.5, 1.0, 2.0, 5.0, 10.0, 15.0)
#: Pinch forces of the test series, 10–150 N in 10 N steps, N [000 §3].
PAPER_PINCH_FORCES_N: tuple[float, ...] = tuple(float(f) for f in range(10, 151, 10))


class SlipLaw(StrEnum):
    """Which slip-gradient law the drive under test follows (:mod:`~flowtwin.teststand.model`)."""

    PINCH = "pinch"
    VELOCITY = "velocity"
    COMBINED = "combined"
