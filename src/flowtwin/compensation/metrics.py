"""Flow figures of a compensated file against the *original* intent.

The twin scores a move by ``delivered / commanded − 1``
(:meth:`flowtwin.simulation.SimulationResult.summary`: ``rms_flow_error`` is the
volume-weighted RMS of that over the extruding XY moves, ``peak_overextrusion`` its
maximum). In a compensated file a move has become pieces whose E is *deliberately*
not the intent, so the pieces of every original move are summed and compared with what the
original move meant: ``Σ delivered(pieces) / commanded(original) − 1``. For an unchanged
file this is exactly the twin's own figure (tested).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.errors import DataError
from flowtwin.gcode.moves import MoveKind
from flowtwin.simulation import SimulationResult

__all__ = ["FlowFigures", "extruding_moves", "flow_figures"]

IntArray = npt.NDArray[np.int64]


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
    """

    rms_flow_error: float
    peak_overextrusion: float
    peak_underextrusion: float
    delivered_volume_mm3: float
    intended_volume_mm3: float
    flow_error: npt.NDArray[np.float64]

    def as_dict(self) -> dict[str, float]:
        """Scalar figures (JSON-ready)."""
        return {"rms_flow_error": self.rms_flow_error,
                "peak_overextrusion": self.peak_overextrusion,
                "peak_underextrusion": self.peak_underextrusion,
                "delivered_volume_mm3": self.delivered_volume_mm3,
                "intended_volume_mm3": self.intended_volume_mm3}


def extruding_moves(original: SimulationResult) -> npt.NDArray[np.bool_]:
    """The moves the twin scores: extruding, with XY motion, commanding a volume."""
    m = original.plan.table.moves
    cmd = original.dynamics.moves["cmd_mm3"]
    return (((m["kind"] & MoveKind.EXTRUDE) != 0) & ((m["kind"] & MoveKind.XY) != 0)
            & (cmd > 0))


def flow_figures(original: SimulationResult, compensated: SimulationResult,
                 piece_row: IntArray) -> FlowFigures:
    """Flow figures of ``compensated`` against the intent of ``original``.

    Parameters
    ----------
    original
        The original file simulated (its moves are the intent).
    compensated
        The compensated file simulated (its moves are pieces of the original's).
    piece_row
        Original move of every compensated move, shape ``(n_pieces,)``.

    Returns
    -------
    FlowFigures

    Raises
    ------
    DataError
        The piece map does not fit the compensated moves.
    """
    n = len(original.plan.table)
    out = compensated.dynamics.moves["out_mm3"]
    if piece_row.shape != out.shape:
        raise DataError("piece map does not match the compensated moves",
                        field="piece_row", value=piece_row.shape, allowed=str(out.shape))
    delivered = np.bincount(piece_row, weights=out, minlength=n)
    cmd = original.dynamics.moves["cmd_mm3"]
    ext = extruding_moves(original)
    # the twin's own flow error needs a bead (a path and a duration); same selection here
    bead = ext & np.isfinite(original.metrics["width_nominal_mm"])
    err = np.zeros(n)
    err[bead] = delivered[bead] / cmd[bead] - 1.0
    w = cmd[ext]
    e = err[ext]
    rms = float(np.sqrt(np.sum(w * e * e) / np.sum(w))) if w.size and np.sum(w) > 0 else 0.0
    return FlowFigures(rms, float(np.max(e, initial=0.0)) if e.size else 0.0,
                       float(-np.min(e, initial=0.0)) if e.size else 0.0,
                       float(np.sum(delivered[ext])), float(np.sum(cmd[ext])), err)
