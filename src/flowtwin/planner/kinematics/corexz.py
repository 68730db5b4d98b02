"""CoreXZ kinematics (Klipper ``kinematics/corexz.py``).

Two belts drive X+Z and X−Z; Klipper limits a corexz move exactly as a cartesian one: the
range box of ``[stepper_x/y/z]`` on the axes it changes, and the Z share
(``max_z_velocity · d/|Δz|``, ``max_z_accel · d/|Δz|``). No per-axis belt limit exists in
Klipper: the belts' speeds are not checked (see :mod:`~flowtwin.planner.kinematics.cartesian`).
"""

from __future__ import annotations

from flowtwin.planner.kinematics.base import PrinterLimits
from flowtwin.planner.kinematics.cartesian import Cartesian, load_box
from flowtwin.planner.klipper_cfg import CfgFile

__all__ = ["BOX", "CoreXZ", "load"]


class CoreXZ(Cartesian):
    """Box range and Z share, as cartesian."""

    name = "corexz"


#: Built from a position box alone (:func:`~flowtwin.planner.kinematics.box_kinematics`).
BOX = CoreXZ

def load(cfg: CfgFile, printer: PrinterLimits) -> CoreXZ:
    """The corexz kinematics of a printer.cfg."""
    return load_box(CoreXZ, cfg, printer, dual_axes=())
