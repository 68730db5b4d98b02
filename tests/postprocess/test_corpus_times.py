"""Every time figure the corpus' slicers write is rewritten with the planner's, in the
slicer's own form; files without progress lines get ``M73`` where the firmware shows them.

Expected values are computed here from the plan of the *written* file (its move lines and
move start times), so the test also checks that the edits moved no move in time.
"""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtwin.planner.plan_file import plan_gcode
from flowtwin.postprocess import PostprocessOptions, postprocess

pytestmark = [pytest.mark.corpus]


class Plan:
    """The planner's times of a file: total, layer 0, before layer 0, elapsed at a line."""

    def __init__(self, path: Path, pph: Any, **kw: Any) -> None:
        p = plan_gcode(path, **kw)
        self.plan, self.pph = p, pph
        self.total = p.timeline.total_time_s
        self.lines = np.asarray(p.table.moves["line"])
        self.t0 = np.asarray(p.timeline.phases["t_start"])
        rows = {r["layer"]: r["time_s"] for r in p.per_layer()}
        self.first, self.before = rows.get(0, 0.0), rows.get(-1, 0.0)

    def at(self, line: int) -> float:
        return float(self.pph.elapsed_at(self.plan, line))


def _dhms(s: float) -> str:
    s = int(round(s))
    h, m, sec = s // 3600, s % 3600 // 60, s % 60
    return f"{h}h {m}m {sec}s" if h else (f"{m}m {sec}s" if m else f"{sec}s")


#: corpus file → the kinds of time lines it has (the sidecar's "rewritten" keys)
FILES = {
    "cura_5.9.1": {"cura total", "cura elapsed"},
    "cura_2.3.1_reprap": {"cura total", "cura elapsed"},
    "ideamaker_5.1.4": {"ideamaker total", "ideamaker elapsed", "ideamaker remaining"},
    "kisslicer_1.1.0.5_thinbox_small": {"kisslicer total"},
    "simplify3d_4.0.0_duet": {"simplify3d total"},
    "bambustudio_1.07_2colour_cube_small": {"bambu model and total", "M73"},
    "crealityprint_5.1.4_klipper": {"prusa total", "total estimated", "cura elapsed", "M73"},
    "prusaslicer_2.7.4_vase": {"prusa total", "prusa first layer"},
}


@pytest.mark.parametrize("name", sorted(FILES))
def test_time_lines_of_every_slicer_carry_the_planners_figures(
        name: str, pph: Any, klipper_dir: Path, tmp_path: Path) -> None:
    cfg = klipper_dir / "B.cfg"
    src = pph.corpus_copy(name, tmp_path / f"{name}.gcode")
    original = src.read_text(errors="replace").splitlines()
    before = Plan(src, pph, klipper_config=cfg)
    r = postprocess(src, PostprocessOptions(klipper_config=cfg), env={})
    assert r.written and set(r.times["rewritten"]) == FILES[name]  # type: ignore[arg-type]
    p = Plan(src, pph, klipper_config=cfg)
    assert p.total == before.total and np.array_equal(p.t0, before.t0)
    text = src.read_text(errors="replace").splitlines()
    assert len(text) == len(original) + 1          # one line added: flowtwin's, at the end
    assert text[-1].startswith("; postprocessed by flowtwin") and "Klipper planner" in text[-1]
    changed = 0
    for number, (old, line) in enumerate(zip(original, text, strict=False), start=1):
        e = p.at(number)
        if m := re.fullmatch(r";TIME:(\d+)", line):
            assert int(m.group(1)) == round(p.total)
        elif m := re.fullmatch(r";TIME_ELAPSED:([\d.]+)", line):
            assert m.group(1) == f"{e:.6f}"
        elif m := re.fullmatch(r";Print Time: (\d+)", line):
            assert int(m.group(1)) == round(p.total)
        elif m := re.fullmatch(r";PRINTING_TIME: (\d+)", line):
            assert int(m.group(1)) == round(e)
        elif m := re.fullmatch(r";REMAINING_TIME: (\d+)", line):
            assert int(m.group(1)) == round(p.total - e)
        elif m := re.fullmatch(r"; Estimated Build Time:\s+([\d.]+) minutes", line):
            assert m.group(1) == f"{p.total / 60:.2f}"
        elif m := re.fullmatch(r";\s+Build time: (\d+) hours (\d+) minutes", line):
            assert int(m.group(1)) * 60 + int(m.group(2)) == round(p.total / 60)
        elif m := re.fullmatch(r"; model printing time: (.*); total estimated time: (.*)", line):
            assert m.groups() == (_dhms(p.total - p.before), _dhms(p.total))
        elif m := re.fullmatch(r"; total estimated time: (.*)", line):
            assert m.group(1) == _dhms(p.total)
        elif m := re.fullmatch(r"; estimated printing time \(normal mode\) = (.*)", line):
            assert m.group(1) == _dhms(p.total)
        elif m := re.fullmatch(r"; estimated first layer printing time \(normal mode\) = (.*)",
                               line):
            assert m.group(1) == _dhms(p.first)
        elif m := re.match(r"M73 P(\d+) R(\d+)", line):
            assert (int(m.group(1)), int(m.group(2))) == (pph.percent(e, p.total),
                                                          int((p.total - e + 0.5) / 60))
        else:
            assert line == old, number       # nothing else changed
            continue
        changed += line != old
    assert changed > 0


