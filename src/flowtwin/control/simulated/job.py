"""A print job for the twin printer: a G-code file read and planned once, in program time.

The twin prints a job physically (:class:`~flowtwin.control.simulated.runner.JobRunner`). What
the G-code asks for does not depend on the loop, so it is prepared once with flowtwin's
own reader, planner and feed model: the commanded extruder position against *program
time* ``τ`` (the planner's clock at 100 % speed, :func:`flowtwin.dynamics.nominal_feed`),
the layer height of every move, and the heater commands with the program time at which
they act. The speed multiplier (``M220``) then makes program time run at
``speed/100`` of clock time; ``M109`` stops it until the nozzle is at its set point.
"""

from __future__ import annotations

import bisect
import functools
import math
import os
from dataclasses import dataclass
from enum import StrEnum
from typing import BinaryIO

import numpy as np
import numpy.typing as npt

from flowtwin.dynamics import CommandedFeed, nominal_feed
from flowtwin.errors import GcodeError
from flowtwin.gcode.moves import MoveKind
from flowtwin.planner.plan_file import plan_gcode
from flowtwin.profiles.machine import Machine
from flowtwin.simulation.parameters import layer_heights_mm

__all__ = ["HeaterCommand", "PrintJob", "WaitMode"]


class WaitMode(StrEnum):
    """How a heater command waits (Marlin semantics)."""

    NONE = "none"   #: ``M104``: set and go on
    HEAT = "heat"   #: ``M109 S``: wait only if the nozzle is colder than the set point
    BOTH = "both"   #: ``M109 R``: wait until reached, heating or cooling


@dataclass(frozen=True, slots=True)
class HeaterCommand:
    """A nozzle set point taking effect at program time ``tau_s`` (line ``line``)."""

    tau_s: float
    set_c: float
    wait: WaitMode
    line: int


def _num(value: object) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value)


