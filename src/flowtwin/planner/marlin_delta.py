"""Marlin on a linear delta: the segments it cuts every move into, and its tower motion.

Marlin 2.x does not plan a delta move as one block (``Marlin/src/module/motion.cpp``,
``line_to_destination_kinematic``; read to understand, written anew here). A move with
XY motion is cut into ``segments = max(1, trunc(S · L / F))`` equal pieces, ``L`` its XYZ
length (its ``|ΔE|`` when ``L`` is below 1 µm), ``F`` its feed rate (× M220) and ``S``
``DEFAULT_SEGMENTS_PER_SECOND`` (``M665 S``); a move without XY motion (Z and/or E only)
is one piece. Each piece enters the planner with its cartesian length (the planner
"hint") but its three *tower* distances: ``M203`` / ``M201`` limits and classic jerk apply
to the carriages, junction deviation to the cartesian direction (``HAS_DIST_MM_ARG``).
A carriage stands at ``z + sqrt(rod² − (x − tx)² − (y − ty)²)`` over the effector, the
towers at ``DELTA_RADIUS`` (+ trim) and 210°, 330°, 90° (+ ``DELTA_TOWER_ANGLE_TRIM``).

Marlin computes in 32-bit floats on most boards; the segment count is computed the same
way here (``float32``), the positions in double precision.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.errors import GcodeError, ProfileError
from flowtwin.gcode.moves import Event, MoveTable

__all__ = ["SEGMENTED_KEY", "MarlinDelta", "segment_moves", "tower_distances"]

Vec3 = tuple[float, float, float]

#: ``MoveTable.metadata`` key :func:`segment_moves` sets (its segments per second).
SEGMENTED_KEY = "marlin_delta_segments_per_second"

#: Marlin's ``UNEAR_ZERO``: shorter XYZ moves count their E distance instead, mm.
_NEAR_ZERO_MM = 1e-6


@dataclass(frozen=True, slots=True)
class MarlinDelta:
    """Delta geometry and segmentation of a Marlin build (``Configuration.h``, mm).

    Attributes
    ----------
    radius_mm
        ``DELTA_RADIUS`` (``M665 R``): horizontal rod span with the effector centred.
    diagonal_rod_mm
        ``DELTA_DIAGONAL_ROD`` (``M665 L``).
    segments_per_second
        ``DEFAULT_SEGMENTS_PER_SECOND`` (``M665 S``).
    printable_radius_mm
        ``PRINTABLE_RADIUS`` (``DELTA_PRINTABLE_RADIUS`` before 2.1.3): a move ending
        farther out is refused.
    height_mm
        ``DELTA_HEIGHT``: where ``G28`` leaves the nozzle (X0 Y0).
    tower_angle_trim_deg, radius_trim_mm, diagonal_rod_trim_mm
        ``DELTA_TOWER_ANGLE_TRIM``, ``DELTA_RADIUS_TRIM_TOWER``,
        ``DELTA_DIAGONAL_ROD_TRIM_TOWER`` (towers A, B, C).
    """

    radius_mm: float
    diagonal_rod_mm: float
    segments_per_second: float
    printable_radius_mm: float
    height_mm: float
    tower_angle_trim_deg: Vec3 = (0.0, 0.0, 0.0)
    radius_trim_mm: Vec3 = (0.0, 0.0, 0.0)
    diagonal_rod_trim_mm: Vec3 = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in ("radius_mm", "diagonal_rod_mm", "segments_per_second",
                     "printable_radius_mm", "height_mm"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ProfileError("invalid Marlin delta setting", field=name, value=value,
                                   allowed="> 0 (finite)")
        rods = [self.diagonal_rod_mm + t for t in self.diagonal_rod_trim_mm]
        radii = [self.radius_mm + t for t in self.radius_trim_mm]
        if min(rods) <= max(radii) + self.printable_radius_mm:
            raise ProfileError("the diagonal rods cannot reach the printable radius",
                               field="diagonal_rod_mm", value=self.diagonal_rod_mm,
                               allowed=f"> {max(radii) + self.printable_radius_mm:g} "
                               "(radius + printable radius)")

    @property
    def towers(self) -> npt.NDArray[np.float64]:
        """XY of the towers A, B, C, ``(3, 2)``, mm."""
        out = np.empty((3, 2))
        for i, base in enumerate((210.0, 330.0, 90.0)):
            a = math.radians(base + self.tower_angle_trim_deg[i])
            r = self.radius_mm + self.radius_trim_mm[i]
            out[i] = (math.cos(a) * r, math.sin(a) * r)
        return out

    def carriage_heights(self, xyz: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Height of each carriage over the nozzle plus Z for positions ``(n, 3)``:
        ``(n, 3)``, mm (Marlin's ``inverse_kinematics``)."""
        t = self.towers
        rod2 = np.array([(self.diagonal_rod_mm + tr) ** 2 for tr in self.diagonal_rod_trim_mm])
        dx = t[None, :, 0] - xyz[:, 0, None]
        dy = t[None, :, 1] - xyz[:, 1, None]
        return xyz[:, 2, None] + np.sqrt(rod2[None, :] - dx * dx - dy * dy)


