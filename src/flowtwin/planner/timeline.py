"""The planner's output: a trapezoidal velocity profile per move and the time line.

Each move row ``i`` of a :class:`~flowtwin.gcode.moves.MoveTable` gets three phases of
constant acceleration: accelerate from ``start_v`` to ``cruise_v`` in ``accel_t``, cruise
for ``cruise_t``, decelerate to ``end_v`` in ``decel_t`` (all along the move's path, mm/s and
s). ``t_start[i]`` is when the move begins on the printer's clock, dwells and forced stops
included; homing moves and heater waits take no time in this model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import numpy.typing as npt

from flowtwin.errors import DataError
from flowtwin.gcode.groups import group_sums

if TYPE_CHECKING:
    from flowtwin.gcode.moves import MoveTable

__all__ = ["DWELL_FEATURE", "PHASE_DTYPE", "Timeline", "Trapezoids", "feature_seconds",
           "time_by_feature", "time_by_layer"]

#: Key of :func:`time_by_feature` that collects dwells and restart gaps.
DWELL_FEATURE = "(dwell)"

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


class Trapezoids(NamedTuple):
    """The velocity trapezoids of some moves as float64 arrays, shape ``(n,)``: start on the
    printer clock and phase durations, s (durations clipped at 0); speeds along the path,
    mm/s. From :meth:`Timeline.trapezoids`."""

    t_start: npt.NDArray[np.float64]
    accel_t: npt.NDArray[np.float64]
    cruise_t: npt.NDArray[np.float64]
    decel_t: npt.NDArray[np.float64]
    start_v: npt.NDArray[np.float64]
    cruise_v: npt.NDArray[np.float64]
    end_v: npt.NDArray[np.float64]


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
    stop_times_s
        Print time at each forced stop the planner was asked for (``stop_after_lines``):
        source line → s, the end of everything commanded up to and including that line.
    lines
        Source line of each move, shape ``(n_moves,)``, or ``None`` if the planner did
        not record them.
    """

    phases: npt.NDArray[np.void]
    dwell_s: list[tuple[int, float, str]] = field(default_factory=list)
    total_time_s: float = 0.0
    firmware: str = "klipper"
    warnings: list[str] = field(default_factory=list)
    stop_times_s: dict[int, float] = field(default_factory=dict)
    lines: npt.NDArray[np.int32] | None = None

    @property
    def move_time_s(self) -> npt.NDArray[np.float64]:
        """Duration of each move, s, shape ``(n_moves,)``."""
        p = self.phases
        return np.asarray(p["accel_t"] + p["cruise_t"] + p["decel_t"], dtype=np.float64)

    @property
    def end_time_s(self) -> npt.NDArray[np.float64]:
        """End of each move on the printer clock, s, shape ``(n_moves,)``."""
        return np.asarray(self.phases["t_start"], dtype=np.float64) + self.move_time_s

    def trapezoids(self, rows: npt.NDArray[np.intp] | None = None) -> Trapezoids:
        """The trapezoids of all moves (or of ``rows``) as float64 arrays (:class:`Trapezoids`)."""
        ph = self.phases if rows is None else self.phases[rows]

        def f64(name: str) -> npt.NDArray[np.float64]:
            return np.asarray(ph[name], dtype=np.float64)

        return Trapezoids(f64("t_start"), np.maximum(f64("accel_t"), 0.0),
                          np.maximum(f64("cruise_t"), 0.0), np.maximum(f64("decel_t"), 0.0),
                          f64("start_v"), f64("cruise_v"), f64("end_v"))

    def time_at_line(self, line: int) -> float:
        """Print time when the motion commanded up to ``line`` (inclusive) is done, s.

        For a line given to the planner's ``stop_after_lines`` this is the time of that
        forced stop (dwells of that line included). For any other line it is the end of
        the last move that comes from a line ``<= line`` (0 before the first move); the
        head may still be moving on into later moves then.

        Raises
        ------
        DataError
            The line was not a requested stop and the timeline has no move lines.
        """
        if line in self.stop_times_s:
            return self.stop_times_s[line]
        if self.lines is None:
            raise DataError("this timeline has no move line numbers; plan with "
                            "stop_after_lines to get the time at a line",
                            field="line", value=line)
        k = int(np.searchsorted(self.lines, line, side="right"))
        if k == 0:
            return 0.0
        return float(self.end_time_s[k - 1])


