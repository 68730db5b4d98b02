"""Where a print over- and under-extrudes: windows of one nozzle diameter of path, located
in the G-code.

:func:`result_windowed` computes a simulation's windowed flow figures
(:func:`flowtwin.simulation.windowed.windowed_flow` on the moves the twin scores);
:func:`locate_spots` turns its worst windows into :class:`Spot` objects with G-code lines,
layer, feature, excess volume, bead widths and whether they follow a retraction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from flowtwin.errors import DataError
from flowtwin.gcode.moves import MoveKind
from flowtwin.simulation import SimulationResult
from flowtwin.simulation.windowed import Window, WindowedFlow, path_lengths_mm, windowed_flow

__all__ = ["Spot", "locate_spots", "move_paths_mm", "result_windowed"]

_BEAD = 1.0 - math.pi / 4.0
_PRINTING = int(MoveKind.EXTRUDE | MoveKind.XY)


@dataclass(frozen=True, slots=True)
class Spot:
    """One window of one nozzle diameter of path, located in the G-code.

    Attributes
    ----------
    error
        Flow error over the window, delivered / commanded − 1 (fraction).
    excess_mm3
        Delivered − commanded melt over the window, mm³.
    length_mm
        Path length of the window, mm.
    line, line_first, line_last
        G-code line of the move at the window's middle, of its first and its last move.
    layer, z_mm, feature
        Where it is.
    width_nominal_mm, width_predicted_mm
        Bead width the G-code means and the twin predicts over the window, mm.
    after_retraction
        The window starts a printed stretch that follows a retraction (a seam or a restart).
    """

    error: float
    excess_mm3: float
    length_mm: float
    line: int
    line_first: int
    line_last: int
    layer: int
    z_mm: float
    feature: str
    width_nominal_mm: float
    width_predicted_mm: float
    after_retraction: bool


def result_windowed(result: SimulationResult, *, delivered_mm3: npt.ArrayLike | None = None,
                    window_mm: float | None = None, spots: int = 10) -> WindowedFlow:
    """Windowed flow error of a simulation over one nozzle diameter of path.

    The moves scored are the twin's (extruding, with XY motion, a commanded volume and a
    bead), as :func:`flowtwin.compensation.metrics.flow_figures` scores them.

    Parameters
    ----------
    result
        The simulation.
    delivered_mm3
        Delivered melt per move of ``result`` (default: the simulation's own); a
        compensated file's delivery mapped onto the original moves gives its figures
        against the original intent. Shape ``(n_moves,)``.
    window_mm
        Window length, mm (default: the nozzle diameter of the simulated machine).
    spots
        Worst separate windows to locate each way.
    """
    tab = result.plan.table
    m = tab.moves
    xyz = np.column_stack([m["x"], m["y"], m["z"]]).astype(np.float64)
    path = path_lengths_mm(xyz, np.asarray(tab.start_xyze[:3], dtype=np.float64))
    cmd = np.asarray(result.dynamics.moves["cmd_mm3"], dtype=np.float64)
    dlv = (np.asarray(result.dynamics.moves["out_mm3"], dtype=np.float64)
           if delivered_mm3 is None else np.asarray(delivered_mm3, dtype=np.float64))
    kind = m["kind"].astype(np.int64)
    printed = (((kind & _PRINTING) == _PRINTING) & (cmd > 0)
               & np.isfinite(result.metrics["width_nominal_mm"]) & (path > 0))
    w = float(window_mm if window_mm is not None else result.nozzle_diameter_mm)
    if not math.isfinite(w):
        meta = tab.metadata.get("nozzle_diameter_mm", tab.metadata.get("nozzle_diameter"))
        try:
            w = float(str(meta).split(",")[0])
        except ValueError:
            raise DataError("the nozzle diameter of this simulation is unknown",
                            field="nozzle_diameter_mm", value=meta,
                            allowed="a result of flowtwin.simulation.simulate, or window_mm"
                            ) from None
    return windowed_flow(path, cmd, dlv, printed, window_mm=w, spots=spots)


def locate_spots(result: SimulationResult, windowed: WindowedFlow,
                 path_mm: npt.NDArray[np.float64] | None = None
                 ) -> tuple[tuple[Spot, ...], tuple[Spot, ...]]:
    """The worst windows of ``windowed`` (figures on ``result``'s moves) located in the
    G-code: ``(over, under)``, worst first."""
    path = move_paths_mm(result) if path_mm is None else path_mm
    return (tuple(_spot(result, w, path) for w in windowed.worst_over),
            tuple(_spot(result, w, path) for w in windowed.worst_under))



def move_paths_mm(result: SimulationResult) -> npt.NDArray[np.float64]:
    """Path length of every move of ``result``, mm."""
    m = result.plan.table.moves
    return path_lengths_mm(np.column_stack([m["x"], m["y"], m["z"]]).astype(np.float64),
                           np.asarray(result.plan.table.start_xyze[:3], dtype=np.float64))



def _name(names: list[str], k: int) -> str:
    return names[k] if 0 <= k < len(names) else ""


def _spot(result: SimulationResult, w: Window, path: npt.NDArray[np.float64]) -> Spot:
    tab = result.plan.table
    m = tab.moves
    c = w.centre_move
    h = float(result.parameters.layer_height_mm[c])
    length = max(w.length_mm, 1e-12)

    def width(volume: float) -> float:
        return volume / length / h + _BEAD * h if h > 0 else math.nan

    layer = int(m["layer"][c])
    z = float(m["z"][c])
    after = _after_retraction(m["kind"].astype(np.int64), path, w.first_move)
    return Spot(error=w.error, excess_mm3=w.delivered_mm3 - w.commanded_mm3,
                length_mm=w.length_mm, line=int(m["line"][c]),
                line_first=int(m["line"][w.first_move]), line_last=int(m["line"][w.last_move]),
                layer=layer, z_mm=z, feature=_name(tab.features, int(m["feature"][c])),
                width_nominal_mm=width(w.commanded_mm3),
                width_predicted_mm=width(w.delivered_mm3), after_retraction=after)


#: A window this close (path, mm) to the start of a stretch that follows a retraction is
#: called "right after a retraction".
_RESTART_MM = 2.0


def _after_retraction(kind: npt.NDArray[np.int64], path: npt.NDArray[np.float64],
                      move: int) -> bool:
    """``move`` lies within :data:`_RESTART_MM` of path after the start of a printed stretch
    that a retraction (negative E, among the 50 moves before it) precedes."""
    k = move - 1
    walked = 0.0
    while k >= 0 and (kind[k] & _PRINTING) == _PRINTING:
        walked += float(path[k])
        if walked > _RESTART_MM:
            return False
        k -= 1
    stop = k - 50
    while k >= 0 and k > stop and (kind[k] & _PRINTING) != _PRINTING:
        if kind[k] & int(MoveKind.RETRACT):
            return True
        k -= 1
    return False
