"""CoreXY kinematics (Klipper ``kinematics/corexy.py``).

Two belts drive X+Y and X−Y; Klipper limits a corexy move exactly as a cartesian one: the
range box of ``[stepper_x/y/z]`` on the axes it changes, and the Z share
(``max_z_velocity · d/|Δz|``, ``max_z_accel · d/|Δz|``). No per-axis belt limit exists in
Klipper: the belts' speeds are not checked (see :mod:`~flowtwin.planner.kinematics.cartesian`).
"""

from __future__ import annotations

from flowtwin.planner.kinematics.base import PrinterLimits
from flowtwin.planner.kinematics.cartesian import Cartesian, load_box
from flowtwin.planner.klipper_cfg import CfgFile

__all__ = ["BOX", "CoreXY", "load"]


class CoreXY(Cartesian):
    """Box range and Z share, as cartesian."""

    name = "corexy"


#: Built from a position box alone (:func:`~flowtwin.planner.kinematics.box_kinematics`).
BOX = CoreXY

def load(cfg: CfgFile, printer: PrinterLimits) -> CoreXY:
    """The corexy kinematics of a printer.cfg."""
    return load_box(CoreXY, cfg, printer, dual_axes=())