@dataclass(frozen=True)
class PrintJob:
    """A planned G-code: commanded filament against program time, layers, heater commands.

    Build it with :meth:`from_gcode`.

    Attributes
    ----------
    source
        File name of the G-code.
    feed
        Commanded extruder motion at 100 % speed (filament mm, M221 of the G-code in).
    move_t0_s
        Program time at which each move starts, s, shape ``(n_moves,)``.
    layer
        Layer index of each move (``-1`` before the first layer), shape ``(n_moves,)``.
    layer_height_mm
        Layer height of each move, mm, shape ``(n_moves,)``.
    heater
        Heater commands in program order.
    part_start_s
        Program time of the first move of layer 0 (what comes before — a prime line — is
        not part of the printed object), s.
    end_s
        Program time at which the G-code is done, s.
    """

    source: str
    feed: CommandedFeed
    move_t0_s: npt.NDArray[np.float64]
    layer: npt.NDArray[np.int64]
    layer_height_mm: npt.NDArray[np.float64]
    heater: tuple[HeaterCommand, ...]
    part_start_s: float
    end_s: float

    @classmethod
    def from_gcode(cls, source: str | os.PathLike[str] | bytes | BinaryIO, *,
                   machine: Machine, name: str | None = None) -> PrintJob:
        """Read and plan ``source`` for ``machine``'s printer.

        Parameters
        ----------
        source
            G-code path, bytes or binary stream.
        machine
            The set-up (its printer profile plans the moves; its layer height is the
            default where the G-code gives none).
        name
            What to call the job (default: the file name, ``<bytes>`` for bytes).

        Returns
        -------
        PrintJob

        Raises
        ------
        GcodeError
            Unreadable G-code, or a file without extrusion.
        """
        plan = plan_gcode(source, printer=machine.printer)
        table = plan.table
        if len(table) == 0 or not np.any((table.moves["kind"] & MoveKind.EXTRUDE) != 0):
            raise GcodeError("the print job extrudes nothing", source=table.source,
                             allowed="G-code with extruding G1/G2/G3 moves")
        feed = nominal_feed(table, plan.timeline)
        t_start = np.asarray(plan.timeline.phases["t_start"], dtype=np.float64)
        default_h = machine.setup.layer_height_mm or 0.2
        heights = layer_heights_mm(table, default_mm=default_h,
                                   max_mm=machine.hotend.nozzle_diameter_mm)
        layer = table.moves["layer"].astype(np.int64)
        end = max(feed.t_end_s, float(t_start[-1]))
        heater: list[HeaterCommand] = []
        for ev in table.events:
            if ev.code not in ("M104", "M109"):
                continue
            tool = _num(ev.params.get("T"))
            if tool is not None and int(tool) != 0:
                continue
            s_val, r_val = _num(ev.params.get("S")), _num(ev.params.get("R"))
            target = r_val if r_val is not None else s_val
            if target is None:
                continue
            if ev.code == "M104":
                mode = WaitMode.NONE
            else:
                mode = WaitMode.BOTH if r_val is not None else WaitMode.HEAT
            tau = float(t_start[ev.move_index]) if ev.move_index < len(table) else end
            heater.append(HeaterCommand(tau, max(target, 0.0), mode, ev.line))
        in_part = np.flatnonzero(layer >= 0)
        part_start = float(t_start[in_part[0]]) if in_part.size else 0.0
        return cls(source=name or table.source, feed=feed, move_t0_s=t_start, layer=layer,
                   layer_height_mm=np.asarray(heights, dtype=np.float64),
                   heater=tuple(heater), part_start_s=part_start, end_s=end)

    @property
    def commanded_mm(self) -> float:
        """Net filament the G-code commands (retractions cancel), mm."""
        return float(self.feed.e_end_mm() - self.feed.e_start_mm)

    def position_mm(self, tau_s: float) -> float:
        """Commanded extruder position at program time ``tau_s``, mm (held outside)."""
        t0, dt, coef, e0 = self._segments
        if not t0:
            return self.feed.e_start_mm
        if tau_s <= t0[0]:
            return self.feed.e_start_mm if tau_s < t0[0] else e0[0]
        i = bisect.bisect_right(t0, tau_s) - 1
        tau = min(tau_s - t0[i], dt[i])
        c0, c1, c2, c3 = coef[i]
        return e0[i] + tau * (c0 + tau * (0.5 * c1 + tau * (c2 / 3.0 + tau * 0.25 * c3)))

    @functools.cached_property
    def _segments(self) -> tuple[list[float], list[float], list[tuple[float, ...]],
                                 list[float]]:
        """The feed's segments as Python lists (a scalar lookup per twin step is cheaper
        than a NumPy call)."""
        f = self.feed
        return (f.t0_s.tolist(), f.dt_s.tolist(), [tuple(r) for r in f.coef.tolist()],
                f.e0_mm.tolist())

    def move_at(self, tau_s: float) -> int:
        """Index of the move running at program time ``tau_s`` (the last one at the end)."""
        starts = self._moves[0]
        i = bisect.bisect_right(starts, tau_s) - 1
        return min(max(i, 0), len(starts) - 1)

    def layer_height_at(self, tau_s: float) -> float:
        """Layer height of the move running at ``tau_s``, mm."""
        return self._moves[1][self.move_at(tau_s)]

    def layer_at(self, tau_s: float) -> int:
        """Layer index of the move running at ``tau_s`` (``-1`` before the first layer)."""
        return self._moves[2][self.move_at(tau_s)]

    @functools.cached_property
    def _moves(self) -> tuple[list[float], list[float], list[int]]:
        return (self.move_t0_s.tolist(), self.layer_height_mm.tolist(), self.layer.tolist())

    def next_heater_index(self, tau_s: float) -> int:
        """Index of the first heater command at or after ``tau_s``."""
        return bisect.bisect_left([h.tau_s for h in self.heater], tau_s)

    def first_set_point_c(self) -> float | None:
        """The first non-zero nozzle set point, °C (None if the G-code sets none)."""
        for h in self.heater:
            if h.set_c > 0.0 and math.isfinite(h.set_c):
                return h.set_c
        return None
