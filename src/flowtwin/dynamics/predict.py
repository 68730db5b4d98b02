"""One call from a planned G-code to the predicted extrusion, with or without pressure advance."""

from __future__ import annotations

from flowtwin.dynamics.advance import AdvanceSettings, apply_advance
from flowtwin.dynamics.extrusion_result import DynamicsResult
from flowtwin.dynamics.feed import nominal_feed
from flowtwin.dynamics.integrator import integrate
from flowtwin.dynamics.params import ExtrusionParams
from flowtwin.gcode.moves import MoveTable
from flowtwin.planner.timeline import Timeline

__all__ = ["predict"]


def predict(moves: MoveTable, timeline: Timeline, params: ExtrusionParams, *,
            advance: AdvanceSettings | None = None, tool: int | None = None,
            e_start_mm: float = 0.0, initial_compression_mm: float = 0.0,
            tail_s: float = 0.0, series_dt_s: float | None = None,
            series_window_s: tuple[float, float] | None = None,
            stiffness: float = 1.0) -> DynamicsResult:
    """Predict what ``moves`` (planned as ``timeline``) extrude on a printer.

    Parameters
    ----------
    moves
        Move table (``n_moves`` rows) with its events.
    timeline
        Planner output for the same moves.
    params
        Per-move physical parameters (:class:`~flowtwin.dynamics.params.ExtrusionParams`).
    advance
        Firmware pressure advance; ``None`` predicts the G-code without any advance.
    tool
        Extruder to simulate (``None``: every move's E).
    e_start_mm
        Extruder position before the first move, mm.
    initial_compression_mm, tail_s, series_dt_s, series_window_s, stiffness
        Passed to :func:`~flowtwin.dynamics.integrator.integrate`.

    Returns
    -------
    DynamicsResult

    Examples
    --------
    The same print with and without Klipper pressure advance::

        with_pa = predict(moves, timeline, params,
                          advance=AdvanceSettings(Firmware.KLIPPER, k_s=0.04))
        without = predict(moves, timeline, params)
    """
    feed = nominal_feed(moves, timeline, tool=tool, e_start_mm=e_start_mm)
    if advance is not None:
        feed = apply_advance(feed, moves, advance)
    return integrate(feed, params, initial_compression_mm=initial_compression_mm,
                     tail_s=tail_s, series_dt_s=series_dt_s, series_window_s=series_window_s,
                     stiffness=stiffness)
