"""What the firmware lets the extruder do within a printing move.

Rewriting E changes the extrusion ratio ``c = E/path`` of a piece. The firmware's planner
looks at that ratio in three ways, and a compensated file must respect all three, or the
printer either refuses it or slows down (which would also spoil the compensation, computed
for the original timing):

* **ratio jump at a junction** — Klipper limits the junction speed to
  ``instantaneous_corner_velocity / |c_k − c_p|`` (``kinematics/extruder.py``
  ``calc_junction``); Marlin's classic jerk limits the E speed change ``|c_k − c_p|·v`` to
  the E jerk (M205 E); Marlin's junction deviation (M205 J) sees the ratio change as a turn
  of the XYZE direction by about ``|Δc|`` rad, allowing ``v² ≈ 8·a·δ/Δc²``. All three are
  "``|Δc|·v ≤ J``" with the jump speed ``J`` given here;
* **largest ratio** — Klipper refuses a move above ``max_extrude_cross_section``
  (``c ≤ max_extrude_ratio``); Marlin scales a move down so the E speed stays within
  M203 E and caps the acceleration so the E acceleration stays within M201 E
  (``c ≤ v_max,E / v``, ``c ≤ a_max,E / a``);
* **moves without E** — Marlin plans a move without E with the travel acceleration
  (M204 T) and M205 T, so a printing piece keeps some E (a minimum ratio).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from flowtwin.planner.klipper_config import KlipperSettings
from flowtwin.planner.marlin import MarlinSettings

__all__ = ["ExtruderLimits", "extruder_limits"]


@dataclass(frozen=True, slots=True)
class ExtruderLimits:
    """Firmware limits on the extrusion ratio of printing moves.

    Attributes
    ----------
    firmware
        ``"klipper"`` or ``"marlin"``.
    jump_mm_s
        Largest E speed step at a junction without a slowdown, ``|Δc|·v ≤ J``, mm/s.
    max_ratio
        Largest E per path length, G-code E mm per mm (``inf``: none).
    max_e_speed_mm_s
        Largest E speed (Marlin M203 E), mm/s (``inf``: none).
    max_e_accel_mm_s2
        Largest E acceleration (Marlin M201 E), mm/s² (``inf``: none).
    tiny_e_mm
        Klipper accepts any ratio on a move with at most this much E, mm.
    e_only_speed_mm_s
        Largest speed of a move of E alone (Klipper ``max_extrude_only_velocity``, Marlin
        M203 E), mm/s.
    e_only_accel_mm_s2
        Largest E acceleration of a move of E alone (Klipper ``max_extrude_only_accel``,
        Marlin M201 E), mm/s². Klipper holds a retraction that also moves the head to
        this and ``e_only_speed_mm_s``, divided by its ratio ``|E|/path``.
    """

    firmware: str
    jump_mm_s: float
    max_ratio: float = math.inf
    max_e_speed_mm_s: float = math.inf
    max_e_accel_mm_s2: float = math.inf
    tiny_e_mm: float = 0.0
    e_only_speed_mm_s: float = math.inf
    e_only_accel_mm_s2: float = math.inf

    def as_dict(self) -> dict[str, object]:
        """Plain dict for reports (infinite values as ``None``)."""
        out: dict[str, object] = {}
        for name in self.__slots__:
            value = getattr(self, name)
            out[name] = None if isinstance(value, float) and not math.isfinite(value) else value
        return out


def extruder_limits(settings: KlipperSettings | MarlinSettings) -> ExtruderLimits:
    """The limits of a planner's settings (tool 0).

    Parameters
    ----------
    settings
        The settings the planner used (:attr:`flowtwin.planner.plan_file.PlanResult.settings`).

    Returns
    -------
    ExtruderLimits
    """
    if isinstance(settings, KlipperSettings):
        ex = settings.extruders[0]  # (resolved: Klipper's derived defaults filled in)
        return ExtruderLimits("klipper", jump_mm_s=float(ex.instantaneous_corner_velocity),
                              max_ratio=float(ex.max_extrude_ratio),
                              tiny_e_mm=float(ex.nozzle_diameter * ex.max_extrude_ratio),
                              e_only_speed_mm_s=float(ex.max_extrude_only_velocity),
                              e_only_accel_mm_s2=float(ex.max_extrude_only_accel))
    amax_e = float(settings.max_acceleration_mm_s2[3])
    if settings.junction_deviation_mm is None:
        jump = float(settings.jerk_mm_s[3])
    else:
        a = min(float(settings.print_accel_mm_s2), amax_e)
        jump = math.sqrt(8.0 * a * float(settings.junction_deviation_mm))
    return ExtruderLimits("marlin", jump_mm_s=jump,
                          max_e_speed_mm_s=float(settings.max_feedrate_mm_s[3]),
                          max_e_accel_mm_s2=amax_e,
                          e_only_speed_mm_s=float(settings.max_feedrate_mm_s[3]),
                          e_only_accel_mm_s2=amax_e)