def _starts(table: MoveTable) -> npt.NDArray[np.float64]:
    m = table.moves
    end = np.column_stack((m["x"], m["y"], m["z"]))
    return np.vstack((np.asarray(table.start_xyze[:3], dtype=np.float64)[None, :], end[:-1]))


def segment_moves(table: MoveTable, delta: MarlinDelta) -> MoveTable:
    """Cut every move with XY motion into Marlin's delta segments.

    Parameters
    ----------
    table
        Moves as read (``n`` rows).
    delta
        The printer's geometry and ``segments_per_second``.

    Returns
    -------
    MoveTable
        One row per segment (positions interpolated, the move's E shared equally and
        summing to it exactly, the other columns copied); events point at the segment
        row their move starts at; ``metadata[SEGMENTED_KEY]`` records the segmentation.

    Raises
    ------
    GcodeError
        A move with XY motion ends beyond ``printable_radius_mm``.

    Notes
    -----
    Row ``i`` starts where row ``i − 1`` ends (the move table's convention, which the
    Marlin planner model shares): after a ``G28`` the first move is measured from the
    position before homing.
    """
    m = table.moves
    n = len(m)
    start = _starts(table) if n else np.zeros((0, 3))
    end = np.column_stack((m["x"], m["y"], m["z"])) if n else np.zeros((0, 3))
    d = end - start
    r2 = end[:, 0] ** 2 + end[:, 1] ** 2
    far = np.flatnonzero(((d[:, 0] != 0.0) | (d[:, 1] != 0.0))
                         & (r2 > delta.printable_radius_mm ** 2 + 1e-9))
    if far.size:
        j = int(far[0])
        raise GcodeError("move ends beyond the delta's printable radius (Marlin clamps it "
                         "to the radius with software endstops on, else drops it)",
                         source=table.source, line=int(m["line"][j]), field="XY",
                         value=(float(end[j, 0]), float(end[j, 1])),
                         allowed=f"x² + y² <= {delta.printable_radius_mm:g}²")
    # segment count as Marlin computes it, in 32-bit floats
    d32 = d.astype(np.float32)
    cart = np.sqrt(np.sum(d32 * d32, axis=1, dtype=np.float32), dtype=np.float32)
    cart = np.where(cart < _NEAR_ZERO_MM, np.abs(m["de"]).astype(np.float32), cart)
    with np.errstate(divide="ignore", invalid="ignore"):
        seconds = cart / m["feed_mm_s"].astype(np.float32)
        raw = np.float32(delta.segments_per_second) * seconds
    raw = np.where(np.isfinite(raw), raw, 1.0)
    count = np.clip(np.floor(raw), 1, 65535).astype(np.int64)
    count = np.where((d[:, 0] == 0.0) & (d[:, 1] == 0.0), 1, count)
    total = int(count.sum())
    first = np.concatenate(([0], np.cumsum(count)[:-1])) if n else np.zeros(0, np.int64)
    src = np.repeat(np.arange(n), count)
    k = np.arange(total) - first[src] + 1                       # 1 .. count within a move
    frac = k / count[src]
    last = k == count[src]
    out = m[src].copy()
    e_start = m["e"] - m["de"]
    for axis, col in enumerate("xyz"):
        out[col] = np.where(last, end[src, axis], start[src, axis] + d[src, axis] * frac)
    e_end = np.where(last, m["e"][src], e_start[src] + m["de"][src] * frac)
    e_prev = np.where(k == 1, e_start[src], np.roll(e_end, 1))
    out["e"] = e_end
    out["de"] = e_end - e_prev
    index = np.append(first, total)
    events = [Event(int(index[min(max(ev.move_index, 0), n)]), ev.line, ev.code, ev.params)
              for ev in table.events]
    meta = dict(table.metadata)
    meta[SEGMENTED_KEY] = delta.segments_per_second
    return MoveTable(moves=out, events=events, start_xyze=table.start_xyze.copy(),
                     features=list(table.features), layer_z=list(table.layer_z),
                     metadata=meta, unknown_commands=dict(table.unknown_commands),
                     warnings=list(table.warnings), source=table.source,
                     n_lines=table.n_lines)


def tower_distances(table: MoveTable, delta: MarlinDelta) -> npt.NDArray[np.float64]:
    """Distance each carriage travels in each move, ``(n, 3)``, mm.

    Raises
    ------
    GcodeError
        A position the rods cannot reach (the message names its line).
    """
    m = table.moves
    if not len(m):
        return np.zeros((0, 3))
    end = np.column_stack((m["x"], m["y"], m["z"]))
    with np.errstate(invalid="ignore"):
        h_end = delta.carriage_heights(end)
        h_start = delta.carriage_heights(_starts(table))
    bad = np.flatnonzero(~np.all(np.isfinite(h_end), axis=1))
    if bad.size:
        k = int(bad[0])
        raise GcodeError("position out of the delta's reach", source=table.source,
                         line=int(m["line"][k]), field="XYZ", value=tuple(end[k].tolist()),
                         allowed=f"within {delta.printable_radius_mm:g} mm of the centre")
    return np.nan_to_num(h_end - h_start)
