"""Deltesian kinematics (Klipper ``kinematics/deltesian.py``).

Two towers (``[stepper_left]``, ``[stepper_right]``) carry arms of ``arm_length`` whose
pivots sit ``arm_x_length`` left and right of the centre: together they set X and Z (a
2-D delta); ``[stepper_y]`` is a plain Y rail. ``G28 X`` or ``G28 Z`` homes both towers
(the head ends at ``x = 0`` and the height where the arms meet when the carriages are at
their ``position_endstop``), ``G28 Y`` homes Y.

What limits a move (``DeltesianKinematics.check_move``):

* range, on each axis the move changes: X within ``±print_width/2`` (default: where the
  arms keep ``min_angle``, 5°, to the horizontal), Y within ``[stepper_y]``, Z within
  ``minimum_z_position .. z_max``; above ``z_max`` the limit is the tower tops' reach at
  that X. A move that ends at ``x = 0`` on the home height without moving Y is allowed
  anyway (the way back from ``G28``);
* the Z share: ``max_z_velocity · d/|Δz|``, ``max_z_accel · d/|Δz|``;
* near the ends of X (``slow_ratio``, default 3; 0 turns it off) Klipper means to slow a
  move that changes X down to half / a quarter of ``max_velocity`` and ``max_accel``
  past ``slow_x`` / ``very_slow_x``. **Klipper cannot run such a move**: its
  ``check_move`` reads ``self.max_velocity``, which the class never sets (Klipper
  84104bb and Kalico 2026.10 alike), so the move stops the printer with an internal
  error. flowtwin refuses it with that explanation rather than guess.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from flowtwin.planner.kinematics.base import (
    AXIS_X,
    AXIS_Z,
    MAX_LENGTH_MM,
    Kinematics,
    MoveGeometry,
    MoveLimits,
    PrinterLimits,
    Refusal,
    read_rail,
    read_z_limits,
)
from flowtwin.planner.klipper_cfg import CfgFile

__all__ = ["Deltesian", "load"]

SLOW_RATIO = 3.0
MIN_ANGLE_DEG = 5.0


@dataclass(frozen=True, kw_only=True)
class Deltesian(Kinematics):
    """A deltesian: arm geometry, the X/Y/Z limits and the slow X zones (mm)."""

    name = "deltesian"
    arm_x: tuple[float, float]
    arm2: tuple[float, float]
    abs_endstops: tuple[float, float]
    home_z: float
    limits: tuple[tuple[float, float], tuple[float, float], tuple[float, float]]
    slow_x2: float | None
    very_slow_x2: float | None

    def homed_axes(self, named: int) -> int:
        """The towers home X and Z together; a bare ``G28`` homes all."""
        if not named:
            return 7
        return named | AXIS_X | AXIS_Z if named & (AXIS_X | AXIS_Z) else named

    def pillars_z_max(self, x: np.ndarray) -> np.ndarray:
        """Highest Z the carriages allow at ``x`` (their endstops minus the arm drop)."""
        with np.errstate(invalid="ignore"):
            left = self.abs_endstops[0] - np.sqrt(self.arm2[0] - (self.arm_x[0] + x) ** 2)
            right = self.abs_endstops[1] - np.sqrt(self.arm2[1] - (self.arm_x[1] - x) ** 2)
        return np.minimum(left, right)

    def limit_moves(self, geom: MoveGeometry) -> MoveLimits:
        """Per-axis range (tower tops above ``z_max``, the way back from home); refuse
        the moves Klipper's slow-zone code cannot run."""
        kin = geom.kinematic
        start, end, d = geom.start, geom.end, geom.delta
        homing = (end[:, 0] == 0.0) & (end[:, 2] == self.home_z) & (d[:, 1] == 0.0)
        zmax = self.limits[2][1]
        top = np.where(~homing & (end[:, 2] > zmax), self.pillars_z_max(end[:, 0]), zmax)
        out = np.zeros(len(geom), dtype=np.bool_)
        for i in range(3):
            lo = self.limits[i][0]
            hi = top if i == 2 else self.limits[i][1]
            out |= (d[:, i] != 0.0) & ~((end[:, i] >= lo) & (end[:, i] <= hi))
        bad = np.flatnonzero(kin & out & ~homing)
        slow = np.zeros(len(geom), dtype=np.bool_)
        if self.slow_x2 and self.very_slow_x2:
            move_x2 = np.maximum(start[:, 0] ** 2, end[:, 0] ** 2)
            slow = kin & (d[:, 0] != 0.0) & (move_x2 > self.slow_x2)
        slow_at = np.flatnonzero(slow)
        first_bad = int(bad[0]) if bad.size else len(geom)
        first_slow = int(slow_at[0]) if slow_at.size else len(geom)
        if first_bad < first_slow:
            k = first_bad
            return MoveLimits(refused=Refusal(
                k, "Move out of range: beyond the deltesian's X/Y/Z limits",
                (float(end[k, 0]), float(end[k, 1]), float(end[k, 2])),
                " and ".join(f"{lo:g} <= {a} <= {hi:g}" for a, (lo, hi)
                             in zip("xyz", self.limits, strict=True))))
        if first_slow < len(geom):
            k = first_slow
            assert self.slow_x2 is not None
            return MoveLimits(refused=Refusal(
                k, "Klipper's deltesian kinematics fails on an X move into its slow zone "
                "(check_move reads max_velocity it never sets: an internal error that "
                "stops the printer); keep X inside the slow zone or set slow_ratio: 0",
                float(max(abs(start[k, 0]), abs(end[k, 0]))),
                f"|x| <= {math.sqrt(self.slow_x2):.6g} mm"))
        return MoveLimits()


