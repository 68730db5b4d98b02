"""Compile the numba kernels of the everyday commands once, into numba's cache, and the
package's Python bytecode.

A kernel is compiled the first time it runs in an installation and loaded from the cache
afterwards (``cache=True``). Compiling the kernels ``plan`` and ``simulate`` use takes
35-100 s (more on a busy machine): ``make install`` runs this module so that a user's first
command does not. It plans and simulates a small generated print the ways the commands do:
Klipper and Marlin planners, whole-table and streamed, the default set-up (Marlin-style
advance) and a Klipper printer with smoothed pressure advance; and it compensates it as
``flowtwin compensate --advance --slip`` does (the refinement's interior point and the
writer: ~15 s more to compile, else a user's first ``compensate`` pays it), and paced.

The package's modules are byte-compiled too (:func:`compile_bytecode`): Python writes
``__pycache__`` on first import, except where ``PYTHONDONTWRITEBYTECODE`` is set (some
containers and CI images set it), and then every command would compile ~120 modules from
source again (0.15-0.3 s of each start-up, measured on this project's VM).

Usage: ``python -m flowtwin.warmup`` (prints the seconds it took).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

__all__ = ["compile_bytecode", "warm_up"]

#: A minimal Klipper printer with smoothed pressure advance (the Klipper kernels).
_KLIPPER_CFG = """[printer]
kinematics: cartesian
max_velocity: 300
max_accel: 3000
""" + "".join(f"[stepper_{a}]\nposition_endstop: 0\nposition_max: 250\n" for a in "xyz") + """
[extruder]
nozzle_diameter: 0.4
filament_diameter: 1.75
pressure_advance: 0.04
pressure_advance_smooth_time: 0.04
[gcode_arcs]
resolution: 1.0
"""


def compile_bytecode() -> bool:
    """Byte-compile every module of the package into its ``__pycache__`` (kept for later
    imports even where Python is told not to write bytecode); ``True`` when all compiled."""
    import compileall

    package = Path(__file__).resolve().parent
    return bool(compileall.compile_dir(package, quiet=1, workers=1))


def warm_up() -> float:
    """Run plan and simulate on a small print in every common configuration, and
    compensate it (advance and slip); return the seconds it took (compilation, or loading
    from the cache when it is warm)."""
    from flowtwin.compensation import compensate
    from flowtwin.compensation.pace import PaceOptions
    from flowtwin.gcode.generator import PrintSpec, write_print
    from flowtwin.planner.plan_file import plan_gcode
    from flowtwin.planner.plan_stream import plan_stream
    from flowtwin.simulation import simulate, simulate_stream

    t0 = time.perf_counter()
    compile_bytecode()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "warm.gcode"
        write_print(path, PrintSpec(layers=3))
        cfg = Path(tmp) / "printer.cfg"
        cfg.write_text(_KLIPPER_CFG)
        for kw in ({"printer": "generic-klipper"}, {"printer": "generic-marlin"},
                   {"klipper_config": cfg}):
            plan = plan_gcode(path, **kw)  # type: ignore[arg-type]
            plan.summary()
            plan.per_layer()
            plan_stream(path, window_moves=1000, **kw).run().summary()  # type: ignore[arg-type]
        for cfg_or_none in (None, cfg):
            sim = simulate(path, klipper_config=cfg_or_none, series_dt_s=0.01)
            sim.summary()
            sim.per_layer()
            sim.per_feature()
            sim.worst_moves("width")
            simulate_stream(path, klipper_config=cfg_or_none, section_moves=1000,
                            chunk_bytes=16 * 1024).summary()
        compensate(path, Path(tmp) / "compensated.gcode", advance=True, slip=True)
        # the pacing everywhere: its staircases are cut on this small print (near the
        # spots alone there would be none to pace)
        compensate(path, Path(tmp) / "paced.gcode", advance=True,
                   pace=PaceOptions(spots=False))
    return time.perf_counter() - t0


if __name__ == "__main__":
    print(f"flowtwin kernels compiled and cached in {warm_up():.1f} s")
