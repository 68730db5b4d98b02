"""Klipper's kinematics, one module each, as they limit moves.

A module here is named as Klipper names the kinematics (``[printer] kinematics:
delta`` → :mod:`flowtwin.planner.kinematics.delta`) and has a ``load(cfg, printer)``
function that reads its sections of a ``printer.cfg`` and returns a
:class:`~flowtwin.planner.kinematics.base.Kinematics`. Adding a kinematics is adding a
module: :func:`names` lists every module of this package but ``base`` and private ones.
"""

from __future__ import annotations

import importlib
import pkgutil
from functools import cache

from flowtwin.errors import ProfileError
from flowtwin.planner.kinematics.base import Kinematics, PrinterLimits
from flowtwin.planner.klipper_cfg import CfgFile

__all__ = ["Kinematics", "PrinterLimits", "box_kinematics", "load_kinematics", "names"]

Vec3 = tuple[float, float, float]


@cache
def names() -> tuple[str, ...]:
    """Every kinematics flowtwin models (module names of this package)."""
    return tuple(sorted(m.name for m in pkgutil.iter_modules(__path__)
                        if not m.name.startswith("_") and m.name != "base"))


def load_kinematics(name: str, cfg: CfgFile, printer: PrinterLimits) -> Kinematics:
    """Build the kinematics ``name`` from a parsed printer.cfg.

    Raises
    ------
    ProfileError
        ``name`` is not a kinematics flowtwin models (the message lists them; it points at
        ``[printer] kinematics``), or a value the kinematics reads is missing or invalid.
    """
    if name not in names():
        raise printer.section.error("kinematics",
                                    "kinematics not supported by the Klipper planner",
                                    value=name, allowed=", ".join(names()))
    module = importlib.import_module(f"{__name__}.{name}")
    kin = module.load(cfg, printer)
    if not isinstance(kin, Kinematics):  # pragma: no cover - a module's programming error
        raise ProfileError("kinematics module returned no Kinematics", field="kinematics",
                           value=name)
    return kin


def box_kinematics(name: str, *, home: Vec3, lo: Vec3, hi: Vec3, max_z_velocity: float,
                   max_z_accel: float, source: str | None = None) -> Kinematics:
    """A cartesian-like kinematics from its range box, homing position and Z limits.

    Raises
    ------
    ProfileError
        ``name`` is not modelled, or its limits need more than a box (a delta's towers,
        a polar arm ...): those come from a printer.cfg (:func:`load_kinematics`).
    """
    if name not in names():
        raise ProfileError("kinematics not supported by the Klipper planner", source=source,
                           field="kinematics", value=name, allowed=", ".join(names()))
    module = importlib.import_module(f"{__name__}.{name}")
    cls = getattr(module, "BOX", None)
    if cls is None:
        boxes = [n for n in names()
                 if getattr(importlib.import_module(f"{__name__}.{n}"), "BOX", None)]
        raise ProfileError(f"the {name} kinematics needs its geometry: load it from a "
                           "printer.cfg (load_printer_cfg) or pass kin=", source=source,
                           field="kinematics", value=name,
                           allowed="without kin=: " + ", ".join(boxes))
    kin: Kinematics = cls(home_position=home, axes_min=lo, axes_max=hi, box_min=lo,
                          box_max=hi, max_z_velocity=max_z_velocity, max_z_accel=max_z_accel)
    return kin
