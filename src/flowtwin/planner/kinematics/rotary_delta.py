"""Rotary delta kinematics (Klipper ``kinematics/rotary_delta.py``).

Three shoulders at ``shoulder_radius`` from the centre and ``shoulder_height`` above the
bed, at ``angle`` 30°, 150°, 270°, each turn an upper arm (``upper_arm_length``) in the
vertical plane through the centre; a lower arm (``lower_arm_length``) runs from its elbow
to the effector. ``G28`` homes all three arms at once: arm ``i`` stops at the angle it
has with the effector at ``(0, 0, position_endstop_i)``, and the head is where the three
lower arms meet (``(0, 0, position_endstop)`` when the arms agree).

What limits a move (``RotaryDeltaKinematics.check_move``), with ``xy²`` of its end:

* range: ``min_z ≤ z ≤ max_z`` (``minimum_z_position``, default 0; ``max_z`` the lowest
  ``position_endstop``) and ``xy² ≤ max_xy²``, ``max_xy = min(shoulder_radius +
  upper_arm, lower_arm − shoulder_radius)`` over the arms; above ``limit_z`` (the lowest
  home elbow height minus its lower arm) the radius shrinks to ``max_z − z``. A move
  ending on the home XY between ``min_z`` and the home height is allowed anyway;
* a move with Z motion cruises at most at ``max_z_velocity`` (not scaled by the Z
  share; its acceleration is not limited).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flowtwin.errors import ProfileError
from flowtwin.planner.kinematics.base import (
    MAX_LENGTH_MM,
    Kinematics,
    MoveGeometry,
    MoveLimits,
    PrinterLimits,
    Refusal,
    read_rail,
    read_z_limits,
    trilaterate,
)
from flowtwin.planner.klipper_cfg import CfgFile

__all__ = ["RotaryDelta", "arm_angle", "load"]

Vec3 = tuple[float, float, float]


def arm_angle(point: Vec3, *, shoulder_radius: float, shoulder_height: float,
              angle_deg: float, upper_arm: float, lower_arm: float) -> float:
    """Upper-arm angle (rad, from the horizontal) that puts the effector at ``point``.

    In the arm's plane (radial ``u`` from the shoulder, height ``h`` over it) the elbow
    lies on the circle of radius ``upper_arm`` round the shoulder and on the circle of
    radius ``sqrt(lower_arm² − w²)`` round the effector's projection (``w``: the
    effector's distance from the plane); of the two intersections the elbow is the outer
    one (larger ``u``).
    """
    a = math.radians(angle_deg)
    x, y, z = point
    u = x * math.cos(a) + y * math.sin(a) - shoulder_radius
    w = y * math.cos(a) - x * math.sin(a)
    h = z - shoulder_height
    r2 = lower_arm * lower_arm - w * w
    dist2 = u * u + h * h
    dist = math.sqrt(dist2)
    along = (upper_arm * upper_arm - r2 + dist2) / (2.0 * dist)
    across2 = upper_arm * upper_arm - along * along
    if not (r2 > 0.0 and across2 >= 0.0):
        raise ProfileError("the arms cannot reach the home position",
                           field="upper_arm_length", value=(upper_arm, lower_arm),
                           allowed="arms that reach (0, 0, position_endstop)")
    across = math.sqrt(across2)
    cu, ch = u / dist, h / dist
    sols = [(along * cu - s * across * ch, along * ch + s * across * cu) for s in (1, -1)]
    eu, eh = max(sols)
    return math.atan2(eh, eu)


@dataclass(frozen=True, kw_only=True)
class RotaryDelta(Kinematics):
    """A rotary delta: reach, the cone and the Z limits (mm, mm/s)."""

    name = "rotary_delta"
    min_z: float
    max_z: float
    limit_z: float
    max_xy2: float
    z_speed: float

    def homed_axes(self, named: int) -> int:
        """All three arms home together."""
        del named
        return 7

    def limit_moves(self, geom: MoveGeometry) -> MoveLimits:
        """Range (reach, cone, Z limits, the way back from home); Z moves at most at
        ``max_z_velocity``."""
        kin = geom.kinematic
        ex, ey, ez = geom.end[:, 0], geom.end[:, 1], geom.end[:, 2]
        end_xy2 = ex * ex + ey * ey
        reach2 = np.where(ez > self.limit_z, np.minimum(self.max_xy2, (self.max_z - ez) ** 2),
                          self.max_xy2)
        out = (end_xy2 > reach2) | (ez > self.max_z) | (ez < self.min_z)
        hx, hy, hz = self.home_position
        homing = (ex == hx) & (ey == hy) & (ez >= self.min_z) & (ez <= hz)
        bad = np.flatnonzero(kin & out & ~homing)
        refused = None
        if bad.size:
            k = int(bad[0])
            refused = Refusal(k, "Move out of range: beyond the rotary delta's reach",
                              (float(ex[k]), float(ey[k]), float(ez[k])),
                              f"x²+y² <= {float(reach2[k]):.6g} mm² at this height, "
                              f"{self.min_z:g} <= z <= {self.max_z:g}")
        z_moves = kin & (geom.delta[:, 2] != 0.0)
        if not np.any(z_moves):
            return MoveLimits(refused=refused)
        speed = np.where(z_moves, self.z_speed, np.inf)
        return MoveLimits(speed=speed, refused=refused)


def load(cfg: CfgFile, printer: PrinterLimits) -> RotaryDelta:
    """The rotary delta kinematics of a printer.cfg (``[printer]``, ``[stepper_a/b/c]``)."""
    secs = [cfg.require(f"stepper_{t}", f"[stepper_{t}] of a rotary delta arm")
            for t in "abc"]
    rail_a = read_rail(secs[0], need_minmax=False)
    endstops = [rail_a.position_endstop] + [
        read_rail(s, need_minmax=False, default_endstop=rail_a.position_endstop
                  ).position_endstop for s in secs[1:]]
    zv, _ = read_z_limits(printer, accel=False)
    pr = printer.section
    big = MAX_LENGTH_MM
    sr = pr.getfloat("shoulder_radius", above=0.0, maxval=big)
    sh = pr.getfloat("shoulder_height", above=0.0, maxval=big)
    ua0 = secs[0].getfloat("upper_arm_length", above=0.0, maxval=big)
    ua = [ua0] + [s.getfloat("upper_arm_length", ua0, above=0.0, maxval=big)
                  for s in secs[1:]]
    la0 = secs[0].getfloat("lower_arm_length", above=0.0, maxval=big)
    la = [la0] + [s.getfloat("lower_arm_length", la0, above=0.0, maxval=big)
                  for s in secs[1:]]
    angles = [s.getfloat("angle", d) for s, d in zip(secs, (30.0, 150.0, 270.0), strict=True)]
    elbows = []
    for i in range(3):
        theta = arm_angle((0.0, 0.0, endstops[i]), shoulder_radius=sr, shoulder_height=sh,
                          angle_deg=angles[i], upper_arm=ua[i], lower_arm=la[i])
        radial = sr + ua[i] * math.cos(theta)
        a = math.radians(angles[i])
        elbows.append((radial * math.cos(a), radial * math.sin(a),
                       sh + ua[i] * math.sin(theta)))
    home = trilaterate(elbows, [v * v for v in la])
    max_z = min(endstops)
    min_z = pr.getfloat("minimum_z_position", 0.0, minval=-big, maxval=max_z)
    max_xy2 = min(min(sr + u for u in ua), min(v - sr for v in la)) ** 2
    max_xy = math.sqrt(max_xy2)
    return RotaryDelta(home_position=home, axes_min=(-max_xy, -max_xy, min_z),
                       axes_max=(max_xy, max_xy, max_z), z_speed=zv, min_z=min_z, max_z=max_z,
                       limit_z=min(e[2] - v for e, v in zip(elbows, la, strict=True)),
                       max_xy2=max_xy2)
