"""Make the validation prints: OpenSCAD models → STL → G-code by Debian's slicers.

    python -m benchmarks.validation.generate [--split dev|check|…|check6] [--out DIR]

Needs ``openscad``, ``prusa-slicer``, ``slic3r``, ``CuraEngine`` and the ``cura`` package's
definitions (``apt-get install -y prusa-slicer slic3r cura-engine cura openscad``). Writes,
per print of :data:`benchmarks.validation.prints.PRINTS`, ``NAME.gcode`` and the machine
it is compensated for (``NAME.cfg``: a Klipper ``printer.cfg``; or a set-up name / TOML),
and ``MANIFEST.tsv`` with every command line run. The slicers are deterministic, so the
same command lines give the same G-code (up to the date in their headers).
"""

from __future__ import annotations

import argparse
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

from benchmarks.validation.prints import PRINTS, SPLITS, Print

HERE = Path(__file__).resolve().parent
MODELS = HERE / "models"
OUT = HERE / "out"
CURA_DEFINITIONS = Path("/usr/share/cura/resources/definitions")
TOOLS = ("openscad", "prusa-slicer", "slic3r", "CuraEngine")

#: A Klipper printer.cfg for the planner: the limits of the row, the rest Klipper's
#: defaults (pins are placeholders: the twin reads the motion and extruder settings only).
KLIPPER_CFG = """\
# validation printer: max_velocity {velocity:g}, max_accel {accel:g}, square_corner_velocity {scv:g}
[printer]
kinematics: cartesian
max_velocity: {velocity:g}
max_accel: {accel:g}
square_corner_velocity: {scv:g}

[stepper_x]
step_pin: PF0
dir_pin: PF1
enable_pin: !PD7
microsteps: 16
rotation_distance: 40
endstop_pin: ^PE5
position_endstop: 0
position_max: 250

[stepper_y]
step_pin: PF6
dir_pin: !PF7
enable_pin: !PF2
microsteps: 16
rotation_distance: 40
endstop_pin: ^PJ1
position_endstop: 0
position_max: 250

[stepper_z]
step_pin: PL3
dir_pin: PL1
enable_pin: !PK0
microsteps: 16
rotation_distance: 8
endstop_pin: ^PD3
position_endstop: 0
position_max: 250

[extruder]
step_pin: PA4
dir_pin: PA6
enable_pin: !PA2
microsteps: 16
rotation_distance: 8
nozzle_diameter: 0.400
filament_diameter: 1.750
max_extrude_only_distance: 200
pressure_advance: 0
heater_pin: PB4
sensor_type: EPCOS 100K B57560G104F
sensor_pin: PK5
control: pid
pid_Kp: 22.2
pid_Ki: 1.08
pid_Kd: 114
min_temp: 0
max_temp: 300

[gcode_arcs]
resolution: 1.0
"""

#: A Marlin 2 printer (stock limits) with the twin's drive, hot end and PLA.
MARLIN_GENERIC_SETUP = """\
kind = "setup"
name = "validation-marlin-generic"
description = "Marlin 2 stock limits, E3D V6 0.4 mm, PLA at 215 C (validation prints)"
printer = "generic-marlin"
drive = "hobb-goblin-80n"
hotend = "e3d-v6-0.4"
material = "pla-4043d"
filament = "pla-4043d-1.75"
temperature_c = 215.0
"""
#: The Klipper prints' drive, hot end (an E3D Volcano: the fast prints need its melt
#: capacity) and PLA; the motion comes from each print's printer.cfg.
KLIPPER_SETUP = """\
kind = "setup"
name = "validation-klipper-volcano"
description = "Klipper printer (printer.cfg per print), E3D Volcano 0.4 mm, PLA at 215 C"
printer = "generic-klipper"
drive = "hobb-goblin-80n"
hotend = "e3d-volcano-0.4"
material = "pla-4043d"
filament = "pla-4043d-1.75"
temperature_c = 215.0
"""
#: Line width CuraEngine prints with (its default for a 0.4 mm nozzle), mm.
CURA_LINE_MM = 0.4


def _first_layer(p: Print) -> float:
    return max(p.layer_mm, 0.2)


def _travel(p: Print) -> float:
    return min(300.0, max(150.0, 1.5 * p.infill_mm_s))


