"""Strand-lag trajectory correction [004]: the nozzle path that lays the intended road.

The soft strand leaves the nozzle at height ``H`` and touches the road a distance ``L``
behind it (a tractrix [004 Eq. 5]; ``L`` where it has sunk to 0.5 % of ``H``,
:func:`flowtwin.physics.strand.tractrix_contact_length_mm`, ≈ 5·H). The road end ``R``
pursues the nozzle ``N`` at the distance ``L`` (:mod:`flowtwin.physics.pursuit`), so a
nozzle that follows the road itself cuts every corner. To lay a road point ``P`` with unit
tangent ``t̂`` the nozzle must be at ``P + L·t̂`` [004 Eqs. 9, 19]. For a polyline road
(what G-code is) that nozzle path is:

* every segment shifted forward along itself by ``L`` (the nozzle runs ``L`` ahead of the
  road end on a straight line [004 Eqs. 10–11]);
* at every vertex ``V`` a pivot: the nozzle swings on the circle of radius ``L`` about
  ``V`` from the incoming to the outgoing direction while the road end rests at ``V``
  (in the pursuit model ``dR/dt = ê·(ê·dN/dt) = 0`` when the nozzle moves across ``ê``);
  on a fine polygon of a circle this converges to [004 Eq. 15]'s circle of radius
  ``sqrt(r² + L²)``;
* a lead-in of ``L`` along the first segment before extrusion starts, so that the road
  starts where it should.

``L`` is capped at ``max_shift_mm`` (the bound on how far the nozzle path may leave the
original path; with the cap the correction is partial, and the laid roads of the report are
computed with the uncapped strand lag). Every original move keeps its E
exactly: the pivots and the lead-in print a small share (``pivot_flow_fraction`` of the
move's ratio) taken from the move's own segment, so the runs stay unbroken. The laid road
of both paths is computed with the pursuit model and reported (largest and mean distance
from the intended road).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.compensation.advance import eligible_rows
from flowtwin.compensation.draft import Draft
from flowtwin.errors import GcodeError, ProfileError
from flowtwin.gcode.moves import MoveKind
from flowtwin.physics.pursuit import laid_road, polyline_distance_mm
from flowtwin.physics.strand import tractrix_contact_length_mm
from flowtwin.simulation import SimulationResult

__all__ = ["TrajectoryOptions", "TrajectoryReport", "bend_paths", "road_deviation"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class TrajectoryOptions:
    """How to bend the nozzle paths.

    Attributes
    ----------
    max_shift_mm
        Largest distance the nozzle path may move from the original path, mm (caps ``L``).
    lag_mm
        Strand lag ``L``, mm; ``None``: from the tractrix at each move's layer height.
    min_turn_deg
        Vertices turning less than this get no pivot (the segments are joined directly).
    pivot_step_deg
        Largest turn of one pivot chord, degrees.
    pivot_flow_fraction
        E ratio of pivot and lead-in pieces as a fraction of their move's ratio.
    evaluate_runs
        Printing runs whose laid road is computed for the report (the first ones).
    """

    max_shift_mm: float = 0.5
    lag_mm: float | None = None
    min_turn_deg: float = 2.0
    pivot_step_deg: float = 15.0
    pivot_flow_fraction: float = 0.05
    evaluate_runs: int = 400

    def __post_init__(self) -> None:
        checks = {
            "max_shift_mm": (self.max_shift_mm, 0.0 <= self.max_shift_mm <= 5.0, "0 .. 5 mm"),
            "min_turn_deg": (self.min_turn_deg, 0.0 <= self.min_turn_deg < 90.0, "0 .. 90"),
            "pivot_step_deg": (self.pivot_step_deg, 1.0 <= self.pivot_step_deg <= 90.0,
                               "1 .. 90"),
            "pivot_flow_fraction": (self.pivot_flow_fraction,
                                    0.0 < self.pivot_flow_fraction <= 1.0, "0 < f <= 1"),
            "evaluate_runs": (self.evaluate_runs, 0 <= self.evaluate_runs <= 100000,
                              "0 .. 100000"),
        }
        if self.lag_mm is not None:
            checks["lag_mm"] = (self.lag_mm, 0.0 <= self.lag_mm <= 5.0, "0 .. 5 mm")
        for name, (value, ok, allowed) in checks.items():
            if not (ok and math.isfinite(float(value))):
                raise ProfileError("invalid trajectory option", field=name, value=value,
                                   allowed=allowed)

    @property
    def is_identity(self) -> bool:
        """The options change nothing."""
        return self.max_shift_mm == 0.0 or self.lag_mm == 0.0


@dataclass(frozen=True, slots=True)
class TrajectoryReport:
    """What the trajectory stage did.

    Attributes
    ----------
    runs
        Printing runs bent.
    pivots
        Vertices given a pivot.
    lag_mm
        Mean strand lag used (after the cap), mm.
    strand_lag_mm
        Mean strand lag of the tractrix at the moves' layer heights (before the cap), mm:
        the laid roads are computed with it.
    max_shift_mm
        Largest distance of the new nozzle path from the original path, mm.
    road_deviation_before_mm, road_deviation_after_mm
        Largest distance of the laid road from the intended road (pursuit model), mm,
        over the evaluated runs.
    road_mean_deviation_before_mm, road_mean_deviation_after_mm
        Mean of that distance, mm.
    evaluated_runs
        Runs the deviations were computed on.
    """

    runs: int
    pivots: int
    lag_mm: float
    strand_lag_mm: float
    max_shift_mm: float
    road_deviation_before_mm: float
    road_deviation_after_mm: float
    road_mean_deviation_before_mm: float
    road_mean_deviation_after_mm: float
    evaluated_runs: int

    def as_dict(self) -> dict[str, object]:
        """Plain dict."""
        return {name: getattr(self, name) for name in self.__slots__}


def _unit(v: FloatArray) -> FloatArray:
    n = float(np.hypot(v[0], v[1]))
    return v / n if n > 0 else np.zeros(2)


def road_deviation(nozzle_xy_mm: FloatArray, road_xy_mm: FloatArray, *,
                   lag_mm: float) -> tuple[float, float]:
    """Largest and mean distance of the road a nozzle path lays from an intended road.

    Parameters
    ----------
    nozzle_xy_mm
        Nozzle polyline, mm, shape ``(M, 2)``.
    road_xy_mm
        Intended road polyline, mm, shape ``(K, 2)``.
    lag_mm
        Strand lag ``L``, mm (> 0).

    Returns
    -------
    tuple of float
        Max and mean distance, mm (pursuit model, :func:`flowtwin.physics.pursuit.laid_road`),
        over the road laid once the nozzle has moved ``L`` (before that the strand of the
        model is still hanging from where the nozzle started).
    """
    steps = np.diff(np.asarray(nozzle_xy_mm, dtype=np.float64), axis=0)
    longest = float(np.max(np.hypot(steps[:, 0], steps[:, 1]), initial=0.0))
    # samples every L/20 at most (the corner transient lasts ~L), 8 to 400 per segment
    per_segment = int(np.clip(np.ceil(longest / (0.05 * lag_mm)), 8, 400))
    laid = laid_road(nozzle_xy_mm, lag_mm=lag_mm, samples_per_segment=per_segment)
    keep = laid.nozzle_s_mm >= lag_mm * (1.0 - 1e-9)
    if not np.any(keep):
        return 0.0, 0.0
    d = polyline_distance_mm(laid.road_xy_mm[keep], road_xy_mm)
    return float(np.max(d)), float(np.mean(d))


def bend_paths(draft: Draft, sim: SimulationResult,
               options: TrajectoryOptions) -> tuple[Draft, TrajectoryReport]:
    """Replace every printing run's path by the nozzle path that lays it (module docstring).

    Parameters
    ----------
    draft
        The draft; ``sim`` is its rendered file simulated (rows = pieces).
    sim
        Simulation of the draft (layer heights per move).
    options
        Cap and discretisation.

    Returns
    -------
    tuple
        The bent draft and a :class:`TrajectoryReport`.

    Raises
    ------
    GcodeError
        The file uses relative XYZ (``G91``) in a printing move: shifted end points would
        move every later relative move.
    """
    n = len(draft)
    kind = sim.plan.table.moves["kind"]
    orig_elig = eligible_rows(draft.table, draft.row_e)
    printing = orig_elig[draft.row] & ((kind & MoveKind.XY) != 0) & (draft.e_grid > 0)
    start = draft.start_xyz()
    end = draft.xyz_mm
    height = np.asarray(sim.parameters.layer_height_mm, dtype=np.float64)
    if options.lag_mm is not None:
        lag_phys = np.full(n, options.lag_mm)
    else:
        lag_phys = np.asarray(tractrix_contact_length_mm(np.maximum(height, 1e-6)),
                              dtype=np.float64)
    lag = np.minimum(lag_phys, options.max_shift_mm)
    relative = printing & ~draft.original.abs_xyz[draft.row]
    if np.any(relative):
        ln = int(draft.table.moves["line"][draft.row[np.argmax(relative)]])
        raise GcodeError("the trajectory correction needs absolute XYZ (G90) in printing "
                         "moves", source=draft.original.source, line=ln, value="G91",
                         allowed="G90")
    # runs: consecutive printing pieces at one Z
    same_z = np.concatenate(([False], np.abs(end[1:, 2] - end[:-1, 2]) < 1e-9))
    cont = printing & np.concatenate(([False], printing[:-1])) & same_z
    run_start = printing & ~cont
    piece_of: list[int] = []
    pts: list[FloatArray] = []
    es: list[int] = []
    pivots = 0
    runs = 0
    max_shift = 0.0
    lag_sum = 0.0
    eval_pairs: list[tuple[FloatArray, FloatArray, float]] = []  # (road, nozzle, real L)
    min_turn = math.radians(options.min_turn_deg)
    step = math.radians(options.pivot_step_deg)
    i = 0
    while i < n:
        if not run_start[i]:
            piece_of.append(i)
            pts.append(end[i])
            es.append(int(draft.e_grid[i]))
            i += 1
            continue
        j = i
        while j + 1 < n and cont[j + 1]:
            j += 1
        L = float(np.mean(lag[i:j + 1]))
        runs += 1
        lag_sum += L
        new_pts, new_piece, new_e, n_piv, shift = _bend_run(
            start, end, draft.e_grid, i, j, L, min_turn, step, options.pivot_flow_fraction)
        pivots += n_piv
        max_shift = max(max_shift, shift)
        piece_of.extend(new_piece)
        pts.extend(new_pts)
        es.extend(new_e)
        if len(eval_pairs) < options.evaluate_runs and L > 0:
            road = np.vstack([start[i, :2], end[i:j + 1, :2]])
            nozzle = np.vstack([start[i, :2]] + [p[:2] for p in new_pts])
            eval_pairs.append((road, nozzle, float(np.mean(lag_phys[i:j + 1]))))
        i = j + 1
    before: list[tuple[float, float]] = []
    after: list[tuple[float, float]] = []
    for road, nozzle, L in eval_pairs:
        if road.shape[0] < 2:
            continue
        before.append(road_deviation(road, road, lag_mm=L))
        after.append(road_deviation(nozzle, road, lag_mm=L))
    report = TrajectoryReport(
        runs=runs, pivots=pivots, lag_mm=lag_sum / runs if runs else 0.0,
        strand_lag_mm=float(np.mean([p[2] for p in eval_pairs])) if eval_pairs else 0.0,
        max_shift_mm=max_shift,
        road_deviation_before_mm=max((b[0] for b in before), default=0.0),
        road_deviation_after_mm=max((a[0] for a in after), default=0.0),
        road_mean_deviation_before_mm=float(np.mean([b[1] for b in before])) if before else 0.0,
        road_mean_deviation_after_mm=float(np.mean([a[1] for a in after])) if after else 0.0,
        evaluated_runs=len(before))
    new = draft.split(np.asarray(piece_of, dtype=np.int64), np.vstack(pts),
                      np.asarray(es, dtype=np.int64))
    return new, report


def _bend_run(start: FloatArray, end: FloatArray, e_grid: IntArray, i: int, j: int, lag: float,
              min_turn: float, step: float, pivot_fraction: float
              ) -> tuple[list[FloatArray], list[int], list[int], int, float]:
    """Nozzle pieces of the run of rows ``i..j`` (see the module docstring)."""
    pts: list[FloatArray] = []
    owner: list[int] = []
    seg_len: list[float] = []
    dirs = []
    for k in range(i, j + 1):
        d = end[k, :2] - start[k, :2]
        dirs.append(_unit(d))
        seg_len.append(float(np.hypot(d[0], d[1])))
    for k in range(1, len(dirs)):  # zero-length segments take the previous direction
        if not np.any(dirs[k]):
            dirs[k] = dirs[k - 1]
    max_shift = 0.0
    pivots = 0
    entries: list[tuple[int, FloatArray, bool]] = []  # (row, end point, is_segment)
    z0 = start[i, 2]
    lead = start[i, :2] + lag * dirs[0]
    entries.append((i, np.array([lead[0], lead[1], z0]), False))
    for idx, k in enumerate(range(i, j + 1)):
        u = dirs[idx]
        p_end = end[k, :2] + lag * u
        entries.append((k, np.array([p_end[0], p_end[1], end[k, 2]]), True))
        max_shift = max(max_shift, lag)
        if idx + 1 < len(dirs):
            v = dirs[idx + 1]
            turn = math.atan2(u[0] * v[1] - u[1] * v[0], float(u @ v))
            if abs(turn) >= min_turn:
                pivots += 1
                n_ch = max(1, int(math.ceil(abs(turn) / step)))
                a0 = math.atan2(u[1], u[0])
                for c in range(1, n_ch + 1):
                    a = a0 + turn * c / n_ch
                    q = end[k, :2] + lag * np.array([math.cos(a), math.sin(a)])
                    entries.append((k, np.array([q[0], q[1], end[k, 2]]), False))
    # E: every row keeps its E; extra pieces print a small share of the row's ratio
    prev = np.array([start[i, 0], start[i, 1]])
    lengths = []
    for _row, p, _seg in entries:
        lengths.append(float(np.hypot(p[0] - prev[0], p[1] - prev[1])))
        prev = p[:2]
    row_seg_len = {k: 0.0 for k in range(i, j + 1)}
    for (row, _p, is_seg), ln in zip(entries, lengths, strict=True):
        if is_seg:
            row_seg_len[row] += ln
    e_out: list[int] = []
    extra_e: dict[int, int] = {k: 0 for k in range(i, j + 1)}
    for (row, _p, is_seg), ln in zip(entries, lengths, strict=True):
        if is_seg:
            e_out.append(0)  # filled below
            continue
        total = int(e_grid[row])
        ratio = total / max(seg_len[row - i], 1e-9)
        e = max(int(round(pivot_fraction * ratio * ln)), 1)
        e = min(e, max(total - 1 - extra_e[row], 0))
        extra_e[row] += e
        e_out.append(e)
    for idx, (row, _p, is_seg) in enumerate(entries):
        if is_seg:
            e_out[idx] = int(e_grid[row]) - extra_e[row]
    for (row, p, _seg) in entries:
        pts.append(p)
        owner.append(row)
    return pts, owner, e_out, pivots, max_shift
