"""The planner's output: a trapezoidal velocity profile per move and the time line.

Each move row ``i`` of a :class:`~flowtwin.gcode.moves.MoveTable` gets three phases of
constant acceleration: accelerate from ``start_v`` to ``cruise_v`` in ``accel_t``, cruise
for ``cruise_t``, decelerate to ``end_v`` in ``decel_t`` (all along the move's path, mm/s and
s). ``t_start[i]`` is when the move begins on the printer's clock, dwells and forced stops
included; homing moves and heater waits take no time in this model.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

__all__ = ["PHASE_DTYPE", "Timeline"]

#: One row per move: 48 bytes + t_start.
PHASE_DTYPE = np.dtype([
    ("t_start", np.float64),   # s, start of the move on the printer clock
    ("start_v", np.float32),   # mm/s along the path
    ("cruise_v", np.float32),
    ("end_v", np.float32),
    ("accel", np.float32),     # mm/s^2 used for the accel and decel phases
    ("accel_t", np.float64),   # s
    ("cruise_t", np.float64),
    ("decel_t", np.float64),
])


@dataclass(slots=True)
class Timeline:
    """Velocity profile of every move and the total time.

    Attributes
    ----------
    phases
        Structured array of :data:`PHASE_DTYPE`, shape ``(n_moves,)``, aligned with the
        move table.
    dwell_s
        Time spent in dwells and firmware pauses that are not moves, per event, as
        ``(move_index, seconds, reason)``.
    total_time_s
        All motion and dwells, excluding homing and heater waits.
    firmware
        ``"klipper"`` or ``"marlin"``.
    warnings
        Counted, non-fatal problems (e.g. a move beyond the printer's limits), with lines.
    """

    phases: npt.NDArray[np.void]
    dwell_s: list[tuple[int, float, str]] = field(default_factory=list)
    total_time_s: float = 0.0
    firmware: str = "klipper"
    warnings: list[str] = field(default_factory=list)

    @property
    def move_time_s(self) -> npt.NDArray[np.float64]:
        """Duration of each move, s, shape ``(n_moves,)``."""
        p = self.phases
        return np.asarray(p["accel_t"] + p["cruise_t"] + p["decel_t"], dtype=np.float64)