def _dwell_owner(timeline: Timeline, n: int) -> npt.NDArray[np.int64]:
    """Move index that each dwell is attributed to (the move it precedes, else the last)."""
    idx = np.array([d[0] for d in timeline.dwell_s], dtype=np.int64)
    return np.clip(idx, 0, max(n - 1, 0))


def time_by_layer(timeline: Timeline, table: MoveTable) -> dict[int, float]:
    """Print time per layer, s: move times plus dwells before a layer's moves.

    Parameters
    ----------
    timeline
        The planner's output for ``table``.
    table
        The move table (``moves["layer"]``; -1 = before the first layer).

    Returns
    -------
    dict[int, float]
        Layer index → seconds; the values sum to the timeline's motion and dwell time.
    """
    layer = np.asarray(table.moves["layer"], dtype=np.int64)
    n = layer.shape[0]
    if timeline.phases.shape[0] != n:
        raise DataError("timeline and move table have different lengths",
                        field="phases", value=timeline.phases.shape[0], allowed=f"{n} rows")
    out: dict[int, float] = {}
    if n:
        keys, inv = np.unique(layer, return_inverse=True)
        sums = np.bincount(inv, weights=timeline.move_time_s, minlength=keys.shape[0])
        if timeline.dwell_s:
            secs = np.array([d[1] for d in timeline.dwell_s])
            sums += np.bincount(inv[_dwell_owner(timeline, n)], weights=secs,
                                minlength=keys.shape[0])
        out = {int(k): float(v) for k, v in zip(keys, sums, strict=True)}
    elif timeline.dwell_s:
        out[-1] = float(sum(d[1] for d in timeline.dwell_s))
    return out


def time_by_feature(timeline: Timeline, table: MoveTable) -> dict[str, float]:
    """Move time per feature type, s, plus :data:`DWELL_FEATURE` for dwells and gaps.

    Parameters
    ----------
    timeline
        The planner's output for ``table``.
    table
        The move table (``moves["feature"]`` indexes ``table.features``; -1 = unknown,
        reported as ``"unknown"``).

    Returns
    -------
    dict[str, float]
        Feature name → seconds; the values sum to the timeline's motion and dwell time.
    """
    feature = table.moves["feature"]
    n = feature.shape[0]
    if timeline.phases.shape[0] != n:
        raise DataError("timeline and move table have different lengths",
                        field="phases", value=timeline.phases.shape[0], allowed=f"{n} rows")
    keys, _, (sums,) = group_sums(feature, timeline.move_time_s)
    return feature_seconds(table.features, keys.tolist(), sums.tolist(), timeline.dwell_s)


def feature_seconds(names: list[str], keys: list[int], seconds: list[float],
                    dwell_s: list[tuple[int, float, str]]) -> dict[str, float]:
    """Time per feature name from time per feature index (:func:`time_by_feature`).

    Parameters
    ----------
    names
        ``MoveTable.features``; an index outside it is ``"unknown"``.
    keys, seconds
        Feature indices and their move time, s (equal length).
    dwell_s
        The timeline's dwells ``(move index, s, reason)``: their sum is :data:`DWELL_FEATURE`.
    """
    out: dict[str, float] = {}
    for k, v in zip(keys, seconds, strict=True):
        name = names[k] if 0 <= k < len(names) else "unknown"
        out[name] = out.get(name, 0.0) + v
    dwell = float(sum(d[1] for d in dwell_s))
    if dwell:
        out[DWELL_FEATURE] = dwell
    return out
