"""What a Klipper kinematics is to the planner, and the config helpers every one uses.

Klipper asks its kinematics about every move before the move enters the look-ahead queue
(``check_move`` in ``klippy/kinematics/*.py``; ``toolhead.py`` calls it for moves with
XYZ motion only). A kinematics can

* refuse the move (``Move out of range``): an end position it cannot reach;
* limit the move (``Move.limit_speed(v, a)``): a cap on its cruise speed and on its
  acceleration, e.g. the Z share of the move, the slow zones near a delta's edge;
* say where ``G28`` leaves the head and which axes a ``G28`` homes together.

:class:`Kinematics` holds these rules for one printer. The compiled planner applies the
two common rules itself (a per-axis box on the axes a move changes; ``max_z_velocity`` /
``max_z_accel`` times ``d/|Δz|``); anything else a kinematics computes over all moves at
once in :meth:`Kinematics.limit_moves`, before the look-ahead kernel runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import numpy.typing as npt

from flowtwin.errors import ProfileError
from flowtwin.planner.klipper_cfg import Section

__all__ = [
    "ALL_AXES",
    "AXIS_X",
    "AXIS_Y",
    "AXIS_Z",
    "MAX_LENGTH_MM",
    "Kinematics",
    "MoveGeometry",
    "MoveLimits",
    "PrinterLimits",
    "Rail",
    "Refusal",
    "read_rail",
    "read_z_limits",
    "step_distance",
    "trilaterate",
]

Vec3 = tuple[float, float, float]
FloatArray = npt.NDArray[np.float64]

#: Axis bits of a homing mask.
AXIS_X, AXIS_Y, AXIS_Z = 1, 2, 4
ALL_AXES = AXIS_X | AXIS_Y | AXIS_Z

#: Largest length the kinematics accept from a printer.cfg, mm. Klipper has no bound; this
#: keeps the geometry's squares in floating-point range and still takes a belt printer's
#: endless Z (Klipper's CR-30 config: ``position_max: 20000000``).
MAX_LENGTH_MM = 1.0e9

_INF3: Vec3 = (math.inf, math.inf, math.inf)
_NINF3: Vec3 = (-math.inf, -math.inf, -math.inf)


@dataclass(frozen=True, slots=True)
class PrinterLimits:
    """``[printer]`` values every kinematics may read.

    Attributes
    ----------
    max_velocity, max_accel
        Config values (mm/s, mm/s²); ``M204`` / ``SET_VELOCITY_LIMIT`` do not change what
        a kinematics derived from them (Klipper reads them once, at start).
    section
        The ``[printer]`` section, for kinematics-specific options.
    """

    max_velocity: float
    max_accel: float
    section: Section


@dataclass(frozen=True, slots=True)
class MoveGeometry:
    """Every move of a table as the kinematics sees it (``n`` moves, mm, mm/s).

    Attributes
    ----------
    start, end
        Start and end position of each move, ``(n, 3)``. A move shorter than 1 nm in XYZ
        is extrude-only: its end is its start (Klipper drops the motion).
    kinematic
        The move has XYZ motion (Klipper calls ``check_move`` only for these), ``(n,)``.
    length
        XYZ length, ``(n,)``.
    speed
        Cruise speed before the kinematics limits it: ``min(F, max_velocity)`` with the
        ``max_velocity`` in force when the move is queued, ``(n,)``.
    """

    start: FloatArray
    end: FloatArray
    kinematic: npt.NDArray[np.bool_]
    length: FloatArray
    speed: FloatArray

    @property
    def delta(self) -> FloatArray:
        """``end - start``, ``(n, 3)``."""
        return self.end - self.start

    def __len__(self) -> int:
        return int(self.length.shape[0])


@dataclass(frozen=True, slots=True)
class Refusal:
    """The first move a kinematics refuses (Klipper stops the print there)."""

    index: int
    message: str
    value: object
    allowed: str


@dataclass(frozen=True, slots=True)
class MoveLimits:
    """What :meth:`Kinematics.limit_moves` found.

    Attributes
    ----------
    speed, accel
        Per-move caps (``inf``: none) on cruise speed (mm/s) and acceleration (mm/s²),
        ``(n,)``, or ``None`` when the kinematics adds none.
    refused
        The first move the kinematics refuses, or ``None``.
    """

    speed: FloatArray | None = None
    accel: FloatArray | None = None
    refused: Refusal | None = None


@dataclass(frozen=True, kw_only=True)
class Kinematics:
    """One printer's kinematics: range, per-move limits and homing (mm, s).

    Attributes
    ----------
    name
        Klipper's name (``[printer] kinematics``); the module of the same name in
        :mod:`flowtwin.planner.kinematics` builds it.
    home_position
        Where ``G28`` leaves the axes it homes.
    axes_min, axes_max
        Klipper's ``axis_minimum`` / ``axis_maximum`` (the bounding box it reports).
    box_min, box_max
        Per-axis range the planner checks on every axis a move changes (Klipper's
        ``_check_endstops``); ``∓inf`` where the kinematics checks range itself.
    max_z_velocity, max_z_accel
        A move with Z motion is limited to ``max_z_velocity · d/|Δz|`` and
        ``max_z_accel · d/|Δz|``; ``inf`` for none.
    """

    name: ClassVar[str] = ""
    home_position: Vec3 = (0.0, 0.0, 0.0)
    axes_min: Vec3 = _NINF3
    axes_max: Vec3 = _INF3
    box_min: Vec3 = _NINF3
    box_max: Vec3 = _INF3
    max_z_velocity: float = math.inf
    max_z_accel: float = math.inf

    def homed_axes(self, named: int) -> int:
        """Axes a ``G28`` naming ``named`` (bits X=1, Y=2, Z=4; 0 = bare G28) homes."""
        return named or ALL_AXES

    def limit_moves(self, geom: MoveGeometry) -> MoveLimits:
        """Range checks and speed/acceleration caps beyond the box and the Z share."""
        del geom
        return MoveLimits()


# ------------------------------------------------------------------ config helpers ---

@dataclass(frozen=True, slots=True)
class Rail:
    """A rail (``[stepper_*]`` / ``[carriage *]``): homing position and range, mm."""

    name: str
    position_endstop: float
    position_min: float
    position_max: float


def read_rail(sec: Section, *, need_minmax: bool = True,
              default_endstop: float | None = None) -> Rail:
    """Klipper's ``GenericPrinterRail`` options (``klippy/stepper.py``).

    ``need_minmax=False`` (delta towers, deltesian arms): ``position_min`` is 0 and
    ``position_max`` the endstop. A probe virtual endstop needs no ``position_endstop``.
    """
    virtual = "virtual_endstop" in sec.get("endstop_pin", "")
    if virtual and default_endstop is None:
        default_endstop = 0.0
    big = MAX_LENGTH_MM
    endstop = sec.getfloat("position_endstop", default_endstop, minval=-big, maxval=big)
    if need_minmax:
        lo = sec.getfloat("position_min", 0.0, minval=-big, maxval=big)
        hi = sec.getfloat("position_max", above=lo, maxval=big)
    else:
        lo, hi = 0.0, endstop
    if not lo <= endstop <= hi:
        raise sec.error("position_endstop",
                        "position_endstop must be between position_min and position_max",
                        value=endstop, allowed=f"{lo:g} .. {hi:g}")
    return Rail(sec.name, endstop, lo, hi)


def step_distance(sec: Section, *, radians: bool = False) -> float:
    """Distance of one full step (mm, or rad): Klipper's ``parse_step_distance``.

    ``rotation_distance / (full_steps_per_rotation · microsteps · gear_ratio)``; an arm
    driven in radians (rotary delta) turns ``2π`` per rotation.
    """
    rotation = 2.0 * math.pi if radians else sec.getfloat("rotation_distance", above=0.0,
                                                          maxval=MAX_LENGTH_MM)
    micro = sec.getint("microsteps", minval=1)
    full = sec.getint("full_steps_per_rotation", 200, minval=1)
    if full % 4:
        raise sec.error("full_steps_per_rotation", "full_steps_per_rotation invalid",
                        value=full, allowed="a multiple of 4")
    gearing = 1.0
    for g1, g2 in sec.getpairs("gear_ratio"):
        if g2 == 0.0:
            raise sec.error("gear_ratio", "gear ratio with a zero", value=(g1, g2),
                            allowed="ratios 'a:b' with b != 0")
        gearing *= g1 / g2
    steps = full * micro * gearing
    if not steps > 0.0:
        raise sec.error("gear_ratio", "steps per rotation must be positive", value=steps,
                        allowed="> 0")
    return rotation / steps


def read_z_limits(printer: PrinterLimits, *, accel: bool = True) -> tuple[float, float]:
    """``[printer] max_z_velocity`` / ``max_z_accel`` (default and maximum: the XY ones)."""
    sec = printer.section
    zv = sec.getfloat("max_z_velocity", printer.max_velocity, above=0.0,
                      maxval=printer.max_velocity)
    za = (sec.getfloat("max_z_accel", printer.max_accel, above=0.0, maxval=printer.max_accel)
          if accel else math.inf)
    return zv, za


def trilaterate(centres: npt.ArrayLike, radius2: npt.ArrayLike) -> Vec3:
    """The point at squared distances ``radius2`` from three ``centres``, below them.

    Intersection of three spheres in a frame built on the centres (x along 1→2, y in
    their plane, z = x × y), taking the solution on the −z side: for a delta, the
    effector hangs below its carriages. Standard analytic geometry.
    """
    c = np.asarray(centres, dtype=np.float64).reshape(3, 3)
    r2 = np.asarray(radius2, dtype=np.float64).reshape(3)
    p1, p2, p3 = c
    ex = p2 - p1
    d = float(np.sqrt(ex @ ex))
    ex = ex / d
    i = float(ex @ (p3 - p1))
    ey = (p3 - p1) - i * ex
    ey = ey / float(np.sqrt(ey @ ey))
    ez = np.cross(ex, ey)
    j = float(ey @ (p3 - p1))
    x = (r2[0] - r2[1] + d * d) / (2.0 * d)
    y = (r2[0] - r2[2] + i * i + j * j) / (2.0 * j) - i * x / j
    h2 = r2[0] - x * x - y * y
    if not h2 >= 0.0:
        raise ProfileError("the arms cannot reach each other (no trilateration solution)",
                           field="arm_length", value=tuple(float(v) for v in r2),
                           allowed="arm lengths that meet below the carriages")
    p = p1 + x * ex + y * ey - math.sqrt(h2) * ez
    return float(p[0]), float(p[1]), float(p[2])
