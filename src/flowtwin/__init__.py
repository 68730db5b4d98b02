"""flowtwin: the digital twin of the extrusion system of a filament 3D printer.

Data flows one way (docs/spec.md §5)::

    G-code text -> reader -> moves -> planner -> timeline -> dynamics -> deposition -> result

The entry points are here, imported on first use (``import flowtwin`` loads none of the
numerical stack)::

    import flowtwin

    plan = flowtwin.plan("print.gcode", printer="generic-klipper")       # read + plan
    sim = flowtwin.simulate("print.gcode", machine="tronvoll2019")       # + the physics
    report = flowtwin.compensate("print.gcode", "fixed.gcode", slip=flowtwin.SlipOptions())

Internal units are mm, s, N, MPa and °C (docs/spec.md §2); names carry units where
ambiguous.
"""

from flowtwin._lazy import lazy_exports
from flowtwin.errors import FlowtwinError

__version__ = "0.1.0"

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (~10 ms)
if TYPE_CHECKING:
    from flowtwin.batch import read_results, run_batch, run_sweep
    from flowtwin.calibration import (
        adaptive_pa_table,
        best_pressure_advance,
        fit_k,
        generate_pattern,
        verify_pattern,
    )
    from flowtwin.compensation import (
        AdvanceOptions,
        CompensationReport,
        GuardOptions,
        PaceOptions,
        SlipOptions,
        TrajectoryOptions,
        compensate,
    )
    from flowtwin.gcode.generator import PrintSpec, write_print
    from flowtwin.gcode.reader import ReadOptions, iter_move_chunks, read_gcode
    from flowtwin.planner.plan_file import PlanResult, load_printer
    from flowtwin.planner.plan_file import plan_gcode as plan
    from flowtwin.profiles import Machine, load_builtin, load_machine, load_profile
    from flowtwin.reproduce import run as reproduce
    from flowtwin.simulation import SimulationResult, StreamResult, simulate, simulate_stream
    from flowtwin.simulation.limits import flow_limit
    from flowtwin.vision import measure

#: Entry point -> where it lives (``module:name`` where the name differs).
_ENTRY_POINTS = {
    # read and plan
    "plan": "flowtwin.planner.plan_file:plan_gcode", "PlanResult": "flowtwin.planner.plan_file",
    "load_printer": "flowtwin.planner.plan_file",
    "read_gcode": "flowtwin.gcode.reader", "iter_move_chunks": "flowtwin.gcode.reader",
    "ReadOptions": "flowtwin.gcode.reader",
    # predict
    "simulate": "flowtwin.simulation", "simulate_stream": "flowtwin.simulation",
    "SimulationResult": "flowtwin.simulation", "StreamResult": "flowtwin.simulation",
    "flow_limit": "flowtwin.simulation.limits",
    # correct
    "compensate": "flowtwin.compensation", "CompensationReport": "flowtwin.compensation",
    "AdvanceOptions": "flowtwin.compensation", "SlipOptions": "flowtwin.compensation",
    "GuardOptions": "flowtwin.compensation", "PaceOptions": "flowtwin.compensation",
    "TrajectoryOptions": "flowtwin.compensation",
    "best_pressure_advance": "flowtwin.calibration",
    "adaptive_pa_table": "flowtwin.calibration",
    # machines
    "Machine": "flowtwin.profiles", "load_machine": "flowtwin.profiles",
    "load_profile": "flowtwin.profiles", "load_builtin": "flowtwin.profiles",
    # calibrate, measure, scale out, reproduce
    "generate_pattern": "flowtwin.calibration", "verify_pattern": "flowtwin.calibration",
    "fit_k": "flowtwin.calibration", "measure": "flowtwin.vision",
    "run_batch": "flowtwin.batch", "run_sweep": "flowtwin.batch",
    "read_results": "flowtwin.batch", "reproduce": "flowtwin.reproduce:run",
    # test prints
    "PrintSpec": "flowtwin.gcode.generator", "write_print": "flowtwin.gcode.generator",
}

__all__ = [
    "AdvanceOptions",
    "CompensationReport",
    "FlowtwinError",
    "GuardOptions",
    "Machine",
    "PaceOptions",
    "PlanResult",
    "PrintSpec",
    "ReadOptions",
    "SimulationResult",
    "SlipOptions",
    "StreamResult",
    "TrajectoryOptions",
    "__version__",
    "adaptive_pa_table",
    "best_pressure_advance",
    "compensate",
    "fit_k",
    "flow_limit",
    "generate_pattern",
    "iter_move_chunks",
    "load_builtin",
    "load_machine",
    "load_printer",
    "load_profile",
    "measure",
    "plan",
    "read_gcode",
    "read_results",
    "reproduce",
    "run_batch",
    "run_sweep",
    "simulate",
    "simulate_stream",
    "verify_pattern",
    "write_print",
]

__getattr__, __dir__ = lazy_exports(__name__, _ENTRY_POINTS)
