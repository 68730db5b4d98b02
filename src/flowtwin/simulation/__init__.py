"""Whole-print prediction: G-code + machine → what the printer really extrudes.

``simulate(gcode, machine)`` reads and plans the file as the firmware would
(:mod:`flowtwin.planner.plan_file`), derives the per-move physics from the machine's profiles
(:mod:`flowtwin.simulation.parameters`), integrates the extrusion state equation with the
firmware's pressure advance (:mod:`flowtwin.dynamics`) and applies the bead model
(:mod:`flowtwin.simulation.result`). ``simulate_stream`` does the same chunk by chunk in
bounded memory and keeps the whole-print aggregates (:mod:`flowtwin.simulation.stream`).
"""

from typing import TYPE_CHECKING

from flowtwin._lazy import lazy_exports

if TYPE_CHECKING:
    from flowtwin.simulation.parameters import MoveParameters, layer_heights_mm, move_parameters
    from flowtwin.simulation.pipeline import DEFAULT_MACHINE, simulate, simulate_plan
    from flowtwin.simulation.result import METRIC_DTYPE, SimulationResult
    from flowtwin.simulation.stream import StreamResult, simulate_stream
    from flowtwin.simulation.summary import SimulationSummary, StreamSummary

__all__ = ["DEFAULT_MACHINE", "METRIC_DTYPE", "MoveParameters", "SimulationResult",
           "SimulationSummary", "StreamResult", "StreamSummary", "layer_heights_mm",
           "move_parameters", "simulate", "simulate_plan", "simulate_stream"]

# names resolve on first use: `flowtwin limits` imports flowtwin.simulation.limits
# without the reader, the planner, the dynamics and numba
__getattr__, __dir__ = lazy_exports(__name__, {
    "DEFAULT_MACHINE": "flowtwin.simulation.pipeline",
    "METRIC_DTYPE": "flowtwin.simulation.result",
    "MoveParameters": "flowtwin.simulation.parameters",
    "SimulationResult": "flowtwin.simulation.result",
    "SimulationSummary": "flowtwin.simulation.summary",
    "StreamResult": "flowtwin.simulation.stream",
    "StreamSummary": "flowtwin.simulation.summary",
    "layer_heights_mm": "flowtwin.simulation.parameters",
    "move_parameters": "flowtwin.simulation.parameters",
    "simulate": "flowtwin.simulation.pipeline",
    "simulate_plan": "flowtwin.simulation.pipeline",
    "simulate_stream": "flowtwin.simulation.stream",
})