def _meet(arm_x: tuple[float, float], arm2: tuple[float, float],
          heights: tuple[float, float]) -> tuple[float, float]:
    """X and Z where the two arms meet below pivots at ``(-arm_x0, h0)``, ``(arm_x1, h1)``."""
    px = np.array([-arm_x[0], heights[0]])
    qx = np.array([arm_x[1], heights[1]])
    dv = qx - px
    dist = float(np.hypot(dv[0], dv[1]))
    along = (arm2[0] - arm2[1] + dist * dist) / (2.0 * dist)
    across = math.sqrt(arm2[0] - along * along)
    u = dv / dist
    n = np.array([u[1], -u[0]])          # the downward normal for pivots side by side
    p = px + along * u + across * n
    return float(p[0]), float(p[1])


def load(cfg: CfgFile, printer: PrinterLimits) -> Deltesian:
    """The deltesian kinematics of a printer.cfg."""
    left_s = cfg.require("stepper_left", "[stepper_left] of a deltesian tower")
    right_s = cfg.require("stepper_right", "[stepper_right] of a deltesian tower")
    left = read_rail(left_s, need_minmax=False)
    right = read_rail(right_s, need_minmax=False, default_endstop=left.position_endstop)
    rail_y = read_rail(cfg.require("stepper_y", "[stepper_y] with position_endstop and "
                                   "position_max"))
    big = MAX_LENGTH_MM
    ax0 = left_s.getfloat("arm_x_length", above=0.0, maxval=big)
    ax1 = right_s.getfloat("arm_x_length", ax0, above=0.0, maxval=big)
    a0 = left_s.getfloat("arm_length", above=ax0, maxval=big)
    a1 = right_s.getfloat("arm_length", a0, above=ax1, maxval=big)
    arm_x, arm2 = (ax0, ax1), (a0 * a0, a1 * a1)
    pr = printer.section
    cos_angle = math.cos(math.radians(pr.getfloat("min_angle", MIN_ANGLE_DEG, minval=0.0,
                                                  maxval=90.0)))
    x_min = math.ceil(-min(ax0, cos_angle * a1 - ax1))
    x_max = math.floor(min(ax1, cos_angle * a0 - ax0))
    x_range = min(x_max - x_min, x_max * 2, -x_min * 2)
    width = pr.getfloat("print_width", 0.0, minval=0.0, maxval=x_range)
    xlim = (-width * 0.5, width * 0.5) if width else (float(x_min), float(x_max))
    abs_end = (left.position_endstop + math.sqrt(arm2[0] - ax0 * ax0),
               right.position_endstop + math.sqrt(arm2[1] - ax1 * ax1))
    home_z = _meet(arm_x, arm2, abs_end)[1]
    probe = Deltesian(arm_x=arm_x, arm2=arm2, abs_endstops=abs_end, home_z=home_z,
                      limits=(xlim, (0.0, 0.0), (0.0, 0.0)), slow_x2=None, very_slow_x2=None)
    z_max = float(np.min(probe.pillars_z_max(np.array(xlim))))
    z_min = pr.getfloat("minimum_z_position", 0.0, minval=-big, maxval=z_max)
    slow_ratio = pr.getfloat("slow_ratio", SLOW_RATIO, minval=0.0, maxval=1e3)
    slow_x2 = very_slow_x2 = None
    if slow_ratio > 0.0:
        sr2 = slow_ratio ** 2
        slow_x2 = min(math.sqrt(sr2 * a2 / (sr2 + 1.0)) - axl
                      for a2, axl in zip(arm2, arm_x, strict=True)) ** 2
        very_slow_x2 = min(math.sqrt(2.0 * sr2 * a2 / (2.0 * sr2 + 1.0)) - axl
                           for a2, axl in zip(arm2, arm_x, strict=True)) ** 2
    zv, za = read_z_limits(printer)
    limits = (xlim, (rail_y.position_min, rail_y.position_max), (z_min, z_max))
    return Deltesian(home_position=(0.0, rail_y.position_endstop, home_z),
                     axes_min=(xlim[0], rail_y.position_min, z_min),
                     axes_max=(xlim[1], rail_y.position_max, z_max), max_z_velocity=zv,
                     max_z_accel=za, arm_x=arm_x, arm2=arm2, abs_endstops=abs_end,
                     home_z=home_z, limits=limits, slow_x2=slow_x2,
                     very_slow_x2=very_slow_x2)
