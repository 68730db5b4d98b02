"""Cable winch kinematics (Klipper ``kinematics/winch.py``).

Three or more steppers (``[stepper_a]``, ``[stepper_b]``, ... up to ``[stepper_z]``) reel
cables to anchors at ``anchor_x/y/z``. Klipper implements no homing, range check or speed
limit for it (``check_move`` does nothing; ``G28`` declares the head at ``0, 0, 0``), so
only ``max_velocity`` / ``max_accel`` and the extruder limit a winch move.
"""

from __future__ import annotations

from flowtwin.planner.kinematics.base import Kinematics, PrinterLimits
from flowtwin.planner.klipper_cfg import CfgFile

__all__ = ["Winch", "load"]


class Winch(Kinematics):
    """No range, no per-move limit; ``G28`` puts the head at the origin."""

    name = "winch"

    def homed_axes(self, named: int) -> int:
        """Klipper's winch "homes" all axes at once."""
        del named
        return 7


def load(cfg: CfgFile, printer: PrinterLimits) -> Winch:
    """The winch kinematics of a printer.cfg (anchors of ``[stepper_a]`` ... )."""
    del printer
    anchors = []
    for i in range(26):
        name = "stepper_" + chr(ord("a") + i)
        if i >= 3 and not cfg.has_section(name):
            break
        sec = cfg.require(name, f"[{name}] with anchor_x, anchor_y, anchor_z")
        anchors.append(tuple(sec.getfloat(f"anchor_{a}") for a in "xyz"))
    lo = tuple(min(a[i] for a in anchors) for i in range(3))
    hi = tuple(max(a[i] for a in anchors) for i in range(3))
    return Winch(home_position=(0.0, 0.0, 0.0), axes_min=(lo[0], lo[1], lo[2]),
                 axes_max=(hi[0], hi[1], hi[2]))