def test_a_marlin_file_without_progress_lines_gets_m73_and_the_verdict_follows_the_lines(
        pph: Any, tmp_path: Path) -> None:
    src = pph.corpus_copy("slic3r_1.2.9_duet", tmp_path / "duet.gcode")
    copy = pph.corpus_copy("slic3r_1.2.9_duet", tmp_path / "untouched.gcode")
    original = src.read_text().splitlines()
    assert not any(ln.startswith("M73") for ln in original)
    r = postprocess(src, PostprocessOptions(setup="tronvoll2019"), env={})
    assert r.choice.firmware.value == "marlin" and r.written
    text = src.read_text().splitlines()
    p = Plan(src, pph, printer=r.choice.machine.printer)
    progress = [(k, ln) for k, ln in enumerate(text, start=1) if ln.startswith("M73 ")]
    assert len(progress) == r.times["progress_added"]
    layers = {row["layer"] for row in r.times["per_layer"]} - {-1}  # type: ignore[attr-defined]
    assert len(progress) == len(layers) + 2         # first move, each layer, after the end
    assert progress[0][1].startswith("M73 P0 R") and progress[-1][1] == "M73 P100 R0"
    for number, line in progress:
        e = p.at(number)
        assert line == f"M73 P{pph.percent(e, p.total)} R{int((p.total - e + 0.5) / 60)}"
    # the verdict names lines of the written file: the twin's verdict of the untouched
    # file, its lines moved past the M73 lines added before them
    new_number, k = {}, 0
    for number, line in enumerate(text, start=1):
        if line.startswith(("M73 ", "; postprocessed by flowtwin")):
            continue
        k += 1
        assert line == original[k - 1]
        new_number[k] = number
    from flowtwin.report.verdict import build_verdict
    from flowtwin.simulation import simulate

    v = build_verdict(simulate(copy, machine=r.choice.machine))
    side = json.loads(r.sidecar.read_text())["verdict"]
    assert v.over is not None and v.under is not None
    for key in ("line", "line_first", "line_last"):
        assert side["over"][key] == new_number[getattr(v.over, key)]
        assert side["under"][key] == new_number[getattr(v.under, key)]
    assert side["grinding"]["line"] == new_number[v.grinding.line]
    assert new_number[v.grinding.line] != v.grinding.line      # the lines did move
    assert f"line {new_number[v.over.line]}" in " ".join(r.sentences)
