"""No kinematics (Klipper ``kinematics/none.py``): a toolhead without motion hardware.

Klipper checks nothing and limits nothing (``check_move`` does nothing; ``G28`` moves
nothing): only ``max_velocity`` / ``max_accel`` and the extruder limit a move. Used for
extruder-only test rigs.
"""

from __future__ import annotations

from flowtwin.planner.kinematics.base import Kinematics, PrinterLimits
from flowtwin.planner.klipper_cfg import CfgFile

__all__ = ["NoKinematics", "load"]


class NoKinematics(Kinematics):
    """Nothing to check."""

    name = "none"


def load(cfg: CfgFile, printer: PrinterLimits) -> NoKinematics:
    """The ``none`` kinematics (reads nothing)."""
    del cfg, printer
    return NoKinematics(axes_min=(0.0, 0.0, 0.0), axes_max=(0.0, 0.0, 0.0))
