"""Generic cartesian kinematics (Klipper ``kinematics/generic_cartesian.py``).

Carriages (``[carriage NAME]``, one primary carriage per axis X, Y, Z; its ``axis`` is
its name when that is ``x``, ``y`` or ``z``) carry the rails, and ``[stepper NAME]``
sections drive any linear combination of them (``carriages: carriage_x+carriage_y``:
corexy, hybrids, belted machines in one description). Klipper limits a move exactly as a
cartesian one: the range box of each axis' active carriage on the axes the move changes,
and the Z share (``max_z_velocity · d/|Δz|``, ``max_z_accel · d/|Δz|``). How the
steppers combine the carriages changes no limit. A ``[dual_carriage NAME]`` on an axis
widens that axis' box to the span of both carriages (flowtwin does not follow
``SET_DUAL_CARRIAGE``; see :mod:`~flowtwin.planner.kinematics.cartesian`).
"""

from __future__ import annotations

from flowtwin.planner.kinematics.base import PrinterLimits, Rail, read_rail, read_z_limits
from flowtwin.planner.kinematics.cartesian import Cartesian
from flowtwin.planner.klipper_cfg import CfgFile, Section

__all__ = ["BOX", "GenericCartesian", "load"]

AXES = ("x", "y", "z")


class GenericCartesian(Cartesian):
    """Box of the carriages and Z share, as cartesian."""

    name = "generic_cartesian"


def _carriage_axis(sec: Section) -> str:
    short = sec.name.split()[-1]
    default = short if short in AXES else None
    if default is None and not sec.has("axis"):
        raise sec.error("axis", "a carriage not named x, y or z needs an axis",
                        allowed="axis: x, y or z")
    axis = sec.get("axis", default).strip().lower()
    if axis not in AXES:
        raise sec.error("axis", "invalid carriage axis", value=axis, allowed="x, y or z")
    return axis


#: Built from a position box alone (:func:`~flowtwin.planner.kinematics.box_kinematics`).
BOX = GenericCartesian

def load(cfg: CfgFile, printer: PrinterLimits) -> GenericCartesian:
    """The generic cartesian kinematics of a printer.cfg.

    Raises
    ------
    ProfileError
        An axis without a primary carriage or with two, a carriage without a valid axis,
        a dual carriage naming an unknown primary carriage, a bad rail value.
    """
    primary: dict[str, tuple[Rail, str]] = {}
    by_name: dict[str, str] = {}
    for sec in cfg.prefix_sections("carriage "):
        axis = _carriage_axis(sec)
        if axis in primary:
            raise sec.error("axis", f"axis '{axis}' is set for two primary carriages",
                            value=(primary[axis][1], sec.name), allowed="one per axis")
        primary[axis] = (read_rail(sec), sec.name)
        by_name[sec.name.split()[-1]] = axis
    missing = [a for a in AXES if a not in primary]
    if missing:
        raise cfg.require("printer", "").error(
            "kinematics", f"no [carriage] defined for axis '{missing[0]}'",
            value="generic_cartesian", allowed="a [carriage NAME] for each of x, y, z")
    lo = {a: primary[a][0].position_min for a in AXES}
    hi = {a: primary[a][0].position_max for a in AXES}
    for sec in cfg.prefix_sections("dual_carriage "):
        name = sec.get("primary_carriage", "").strip()
        if name:
            if name not in by_name:
                raise sec.error("primary_carriage", "primary_carriage is not a carriage",
                                value=name, allowed=", ".join(sorted(by_name)))
            axis = by_name[name]
        else:
            axis = _carriage_axis(sec)
        if axis == "z":
            raise sec.error("axis", "a dual carriage cannot move Z", value=axis,
                            allowed="x or y")
        rail = read_rail(sec)
        lo[axis] = min(lo[axis], rail.position_min)
        hi[axis] = max(hi[axis], rail.position_max)
    zv, za = read_z_limits(printer)
    home = (primary["x"][0].position_endstop, primary["y"][0].position_endstop,
            primary["z"][0].position_endstop)
    box_lo = (lo["x"], lo["y"], lo["z"])
    box_hi = (hi["x"], hi["y"], hi["z"])
    return GenericCartesian(home_position=home, axes_min=box_lo, axes_max=box_hi,
                            box_min=box_lo, box_max=box_hi, max_z_velocity=zv,
                            max_z_accel=za)
