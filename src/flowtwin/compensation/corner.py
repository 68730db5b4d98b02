"""What Klipper's extruder corner velocity costs a compensated file.

Klipper limits the speed of a junction between two moves whose E per mm of path differ by
``Δρ`` to ``instantaneous_corner_velocity/|Δρ|`` (``kinematics/extruder.py``
``calc_junction``; 1 mm/s by default). An advance baked into the G-code changes the ratio
from piece to piece, which is what it is for, and on a fast Klipper print those junctions
then cost print time: +24.9 % on check4's PrusaSlicer honeycomb at 180–280 mm/s, of which
a larger corner velocity gives back nearly all (docs/compensation.md, "Session 14"). The
written file is planned again with larger values of that one setting; the planner is the
same (exact) one, so the times are what the printer would take for this very file. The
figures of a file compensated *for* the larger value differ a little (its junctions were
refined on the slower plan): compensate again with the changed ``printer.cfg``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from flowtwin.planner.klipper_config import KlipperSettings
from flowtwin.planner.plan_file import PlanResult, plan_table

__all__ = ["CORNER_CANDIDATES_MM_S", "CORNER_REPORT_SHARE", "CornerVelocityCost",
           "corner_velocity_cost"]

#: Corner velocities the file is planned again with, mm/s of filament (ascending).
CORNER_CANDIDATES_MM_S: tuple[float, ...] = (2.0, 3.0, 5.0, 10.0)
#: Print-time increase over the original above which the cost is looked at (fraction).
CORNER_REPORT_SHARE = 0.05


@dataclass(frozen=True, slots=True)
class CornerVelocityCost:
    """The compensated file's print time at larger extruder corner velocities.

    Attributes
    ----------
    corner_velocity_mm_s
        ``instantaneous_corner_velocity`` of the printer the file was compensated for
        (tool 0), mm/s.
    time_before_s, time_after_s
        Print time of the original and of the compensated file, s.
    times_s
        ``(corner velocity, print time of the compensated file with it)`` for every
        candidate above the current one, up to the first that brings the increase within
        :data:`CORNER_REPORT_SHARE` (mm/s, s).
    """

    corner_velocity_mm_s: float
    time_before_s: float
    time_after_s: float
    times_s: tuple[tuple[float, float], ...]

    def as_dict(self) -> dict[str, object]:
        """Plain JSON-able values."""
        return {"instantaneous_corner_velocity_mm_s": self.corner_velocity_mm_s,
                "time_at_corner_velocity_s": {f"{v:g}": t for v, t in self.times_s}}

    def note(self) -> str:
        """One line for the user: what the setting costs and what to change."""
        def pct(t: float) -> str:
            return f"{100.0 * (t / self.time_before_s - 1.0):+.1f} %"

        alts = ", ".join(f"{pct(t)} with {v:g} mm/s" for v, t in self.times_s)
        return (f"print time {pct(self.time_after_s)}: Klipper slows the junctions where "
                f"the advance steps the E ratio (instantaneous_corner_velocity "
                f"{self.corner_velocity_mm_s:g} mm/s in [extruder]); this file would take "
                f"{alts}. A larger value lets the extruder motor change speed more "
                "abruptly at a junction: raise it only as far as your extruder follows "
                "without skipping, in printer.cfg, and compensate again with that file")


def corner_velocity_cost(after: PlanResult, time_before_s: float, *,
                         candidates: tuple[float, ...] = CORNER_CANDIDATES_MM_S
                         ) -> CornerVelocityCost | None:
    """The compensated file planned again with larger extruder corner velocities.

    Parameters
    ----------
    after
        The compensated file's plan.
    time_before_s
        Print time of the original file, s (> 0).
    candidates
        Corner velocities to try, mm/s, ascending.

    Returns
    -------
    CornerVelocityCost or None
        ``None`` unless the file was planned for Klipper and takes more than
        :data:`CORNER_REPORT_SHARE` longer than the original, or when no larger
        corner velocity would make it faster.
    """
    settings = after.settings
    time_after_s = float(after.timeline.total_time_s)
    if (not isinstance(settings, KlipperSettings) or time_before_s <= 0.0
            or time_after_s <= (1.0 + CORNER_REPORT_SHARE) * time_before_s):
        return None
    current = float(settings.extruders[0].instantaneous_corner_velocity)
    times: list[tuple[float, float]] = []
    for v in candidates:
        if v <= current:
            continue
        faster = replace(settings, extruders=tuple(
            replace(ex, instantaneous_corner_velocity=v) for ex in settings.extruders))
        t = float(plan_table(after.table, faster, printer=after.printer)
                  .timeline.total_time_s)
        times.append((v, t))
        if t <= (1.0 + CORNER_REPORT_SHARE) * time_before_s:
            break
    if not times or times[-1][1] >= time_after_s * (1.0 - 1e-3):
        return None
    return CornerVelocityCost(current, float(time_before_s), time_after_s, tuple(times))