def max_flow_mm3_s(p: Print, out: Path) -> float:
    """The hot end's maximum volumetric flow at the print's layer height (the twin's
    ``flowtwin limits``), rounded down to 0.5 mm³/s."""
    from flowtwin.profiles.machine import load_machine
    from flowtwin.simulation.limits import flow_limit

    machine, _cfg = machine_of(p, out)
    q = flow_limit(load_machine(machine), layer_height_mm=p.layer_mm).max_volumetric_flow_mm3_s
    return float(int(2.0 * q) / 2.0)


def slicer_command(p: Print, stl: Path, gcode: Path, max_flow: float) -> list[str]:
    """The command line that slices ``stl`` into ``gcode`` with the row's settings, held to
    ``max_flow`` (mm³/s)."""
    w, i, a = p.wall_mm_s, p.infill_mm_s, p.accel_mm_s2
    if p.slicer.startswith("prusa"):
        cmd = ["prusa-slicer", "--export-gcode", "--nozzle-diameter", "0.4",
               "--filament-diameter", "1.75", "--temperature", "215",
               "--first-layer-temperature", "215", "--bed-temperature", "60",
               "--layer-height", f"{p.layer_mm:g}", "--first-layer-height",
               f"{_first_layer(p):g}", "--perimeters", "2", "--top-solid-layers", "4",
               "--bottom-solid-layers", "3", "--fill-density", "20%", "--skirts", "1",
               "--center", "100,100", "--gcode-flavor", "marlin2",
               "--perimeter-generator", p.slicer.split("-")[1],
               "--perimeter-speed", f"{w:g}", "--external-perimeter-speed", f"{0.7 * w:g}",
               "--small-perimeter-speed", f"{0.6 * w:g}", "--infill-speed", f"{i:g}",
               "--solid-infill-speed", f"{0.8 * i:g}", "--top-solid-infill-speed",
               f"{0.5 * i:g}", "--gap-fill-speed", f"{0.5 * w:g}", "--bridge-speed",
               f"{0.5 * w:g}", "--travel-speed", f"{_travel(p):g}", "--first-layer-speed",
               "30", "--default-acceleration", f"{a:g}", "--perimeter-acceleration",
               f"{a:g}", "--infill-acceleration", f"{a:g}", "--first-layer-acceleration",
               f"{min(a, 1000.0):g}", "--max-volumetric-speed", f"{max_flow:g}"]
        if p.relative_e:
            cmd += ["--use-relative-e-distances", "--layer-gcode", "G92 E0"]
        return [*cmd, "-o", str(gcode), str(stl)]
    if p.slicer == "slic3r":
        cmd = ["slic3r", "--nozzle-diameter", "0.4", "--filament-diameter", "1.75",
               "--temperature", "215", "--first-layer-temperature", "215",
               "--bed-temperature", "60", "--layer-height", f"{p.layer_mm:g}",
               "--first-layer-height", f"{_first_layer(p):g}", "--perimeters", "2",
               "--top-solid-layers", "4", "--bottom-solid-layers", "3", "--fill-density",
               "20%", "--skirts", "1", "--print-center", "100,100", "--gcode-flavor",
               "reprap", "--perimeter-speed", f"{w:g}", "--external-perimeter-speed",
               f"{0.7 * w:g}", "--small-perimeter-speed", f"{0.6 * w:g}", "--infill-speed",
               f"{i:g}", "--solid-infill-speed", f"{0.8 * i:g}", "--top-solid-infill-speed",
               f"{0.5 * i:g}", "--gap-fill-speed", f"{0.5 * w:g}", "--bridge-speed",
               f"{0.5 * w:g}", "--travel-speed", f"{_travel(p):g}", "--first-layer-speed",
               "30", "--default-acceleration", f"{a:g}", "--perimeter-acceleration", f"{a:g}",
               "--infill-acceleration", f"{a:g}", "--max-volumetric-speed", f"{max_flow:g}"]
        if p.relative_e:
            cmd += ["--use-relative-e-distances"]
        return [*cmd, "-o", str(gcode), str(stl)]
    if p.slicer == "cura":
        d = CURA_DEFINITIONS
        cap = max_flow / (CURA_LINE_MM * p.layer_mm)  # the fastest line the hot end melts
        w, i = min(w, cap), min(i, cap)
        settings = {
            "machine_width": "200", "machine_depth": "200", "machine_height": "200",
            "machine_gcode_flavor": "RepRap (Marlin/Sprinter)",
            "layer_height": f"{p.layer_mm:g}", "layer_height_0": f"{_first_layer(p):g}",
            "wall_line_count": "2", "top_layers": "4", "bottom_layers": "3",
            "infill_sparse_density": "20", "adhesion_type": "skirt",
            "material_print_temperature": "215", "material_print_temperature_layer_0": "215",
            "material_bed_temperature": "60", "speed_print": f"{i:g}",
            "speed_infill": f"{i:g}", "speed_wall": f"{w:g}", "speed_wall_0": f"{0.7 * w:g}",
            "speed_wall_x": f"{w:g}", "speed_topbottom": f"{0.5 * i:g}",
            "speed_travel": f"{_travel(p):g}", "speed_layer_0": "30",
            "speed_print_layer_0": "30", "speed_travel_layer_0": "100",
            "acceleration_enabled": "true", "acceleration_print": f"{a:g}",
            "acceleration_infill": f"{a:g}", "acceleration_wall": f"{a:g}",
            "acceleration_wall_0": f"{a:g}", "acceleration_wall_x": f"{a:g}",
            "acceleration_topbottom": f"{a:g}", "acceleration_travel": f"{a:g}",
            "acceleration_layer_0": f"{min(a, 1000.0):g}", "jerk_enabled": "false",
            "relative_extrusion": "true" if p.relative_e else "false",
        }
        cmd = ["CuraEngine", "slice", "-j", str(d / "fdmprinter.def.json")]
        for k, v in settings.items():
            cmd += ["-s", f"{k}={v}"]
        cmd += ["-e0", "-s", "machine_nozzle_size=0.4", "-s", "material_diameter=1.75",
                "-l", str(stl), "-s", "mesh_position_x=100", "-s", "mesh_position_y=100",
                "-o", str(gcode)]
        return cmd
    raise ValueError(f"unknown slicer {p.slicer}")


