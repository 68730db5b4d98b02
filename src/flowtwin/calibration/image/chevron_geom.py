"""A chevron pattern's bands on the bed, from its planned G-code.

Flowtwin's chevrons (:mod:`flowtwin.calibration.patterns.chevron`, after Andrew Ellis' pattern) are
``walls`` nested 90° corners per advance factor, touching at the line spacing, printed on
several layers. A photo from above sees the top layer: each chevron as one *band* of
its walls, two straight arms meeting at an apex. This module gives, per chevron, the
band's centreline (the mean of its walls' paths: the upper end, the apex, the lower end,
in bed mm), the band's width and the distance between neighbouring bands across the
arms, the twin's runs of the top layer's walls, and the pattern's other extrusions
(prime line, ticks) as marks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.calibration.fits.lagmodel import LagModel, printed_runs
from flowtwin.calibration.patterns.pattern import Pattern
from flowtwin.errors import CalibrationError

__all__ = ["ChevronGeometry", "chevron_geometry"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class ChevronGeometry:
    """The chevrons' bands on the bed (mm), one row per chevron (rising K).

    Attributes
    ----------
    apex, upper, lower
        The band centreline's apex and the ends of its two arms (upper: larger bed y),
        shape ``(n, 2)``.
    walls
        For each chevron, the indices into :attr:`wall_runs` of its top-layer walls.
    wall_runs
        Run index (into the twin's model of every printed run) of each top-layer wall.
    wall_paths
        Each top-layer wall's path ``(start, apex, end)``, shape ``(m, 3, 2)``.
    band_mm
        Width of a band: ``(walls − 1) × spacing + line width``.
    pitch_mm
        Distance across the arms from one band's centreline to the next.
    line_width_mm, layer_height_mm
        The pattern's bead.
    marks
        Paths of the pattern's other extrusions (polylines).
    upper_first
        Per chevron: walls printed into the apex along the upper arm less those printed
        along the lower arm first (the walls alternate; with three walls ±1).
    """

    apex: FloatArray
    upper: FloatArray
    lower: FloatArray
    walls: tuple[tuple[int, ...], ...]
    wall_runs: tuple[int, ...]
    wall_paths: FloatArray
    band_mm: float
    pitch_mm: float
    line_width_mm: float
    layer_height_mm: float
    marks: tuple[FloatArray, ...]
    upper_first: tuple[int, ...] = ()

    @property
    def arm_mm(self) -> float:
        """Length of a band's arm along its centreline, mm."""
        return float(np.median(np.hypot(*(self.upper - self.apex).T)))


def _z_of_lines(pattern: Pattern) -> dict[int, float]:
    z = 0.0
    out = {}
    for no, text in enumerate(pattern.lines, start=1):
        words = text.split(";")[0].split()
        if words and words[0] in ("G0", "G1"):
            for w in words[1:]:
                if w[0] == "Z":
                    z = float(w[1:])
        out[no] = z
    return out


def chevron_geometry(pattern: Pattern, full: LagModel) -> ChevronGeometry:
    """The bands of a chevron pattern (module docstring).

    Parameters
    ----------
    pattern
        A chevron pattern (its test segments: two arms per wall, group = chevron).
    full
        The twin's model of every printed run of the pattern.

    Raises
    ------
    CalibrationError
        A pattern whose walls are not two-armed corners.
    """
    z_of = _z_of_lines(pattern)
    runs = printed_runs(full.plan)
    n = len(pattern.values)
    top = max(z_of[sg.line] for sg in pattern.segments)
    walls: list[list[int]] = [[] for _ in range(n)]
    wall_runs: list[int] = []
    paths: list[FloatArray] = []
    for g in range(n):
        segs = [sg for sg in pattern.segments if sg.group == g]
        for a in segs[0::2]:
            if abs(z_of[a.line] - top) > 1e-6:
                continue
            if a.line not in runs:
                raise CalibrationError("a chevron wall does not start a printed run",
                                       field="pattern", value=a.line)
            r = runs.index(a.line)
            v = np.asarray(full.lines[r].vertices_xy_mm, dtype=np.float64)
            if v.shape[0] != 3:
                raise CalibrationError("a chevron wall is not two arms", field="pattern",
                                       value=v.shape[0], allowed="3 vertices per wall")
            walls[g].append(len(wall_runs))
            wall_runs.append(r)
            paths.append(v)
    if any(not w for w in walls):
        raise CalibrationError("a chevron has no wall on the top layer", field="pattern")
    wp = np.asarray(paths)
    # each wall's ends by bed y: upper (larger y) and lower
    ends_a, ends_b = wp[:, 0], wp[:, 2]
    up = np.where((ends_a[:, 1] >= ends_b[:, 1])[:, None], ends_a, ends_b)
    lo = np.where((ends_a[:, 1] >= ends_b[:, 1])[:, None], ends_b, ends_a)
    apex = np.array([wp[w, 1].mean(axis=0) for w in walls])
    upper = np.array([up[w].mean(axis=0) for w in walls])
    lower = np.array([lo[w].mean(axis=0) for w in walls])
    lw = pattern.settings.line_width_mm
    u = (upper[0] - apex[0]) / np.hypot(*(upper[0] - apex[0]))
    nrm = np.array([-u[1], u[0]])
    w0 = walls[0]
    offs = np.sort(wp[w0, 1] @ nrm)
    spacing = float(np.median(np.diff(offs))) if len(w0) > 1 else 0.0
    band = (len(w0) - 1) * spacing + lw
    pitch = float(np.median(np.abs(np.diff(apex @ nrm)))) if n > 1 else 3.0 * band
    starts_up = wp[:, 0, 1] >= wp[:, 2, 1]
    upper_first = tuple(int(sum(1 if starts_up[i] else -1 for i in w)) for w in walls)
    test_runs = set(runs.index(sg.line) for sg in pattern.segments if sg.line in runs)
    marks = tuple(np.asarray(ln.vertices_xy_mm, dtype=np.float64)
                  for r, ln in enumerate(full.lines) if r not in test_runs)
    return ChevronGeometry(apex, upper, lower, tuple(tuple(w) for w in walls),
                           tuple(wall_runs), wp, float(band), pitch, lw,
                           pattern.settings.layer_height_mm, marks, upper_first)
