"""A layout's lines, marks and filled areas on the bed, from its planned G-code.

Every printed run of the pattern (consecutive extruding moves, from the twin's plan) is
one of:

* a **test line** (the runs the pattern records as tested, one per advance factor);
* a **parallel mark**: a straight run at least half a test line long along the test
  lines (flowtwin's prime line, the frame of a framed pattern): the line finder finds it
  among the lines, so it takes part in the registration; parallel marks closer together
  than a third of the pitch (a frame drawn twice, one line width apart) are one line in
  a photo and are merged;
* a **filled area**: four or more straight strokes side by side, each within
  :data:`FILL_SPACING` line widths of the next (OrcaSlicer's number box): a photo shows a
  solid patch there, which a top-hat made for thin beads does not see, so it is kept as a
  rectangle and looked for by its fill (:mod:`.register`);
* any other **mark** (prime and anchor lines across the test lines, reference marks,
  digits, ticks), looked for by the thin-bead signal along its path.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.calibration.fits.lagmodel import LagModel, printed_runs
from flowtwin.calibration.patterns.pattern import Pattern

__all__ = ["FILL_SPACING", "LayoutGeometry", "layout_geometry"]

FloatArray = npt.NDArray[np.float64]

#: Strokes at most this many line widths apart (centre to centre) fill an area.
FILL_SPACING = 1.6
#: Fewest strokes of a filled area.
_MIN_FILL_STROKES = 4


@dataclass(frozen=True)
class LayoutGeometry:
    """A layout's lines and marks on the bed (mm).

    Attributes
    ----------
    starts, ends
        Test-line path ends, front to back, shape ``(n, 2)``.
    parallel
        ``(start, end, test_index)`` of every long line parallel to the test lines (test
        lines and parallel marks), front to back; ``test_index`` −1 for a mark.
    marks
        Paths of the other thin extrusions (polylines, ``(k, 2)`` each).
    areas
        Filled areas: ``(corners (4, 2), weight_mm)``; the weight is the length of bead
        laid there (area / line width), so an area counts as much as its strokes would.
    line_width_mm
        The pattern's line width.
    """

    starts: FloatArray
    ends: FloatArray
    parallel: tuple[tuple[FloatArray, FloatArray, int], ...]
    marks: tuple[FloatArray, ...]
    areas: tuple[tuple[FloatArray, float], ...] = ()
    line_width_mm: float = 0.45


def _fill_areas(strokes: list[FloatArray], lw: float
                ) -> tuple[list[tuple[FloatArray, float]], set[int]]:
    """Clusters of parallel strokes side by side, as rectangles; and the strokes used."""
    n = len(strokes)
    if n < _MIN_FILL_STROKES:
        return [], set()
    a = np.array([s[0] for s in strokes])
    b = np.array([s[-1] for s in strokes])
    d = b - a
    length = np.hypot(d[:, 0], d[:, 1])
    u = d / np.maximum(length, 1e-9)[:, None]
    parent = list(range(n))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i in range(n):
        for j in range(i + 1, n):
            if abs(float(u[i] @ u[j])) < 0.99:
                continue
            nrm = np.array([-u[i, 1], u[i, 0]])
            if abs(float((a[j] - a[i]) @ nrm)) > FILL_SPACING * lw:
                continue
            # overlapping along the strokes
            ti = sorted((0.0, float(length[i])))
            tj = sorted((float((a[j] - a[i]) @ u[i]), float((b[j] - a[i]) @ u[i])))
            if min(ti[1], tj[1]) - max(ti[0], tj[0]) > 0.5 * min(length[i], length[j]):
                parent[root(j)] = root(i)
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(root(i), []).append(i)
    out: list[tuple[FloatArray, float]] = []
    used: set[int] = set()
    for members in groups.values():
        if len(members) < _MIN_FILL_STROKES:
            continue
        ux = u[members[0]]
        nx = np.array([-ux[1], ux[0]])
        pts = np.vstack([a[members], b[members]])
        along = pts @ ux
        across = pts @ nx
        lo_a, hi_a = float(along.min()), float(along.max())
        lo_c, hi_c = float(across.min()) - 0.5 * lw, float(across.max()) + 0.5 * lw
        corners = np.array([lo_a * ux + lo_c * nx, hi_a * ux + lo_c * nx,
                            hi_a * ux + hi_c * nx, lo_a * ux + hi_c * nx])
        out.append((corners, float((hi_a - lo_a) * (hi_c - lo_c) / lw)))
        used.update(members)
    return out, used


def layout_geometry(pattern: Pattern, full: LagModel) -> tuple[LayoutGeometry, list[int]]:
    """The layout's lines, marks and areas from its planned G-code; the test lines' runs.

    Parameters
    ----------
    pattern
        The pattern (its test segments name the test lines).
    full
        The twin's model of every printed run of the pattern
        (:func:`~flowtwin.calibration.fits.lagmodel.lag_model` with ``gcode_lines=None``).

    Returns
    -------
    tuple
        ``(geometry, k_index)``: ``k_index[i]`` is the run of test line ``i``.
    """
    runs = printed_runs(full.plan)
    firsts = [next(s.line for s in pattern.segments if s.group == g)
              for g in range(len(pattern.values))]
    k_index = [runs.index(f) for f in firsts]
    starts = np.array([full.lines[i].vertices_xy_mm[0] for i in k_index])
    ends = np.array([full.lines[i].vertices_xy_mm[-1] for i in k_index])
    d = ends[0] - starts[0]
    length = float(np.hypot(*d))
    u = d / length
    across = np.array([-u[1], u[0]])
    pitch = (float(np.median(np.abs(np.diff(starts @ across)))) if len(k_index) > 1
             else 5.0)
    lw = pattern.settings.line_width_mm
    par: list[tuple[FloatArray, FloatArray, int]] = []
    marks_in: list[FloatArray] = []
    for r, ln in enumerate(full.lines):
        if r in k_index:
            par.append((ln.vertices_xy_mm[0], ln.vertices_xy_mm[-1], k_index.index(r)))
            continue
        v = np.asarray(ln.vertices_xy_mm, dtype=np.float64)
        pieces = [(a, b) for a, b in itertools.pairwise(v)
                  if float(np.hypot(*(b - a))) > 1e-9]
        along = [_is_along(a, b, u, length) for a, b in pieces]
        if not any(along):
            marks_in.append(v)
            continue
        # a prime line or a frame: its long pieces along the lines are registered with
        # the lines, its other pieces are marks
        for (a, b), is_par in zip(pieces, along, strict=True):
            if is_par:
                par.append((a, b, -1) if float((b - a) @ u) > 0 else (b, a, -1))
            else:
                marks_in.append(np.vstack([a, b]))
    par = _merge_close(par, across, pitch, lw)
    strokes = [i for i, m in enumerate(marks_in) if m.shape[0] == 2]
    areas, used = _fill_areas([marks_in[i] for i in strokes], lw)
    drop = {strokes[i] for i in used}
    marks = [m for i, m in enumerate(marks_in) if i not in drop]
    par.sort(key=lambda p: float(0.5 * (p[0] + p[1]) @ across))
    return LayoutGeometry(starts, ends, tuple(par), tuple(marks), tuple(areas), lw), k_index


def _is_along(a: FloatArray, b: FloatArray, u: FloatArray, length: float) -> bool:
    """A straight piece at least half a test line long, along the test lines."""
    seg = b - a
    seg_len = float(np.hypot(*seg))
    return seg_len >= 0.5 * length and abs(float(seg @ u)) >= 0.99 * seg_len


def _merge_close(par: list[tuple[FloatArray, FloatArray, int]], across: FloatArray,
                 pitch: float, lw: float) -> list[tuple[FloatArray, FloatArray, int]]:
    """Parallel marks closer than a third of the pitch (or two line widths) to another
    mark become one (a frame drawn twice, one line width apart)."""
    marks = [p for p in par if p[2] < 0]
    tests = [p for p in par if p[2] >= 0]
    marks.sort(key=lambda p: float(0.5 * (p[0] + p[1]) @ across))
    merged: list[list[tuple[FloatArray, FloatArray, int]]] = []
    for p in marks:
        off = float(0.5 * (p[0] + p[1]) @ across)
        if merged and abs(off - float(0.5 * (merged[-1][-1][0] + merged[-1][-1][1])
                                      @ across)) < max(pitch / 3.0, 2.0 * lw):
            merged[-1].append(p)
        else:
            merged.append([p])
    out = list(tests)
    for group in merged:
        a = np.mean([g[0] for g in group], axis=0)
        b = np.mean([g[1] for g in group], axis=0)
        out.append((a, b, -1))
    return out