def machine_of(p: Print, out: Path) -> tuple[str, str | None]:
    """``(machine, klipper_config)`` to compensate the print for (files written in
    ``out``)."""
    if p.printer == "klipper":
        cfg = out / f"{p.name}.cfg"
        cfg.write_text(KLIPPER_CFG.format(velocity=p.velocity_mm_s, accel=p.accel_mm_s2,
                                          scv=p.scv_mm_s))
        setup = out / "validation-klipper-volcano.toml"
        setup.write_text(KLIPPER_SETUP)
        return str(setup), str(cfg)
    if p.printer == "marlin-mk25":
        return "tronvoll2019", None
    if p.printer == "marlin-generic":
        setup = out / "validation-marlin-generic.toml"
        setup.write_text(MARLIN_GENERIC_SETUP)
        return str(setup), None
    raise ValueError(f"unknown printer {p.printer}")


def _run(cmd: list[str], log: list[str]) -> None:
    log.append(shlex.join(cmd))
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600, check=False)
    if done.returncode != 0:
        raise SystemExit(f"failed ({done.returncode}): {shlex.join(cmd)}\n"
                         f"{done.stdout[-2000:]}\n{done.stderr[-2000:]}")


def generate(split: str | None = None, out: Path = OUT) -> list[Path]:
    """Slice every print of ``split`` (default: all) into ``out``; return the G-code paths."""
    missing = [t for t in TOOLS if shutil.which(t) is None]
    if missing or not CURA_DEFINITIONS.is_dir():
        raise SystemExit("missing: " + ", ".join(missing or ["cura definitions"])
                         + " (apt-get install -y prusa-slicer slic3r cura-engine cura "
                         "openscad)")
    out.mkdir(parents=True, exist_ok=True)
    stl_dir = out / "stl"
    stl_dir.mkdir(exist_ok=True)
    log: list[str] = []
    paths = []
    for p in PRINTS:
        if split is not None and p.split != split:
            continue
        stl = stl_dir / f"{p.model}.stl"
        if not stl.exists():
            _run(["openscad", "-o", str(stl), str(MODELS / f"{p.model}.scad")], log)
        gcode = out / f"{p.name}.gcode"
        _run(slicer_command(p, stl, gcode, max_flow_mm3_s(p, out)), log)
        paths.append(gcode)
        print(f"sliced {gcode.name}", flush=True)
    manifest = out / ("MANIFEST.tsv" if split is None else f"MANIFEST-{split}.tsv")
    manifest.write_text("\n".join(log) + "\n")
    return paths


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", choices=SPLITS)
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    generate(args.split, args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
