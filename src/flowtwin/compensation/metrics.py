"""Flow figures of a compensated file against the *original* intent.

The twin scores a move by ``delivered / commanded − 1``
(:meth:`flowtwin.simulation.SimulationResult.summary`: ``rms_flow_error`` is the
volume-weighted RMS of that over the extruding XY moves, ``peak_overextrusion`` its
maximum). In a compensated file a move has become pieces whose E is *deliberately*
not the intent, so the pieces of every original move are summed and compared with what the
original move meant: ``Σ delivered(pieces) / commanded(original) − 1``. For an unchanged
file this is exactly the twin's own figure (tested).

The per-move peak is the ratio of two numbers that can both be tiny (slicers write moves of
a few micrometres with 10⁻⁴ mm of E); a move of 0.07 mm whose ratio is +100 % is not a
bulge of the part. The melt leaves the orifice as a strand of the nozzle's diameter ``d``
and is pressed into the bead under the nozzle [001 bead cross-section, 004 strand model]:
an excess of volume is spread along the path over at least ``d``. The *windowed* peak
(:func:`window_peak`) is therefore the largest over-extrusion of any stretch of
continuously printed path ``d`` long (the whole stretch where it is shorter): the
physically defined "peak corner over-extrusion". It never exceeds the per-move peak (a
window's ratio is a volume-weighted mean of its moves' ratios); both are reported.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.errors import DataError
from flowtwin.gcode.moves import MoveKind, MoveTable
from flowtwin.simulation import SimulationResult, SimulationSummary
from flowtwin.simulation.windowed import windowed_flow

__all__ = ["FlowFigures", "Intent", "extruding_moves", "flow_figures", "flow_score", "window_peak"]

IntArray = npt.NDArray[np.int64]
FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class FlowFigures:
    """Flow error of a print against an intent.

    Attributes
    ----------
    rms_flow_error
        Volume-weighted RMS of the per-move flow error (fraction).
    peak_overextrusion
        Largest per-move flow error (fraction; negative when every move under-extrudes).
    peak_underextrusion
        Largest per-move shortfall, ``−min(flow error)`` (fraction).
    delivered_volume_mm3
        Melt delivered by the extruding moves (their pieces), mm³.
    intended_volume_mm3
        What those moves meant, mm³.
    flow_error
        Per original move: flow error (0 where the move does not extrude),
        shape ``(n_moves,)``.
    peak_overextrusion_window
        Largest over-extrusion of any ``window_mm`` of continuously printed path
        (:func:`window_peak`; fraction, ``nan`` when no window was asked for).
    window_mm
        Length of those windows, mm (the nozzle diameter; ``nan``: none).
    """

    rms_flow_error: float
    peak_overextrusion: float
    peak_underextrusion: float
    delivered_volume_mm3: float
    intended_volume_mm3: float
    flow_error: npt.NDArray[np.float64]
    peak_overextrusion_window: float = float("nan")
    window_mm: float = float("nan")

    def as_dict(self) -> dict[str, float]:
        """Scalar figures (JSON-ready)."""
        return {"rms_flow_error": self.rms_flow_error,
                "peak_overextrusion": self.peak_overextrusion,
                "peak_underextrusion": self.peak_underextrusion,
                "delivered_volume_mm3": self.delivered_volume_mm3,
                "intended_volume_mm3": self.intended_volume_mm3,
                "peak_overextrusion_window": self.peak_overextrusion_window,
                "window_mm": self.window_mm}


@dataclass(frozen=True, slots=True)
class Intent:
    """What is read of the original file's simulation once its figures are taken, so that
    the simulation itself can be let go (:func:`Intent.of`).

    Attributes
    ----------
    table
        The original's move table (its moves are the intent).
    cmd_mm3, width_nominal_mm, lag_k_s
        Per original move: commanded melt volume (mm³), nominal bead width (mm, ``nan``
        without a bead), the twin's lag factor ``K`` (s); shape ``(n_moves,)``.
    before
        The original's flow figures against itself, windowed over ``window_mm``.
    summary
        The original's whole-print figures.
    warnings
        The original's simulation warnings.
    time_s
        The original's planned print time, s.
    """

    table: MoveTable
    cmd_mm3: FloatArray
    width_nominal_mm: FloatArray
    lag_k_s: FloatArray
    before: FlowFigures
    summary: SimulationSummary
    warnings: tuple[str, ...]
    time_s: float

    @classmethod
    def of(cls, original: SimulationResult, *, window_mm: float) -> Intent:
        """The intent of ``original`` (its arrays copied out of its records)."""
        n = len(original.plan.table)
        return cls(original.plan.table,
                   np.array(original.dynamics.moves["cmd_mm3"], dtype=np.float64),
                   np.array(original.metrics["width_nominal_mm"], dtype=np.float64),
                   np.array(original.parameters.params.lag_k_s, dtype=np.float64),
                   flow_figures(original, original, np.arange(n, dtype=np.int64),
                                window_mm=window_mm),
                   original.summary(), tuple(original.warnings),
                   float(original.plan.timeline.total_time_s))


def _read_intent(original: SimulationResult | Intent
                 ) -> tuple[MoveTable, npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """The table, commanded volume and nominal width of ``original``."""
    if isinstance(original, Intent):
        return original.table, original.cmd_mm3, original.width_nominal_mm
    return original.plan.table, original.dynamics.moves["cmd_mm3"], \
        original.metrics["width_nominal_mm"]


def extruding_moves(original: SimulationResult | Intent) -> npt.NDArray[np.bool_]:
    """The moves the twin scores: extruding, with XY motion, commanding a volume."""
    table, cmd, _ = _read_intent(original)
    m = table.moves
    return (((m["kind"] & MoveKind.EXTRUDE) != 0) & ((m["kind"] & MoveKind.XY) != 0)
            & (cmd > 0))


def flow_figures(original: SimulationResult | Intent, compensated: SimulationResult,
                 piece_row: IntArray, *, window_mm: float | None = None) -> FlowFigures:
    """Flow figures of ``compensated`` against the intent of ``original``.

    Parameters
    ----------
    original
        The original file simulated (its moves are the intent), or its :class:`Intent`.
    compensated
        The compensated file simulated (its moves are pieces of the original's).
    piece_row
        Original move of every compensated move, shape ``(n_pieces,)``.
    window_mm
        Also compute the windowed peak over this length of printed path, mm (the nozzle
        diameter; see :func:`window_peak`); ``None``: not computed (``nan``).

    Returns
    -------
    FlowFigures

    Raises
    ------
    DataError
        The piece map does not fit the compensated moves, or ``window_mm`` is not positive.
    """
    tab, cmd, width = _read_intent(original)
    n = len(tab)
    out = compensated.dynamics.moves["out_mm3"]
    if piece_row.shape != out.shape:
        raise DataError("piece map does not match the compensated moves",
                        field="piece_row", value=piece_row.shape, allowed=str(out.shape))
    delivered = np.asarray(np.bincount(piece_row, weights=out, minlength=n), dtype=np.float64)
    ext = extruding_moves(original)
    # the twin's own flow error needs a bead (a path and a duration); same selection here
    bead = ext & np.isfinite(width)
    err = np.zeros(n)
    err[bead] = delivered[bead] / cmd[bead] - 1.0
    w = cmd[ext]
    e = err[ext]
    rms = float(np.sqrt(np.sum(w * e * e) / np.sum(w))) if w.size and np.sum(w) > 0 else 0.0
    peak_w = float("nan")
    if window_mm is not None:
        if not (np.isfinite(window_mm) and window_mm > 0.0):
            raise DataError("window length must be positive", field="window_mm",
                            value=window_mm, allowed="> 0 mm")
        xyz = np.column_stack([tab.moves["x"], tab.moves["y"], tab.moves["z"]]).astype(
            np.float64)
        start = np.vstack([np.asarray(tab.start_xyze[:3], dtype=np.float64)[None, :],
                           xyz[:-1]]) if n else xyz
        path = np.sqrt(np.sum((xyz - start) ** 2, axis=1))
        peak_w = window_peak(path, cmd, delivered, bead & (path > 0), window_mm=window_mm)
    return FlowFigures(rms, float(np.max(e, initial=0.0)) if e.size else 0.0,
                       float(-np.min(e, initial=0.0)) if e.size else 0.0,
                       float(np.sum(delivered[ext])), float(np.sum(cmd[ext])), err,
                       peak_w, float("nan") if window_mm is None else float(window_mm))


def window_peak(path_mm: npt.NDArray[np.float64], commanded_mm3: npt.NDArray[np.float64],
                delivered_mm3: npt.NDArray[np.float64], printed: npt.NDArray[np.bool_], *,
                window_mm: float) -> float:
    """Largest over-extrusion of any ``window_mm`` of continuously printed path.

    Consecutive ``printed`` moves form a stretch of continuous path. Within a move, the
    commanded and the delivered volume are taken as spread evenly along its path (the twin
    resolves a move as a whole). For a window ``[s, s + W]`` of a stretch the figure is
    ``delivered(window) / commanded(window) − 1``; both are piecewise linear in ``s``, so
    the ratio is monotonic between the positions where a window edge meets a move end, and
    the maximum over all windows is found by evaluating exactly those positions. A stretch
    shorter than ``W`` is one window. ``W`` is one nozzle diameter: the melt leaves as a
    strand of that diameter and is pressed into the bead under the nozzle [001, 004], so an
    excess of volume shows on the part spread over at least that length of path.
    (The computation is :func:`flowtwin.simulation.windowed.windowed_flow`'s, which also
    gives the under-extrusion and where the worst windows are.)

    Parameters
    ----------
    path_mm
        Path length of every move, mm, shape ``(n,)``.
    commanded_mm3, delivered_mm3
        Commanded (intended) and delivered melt volume of every move, mm³, ``(n,)``.
    printed
        Moves that print a bead (path > 0, commanded > 0), shape ``(n,)``.
    window_mm
        Window length ``W``, mm (> 0).

    Returns
    -------
    float
        The largest window flow error (fraction; 0 when nothing prints).
    """
    return windowed_flow(path_mm, commanded_mm3, delivered_mm3, printed, window_mm=window_mm,
                         spots=0).peak_over


def flow_score(before: FlowFigures, after: FlowFigures) -> float:
    """The larger of two ratios, after over before, of the RMS flow error and of the
    windowed peak over-extrusion (the smaller the better; a ratio whose ``before`` is 0
    counts 0; ``after`` must have the windowed peak)."""
    rms = after.rms_flow_error / before.rms_flow_error if before.rms_flow_error > 0 else 0.0
    peak = before.peak_overextrusion_window
    win = max(after.peak_overextrusion_window, 0.0) / peak if peak > 0 else 0.0
    return max(rms, win)
