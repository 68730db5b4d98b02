"""Debian's real PrusaSlicer runs ``flowtwin postprocess`` as its post-processing script,
set up exactly as the README tells users (an absolute path to ``flowtwin`` and its options
in "Post-processing scripts"; on the command line ``--post-process``).

PrusaSlicer 2.5 (Debian) has no Klipper G-code flavor (2.6 added one): a Klipper user
slices for Marlin 2 and gives flowtwin the printer's ``printer.cfg``.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest

from flowtwin.planner.plan_file import plan_gcode

pytestmark = [pytest.mark.slow]


def _m73_expected(path: Path, cfg: Path, pph: Any) -> tuple[float, dict[int, tuple[int, int]]]:
    """Total time and, per ``M73 P R`` line of ``path``, the (percent, minutes) the planner
    gives there: PrusaSlicer's formulas on the time at which the printer reaches the line."""
    plan = plan_gcode(path, klipper_config=cfg)
    total = plan.timeline.total_time_s
    out = {}
    for number, text in enumerate(path.read_text().splitlines(), start=1):
        if re.match(r"M73 P\d", text):
            e = pph.elapsed_at(plan, number)
            out[number] = (pph.percent(e, total), int((total - e + 0.5) / 60))
    return total, out


def test_prusaslicer_runs_flowtwin_and_the_written_times_are_flowtwins_plan(
        prusa_slicer: str, part_stl: Path, flowtwin_exe: str, pph: Any,
        tmp_path: Path) -> None:
    cfg = pph.KLIPPER_CFG
    reference = tmp_path / "plain.gcode"   # the slicer's file as the script is given it
    out = tmp_path / "part.gcode"
    # the README's line
    proc = pph.slice_part(prusa_slicer, part_stl, out, post_process=(
        f"{flowtwin_exe} postprocess --klipper-config {cfg} --fail-on grinding"),
        keep_before=reference)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    slicer_says = re.search(r"estimated printing time \(normal mode\) = (.*)",
                            reference.read_text()).group(1)
    text = out.read_text()
    plan = pph.flowtwin_json(flowtwin_exe, "plan", str(out), "--klipper-config", str(cfg))
    total = float(plan["total_time_s"])
    # the slicer's own figures are replaced by the planner's (to the second; to 10 ms on
    # flowtwin's line), and they differ from what the slicer wrote
    assert f"; estimated printing time (normal mode) = {pph.dhms(total)}\n" in text
    assert f"; estimated printing time (silent mode) = {pph.dhms(total)}\n" in text
    assert pph.dhms(total) != slicer_says
    mark = re.findall(r"^; postprocessed by flowtwin [\w.]+: print time .*? \(([\d.]+) s\)"
                      r".*Klipper planner.*printer\.cfg", text, re.MULTILINE)
    assert len(mark) == 1 and abs(float(mark[0]) - total) < 0.005
    # every progress line: PrusaSlicer's M73 formulas on the planner's time line
    plan_total, expected = _m73_expected(out, cfg, pph)
    assert abs(plan_total - total) < 1e-9 and len(expected) > 20
    for number, line in enumerate(text.splitlines(), start=1):
        if number in expected:
            p, r = expected[number]
            assert line == f"M73 P{p} R{r}", (number, line)
    assert text.count("\nM73 P") == len(expected)
    assert [v for v in expected.values()][-1] == (100, 0)
    # no move changed: the file plans exactly as the slicer's own (times differ only in
    # the lines rewritten)
    assert len(text.splitlines()) == len(reference.read_text().splitlines()) + 1

    def kept(lines: list[str]) -> list[str]:
        return [x for x in lines if not re.match(r"M73 |; estimated printing time|"
                                                   r"; postprocessed by flowtwin", x)]
    assert kept(text.splitlines()) == kept(reference.read_text().splitlines())
    assert plan["moves"] == pph.flowtwin_json(flowtwin_exe, "plan", str(reference),
                                              "--klipper-config", str(cfg))["moves"]
    # the verdict's sidecar, beside the output
    side = json.loads((tmp_path / "part.gcode.flowtwin.json").read_text())
    assert side["written"] is True and side["failed"] is False
    assert side["slicer"] == {"host": "File", "output_name": str(out),
                              "settings": "environment"}
    assert side["printer"]["source"] == "klipper-config"
    assert side["verdict"]["grinding"]["level"] in ("safe", "at risk")
    assert abs(side["times"]["total_s"] - total) < 1e-9
    assert side["times"]["per_layer"] == plan["per_layer"]


def test_a_print_the_twin_says_will_grind_stops_the_export_with_the_message(
        prusa_slicer: str, part_stl: Path, flowtwin_exe: str, pph: Any,
        tmp_path: Path) -> None:
    # 0.6 mm lines of 0.3 mm layers at 250-300 mm/s: ~45-54 mm³/s asked of a drive whose
    # grip (roller #3 at 80 N) holds about 8 mm³/s
    fast = ["--layer-height", "0.3", "--extrusion-width", "0.6", "--perimeter-speed", "250",
            "--external-perimeter-speed", "250", "--infill-speed", "300",
            "--solid-infill-speed", "300", "--top-solid-infill-speed", "300",
            "--max-volumetric-speed", "0"]
    out = tmp_path / "fast.gcode"
    script = (f"{flowtwin_exe} postprocess --klipper-config {pph.KLIPPER_CFG} "
              "--fail-on grinding")
    proc = pph.slice_part(prusa_slicer, part_stl, out, *fast, post_process=script)
    assert proc.returncode != 0
    said = proc.stdout + proc.stderr
    # PrusaSlicer reports the script's failure with flowtwin's own words
    assert "Post-processing script" in said and "failed" in said
    assert "export stopped" in said and "the twin predicts the drive grinds" in said
    assert re.search(r"smallest margin is at line \d+ \(layer \d+, ", said)
    # the G-code is left as the slicer wrote it; the sidecar says why
    text = out.read_text()
    assert "postprocessed by flowtwin" not in text
    side = json.loads((tmp_path / "fast.gcode.flowtwin.json").read_text())
    assert side["failed"] is True and side["written"] is False
    assert side["verdict"]["grinding"]["level"] == "grinds"
    assert side["verdict"]["grinding"]["grinding_moves"] > 0
    # without --fail-on the same file is processed, and the verdict still says it grinds
    proc = pph.slice_part(prusa_slicer, part_stl, out, *fast,
                          post_process=script.replace("--fail-on grinding", "--fail-on none"))
    assert proc.returncode == 0, proc.stderr
    assert "postprocessed by flowtwin" in out.read_text()
    assert json.loads((tmp_path / "fast.gcode.flowtwin.json").read_text())["verdict"][
        "grinding"]["level"] == "grinds"
