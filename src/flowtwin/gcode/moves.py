"""The columnar move table: the reader's output and the planner's input.

One row per straight segment the firmware would execute (arcs are linearised by the
reader, firmware retractions expanded). Positions are *toolhead* coordinates in mm
(after G92 offsets and G20 inch conversion): the start of row ``i`` is the end of row
``i - 1`` (row 0 starts at :attr:`MoveTable.start_xyze`).

Non-motion commands that matter to a planner or to the physics (accelerations, dwells,
tool changes, temperatures, pressure advance, ...) are kept in order as :class:`Event`
objects with the index of the move they precede; the planner decides what each means for
its firmware (e.g. Klipper ignores ``M204 P`` alone, Marlin does not).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import IntFlag

import numpy as np
import numpy.typing as npt

__all__ = ["MOVE_DTYPE", "Event", "MoveKind", "MoveTable"]


class MoveKind(IntFlag):
    """Bit flags of a move row (column ``kind``)."""

    TRAVEL = 1        #: no extrusion (``de == 0``)
    EXTRUDE = 2       #: ``de > 0``
    RETRACT = 4       #: ``de < 0``
    XY = 8            #: has X/Y motion
    Z = 16            #: has Z motion
    ARC = 32          #: segment of a linearised G2/G3
    FW_RETRACT = 64   #: generated from G10/G11 firmware retraction
    RAPID = 128       #: came from G0


#: numpy dtype of one move row (aligned: 72 bytes per move; fields by name, not position).
MOVE_DTYPE = np.dtype([
    ("x", np.float64),         # end position, mm
    ("y", np.float64),
    ("z", np.float64),
    ("e", np.float64),         # end extruder position of this row's tool, mm of filament,
                               # G-code units (before the M221 flow factor)
    ("de", np.float64),        # E change of this row, mm of filament (before M221)
    ("feed_mm_s", np.float64), # requested speed, F/60 times the M220 factor, mm/s
    ("line", np.int32),        # 1-based source line number
    ("layer", np.int32),       # 0-based layer index, -1 before the first layer
    ("flow", np.float32),      # M221 extrusion factor in force (1.0 = 100 %)
    ("tool", np.int16),        # active tool number as written (T255/T1000 kept as such)
    ("feature", np.int16),     # index into MoveTable.features, -1 = unknown
    ("kind", np.uint8),        # MoveKind flags
], align=True)


@dataclass(frozen=True, slots=True)
class Event:
    """A non-motion command kept for the planner and the physics.

    Attributes
    ----------
    move_index
        Number of move rows that precede this command (it takes effect before that row).
    line
        1-based source line.
    code
        Upper-case command (``"M204"``, ``"G4"``, ``"SET_VELOCITY_LIMIT"``, ``"T1"``, ...).
    params
        Parameter letters (or Klipper ``NAME=``) mapped to their float value, or to the
        raw string where the value is not a number (``"M221 S"`` gives ``{"S": ""}``).
    """

    move_index: int
    line: int
    code: str
    params: dict[str, float | str] = field(default_factory=dict)


@dataclass(slots=True)
class MoveTable:
    """Moves, events and what was learnt about the file.

    Attributes
    ----------
    moves
        Structured array of :data:`MOVE_DTYPE`, shape ``(n_moves,)``.
    events
        Non-motion commands in file order.
    start_xyze
        Toolhead position before the first row, mm, shape ``(4,)``.
    features
        Names of feature types (``moves["feature"]`` indexes this list).
    layer_z
        Z (mm) of each layer, indexed by ``moves["layer"]``.
    metadata
        Slicer metadata found in comments (slicer name, layer height, nozzle and filament
        diameters, line widths, the slicer's own time and filament estimates, ...).
    unknown_commands
        Commands the reader did not interpret, with counts.
    warnings
        Counted, non-fatal problems, each with a line number.
    source
        File name or ``"<stdin>"``.
    n_lines
        Number of lines read.
    """

    moves: npt.NDArray[np.void]
    events: list[Event]
    start_xyze: npt.NDArray[np.float64]
    features: list[str] = field(default_factory=list)
    layer_z: list[float] = field(default_factory=list)
    metadata: dict[str, object] = field(default_factory=dict)
    unknown_commands: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    source: str = "<input>"
    n_lines: int = 0

    def __len__(self) -> int:
        return int(self.moves.shape[0])

    def net_filament_mm(self) -> dict[int, float]:
        """Net filament per tool as written in the G-code E words (before M221).

        Firmware retractions (``G10``/``G11``) are motions of the extruder but not
        filament the G-code asks for, so they are not counted here.
        """
        from flowtwin.gcode.groups import group_sums  # a numba kernel: loaded when used

        written = (self.moves["kind"] & MoveKind.FW_RETRACT) == 0
        tools, _, (sums,) = group_sums(self.moves["tool"], np.where(written, self.moves["de"], 0.0))
        return {int(t): float(v) for t, v in zip(tools.tolist(), sums.tolist(), strict=True)}
