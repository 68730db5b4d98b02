"""Hybrid corexz kinematics (Klipper ``kinematics/hybrid_corexz.py``).

The X carriage is driven by a belt on X+Z (and, with a ``[dual_carriage]``, a second X
carriage by the other belt): the IDEX and "Markforged" machines. Klipper limits a move as
a cartesian one: the range box of ``[stepper_x/y/z]`` on the axes a move changes (the
active X carriage's range: here the span of both carriages, see
:mod:`~flowtwin.planner.kinematics.cartesian`) and the Z share (``max_z_velocity · d/|Δz|``,
``max_z_accel · d/|Δz|``).
"""

from __future__ import annotations

from flowtwin.planner.kinematics.base import PrinterLimits
from flowtwin.planner.kinematics.cartesian import Cartesian, load_box
from flowtwin.planner.klipper_cfg import CfgFile

__all__ = ["BOX", "HybridCoreXZ", "load"]


class HybridCoreXZ(Cartesian):
    """Box range and Z share, as cartesian."""

    name = "hybrid_corexz"


#: Built from a position box alone (:func:`~flowtwin.planner.kinematics.box_kinematics`).
BOX = HybridCoreXZ

def load(cfg: CfgFile, printer: PrinterLimits) -> HybridCoreXZ:
    """The hybrid_corexz kinematics of a printer.cfg (a ``[dual_carriage]`` moves X only)."""
    return load_box(HybridCoreXZ, cfg, printer, dual_axes=("x",))
