"""Cartesian kinematics (Klipper ``kinematics/cartesian.py``).

Each of X, Y, Z has its own rail (``[stepper_x]``, ``[stepper_y]``, ``[stepper_z]``):
``G28`` homes the named axes (all without a name) to their ``position_endstop``, a move
is refused when an axis it changes ends outside ``position_min .. position_max``, and a
move with Z motion is limited to ``max_z_velocity · d/|Δz|`` and ``max_z_accel · d/|Δz|``
(``[printer]``; default and maximum ``max_velocity`` / ``max_accel``). Nothing else
limits a cartesian move. The planner applies these rules itself (the box and the Z
share), so this kinematics adds no per-move limits.

With a ``[dual_carriage]`` (IDEX), Klipper checks the range of whichever carriage is
active; flowtwin does not follow ``SET_DUAL_CARRIAGE`` and checks that axis against the
span of both carriages, so it never refuses a move the second carriage can make.
"""

from __future__ import annotations

from typing import TypeVar

from flowtwin.planner.kinematics.base import Kinematics, PrinterLimits, read_rail, read_z_limits
from flowtwin.planner.klipper_cfg import CfgFile

__all__ = ["BOX", "Cartesian", "load", "load_box"]


class Cartesian(Kinematics):
    """X, Y, Z rails; range box and Z share applied by the planner."""

    name = "cartesian"


K = TypeVar("K", bound=Kinematics)


def load_box(cls: type[K], cfg: CfgFile, printer: PrinterLimits, *,
             dual_axes: tuple[str, ...] = ("x", "y")) -> K:
    """A box kinematics from ``[stepper_x/y/z]`` (and ``[dual_carriage]``) of ``cfg``."""
    rails = [read_rail(cfg.require(f"stepper_{a}",
                                   f"[stepper_{a}] with position_endstop and position_max"))
             for a in "xyz"]
    lo = [r.position_min for r in rails]
    hi = [r.position_max for r in rails]
    if dual_axes and cfg.has_section("dual_carriage"):
        dc = cfg.section("dual_carriage")
        axis = dc.get("axis", dual_axes[0]).strip().lower()
        if axis not in dual_axes:
            raise dc.error("axis", "invalid dual carriage axis", value=axis,
                           allowed=", ".join(dual_axes))
        rail = read_rail(dc)
        i = "xyz".index(axis)
        lo[i] = min(lo[i], rail.position_min)
        hi[i] = max(hi[i], rail.position_max)
    zv, za = read_z_limits(printer)
    home = (rails[0].position_endstop, rails[1].position_endstop, rails[2].position_endstop)
    box_lo = (lo[0], lo[1], lo[2])
    box_hi = (hi[0], hi[1], hi[2])
    return cls(home_position=home, axes_min=box_lo, axes_max=box_hi, box_min=box_lo,
               box_max=box_hi, max_z_velocity=zv, max_z_accel=za)


#: Built from a position box alone (:func:`~flowtwin.planner.kinematics.box_kinematics`).
BOX = Cartesian

def load(cfg: CfgFile, printer: PrinterLimits) -> Cartesian:
    """The cartesian kinematics of a printer.cfg."""
    return load_box(Cartesian, cfg, printer)
