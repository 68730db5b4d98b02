"""The verdict: plain words and units, the windowed figures, advice that holds in the twin."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from flowtwin.cli.main import app
from flowtwin.compensation.metrics import flow_figures
from flowtwin.report import build_verdict
from flowtwin.simulation import SimulationResult, simulate

_AFIL = math.pi * 1.75 ** 2 / 4


def _area(w: float, h: float) -> float:
    return w * h - (1 - math.pi / 4) * h * h


def _gcode(body: list[str]) -> bytes:
    head = ["G21", "G90", "M83", "M104 S215", "G28", "G1 Z0.2 F600"]
    return "\n".join(head + body + [""]).encode()


def _line(x0: float, x1: float, y: float, speed: float, w: float = 0.45,
          h: float = 0.2) -> str:
    e = _area(w, h) * abs(x1 - x0) / _AFIL
    return f"G1 X{x1:.3f} Y{y:.3f} E{e:.5f} F{speed * 60:.0f}"


def test_demo_verdict_agrees_with_summary_and_compensation(
        demo_result: SimulationResult, demo_gcode: Path) -> None:
    v = build_verdict(demo_result)
    s = demo_result.summary()
    n = len(demo_result.plan.table)
    comp = flow_figures(demo_result, demo_result, np.arange(n), window_mm=0.4)
    assert v.window_mm == 0.4                       # the E3D V6 0.4 nozzle of the set-up
    assert v.over is not None and v.under is not None
    assert v.over.error == pytest.approx(comp.peak_overextrusion_window, rel=1e-12)
    # a window inside one move is that move: equal up to the rounding of two sums
    assert v.over.error <= s.peak_overextrusion * (1 + 1e-9)
    assert v.grinding.min_margin_n == pytest.approx(s.min_force_margin_n)
    assert v.grinding.level == "safe" and s.grinding_moves == 0
    assert v.print_time_s == s.total_time_s and v.ooze_mm3 == s.ooze_volume_mm3
    lines = demo_gcode.read_text().splitlines()
    for spot in (*v.worst_over, *v.worst_under):
        text = lines[spot.line - 1]
        assert text[:2] in ("G1", "G2", "G3") and " E" in text, text  # printing
        assert spot.line_first <= spot.line <= spot.line_last
    # plain words with units, and JSON without NaN
    words = " ".join(v.sentences())
    for unit in (" N ", " mm³", " %", " mm"):
        assert unit in words
    json.dumps(v.as_dict(), allow_nan=False)
    assert {f.feature for f in v.by_feature} >= {"External perimeter", "Internal infill"}


def test_micrometre_move_is_not_the_headline_and_the_cli_lists_windows(
        tmp_path: Path) -> None:
    # a fast line, a slow 10 mm line and a 0.03 mm move before a retraction: the melt the
    # slow move cannot take piles into the tiny move (+82 % per move); over 0.4 mm of path
    # the excess is +24 %
    body = ["G1 X20 Y100 F6000", _line(20, 60, 100, 60),
            f"G1 X60 Y110 E{_area(0.45, 0.2) * 10 / _AFIL:.5f} F600",
            f"G1 X60.03 Y110 E{_area(0.45, 0.2) * 0.03 / _AFIL:.5f}",
            "G1 E-0.8 F2100", "G1 X20 Y120 F6000", "G1 E0.8 F2100", _line(20, 60, 120, 30)]
    path = tmp_path / "tiny.gcode"
    path.write_bytes(_gcode(body))
    result = simulate(path)
    v = build_verdict(result)
    per_move = result.summary().peak_overextrusion
    assert v.over is not None
    assert per_move > 0.5 and v.over.error < 0.5 * per_move
    assert v.over.line_first == 9 and v.over.line_last == 10   # the slow line and the tiny move
    res = CliRunner().invoke(app, ["simulate", str(path), "--no-fit"],
                             env={"COLUMNS": "120"})
    assert res.exit_code == 0, res.output
    assert f"{100 * v.over.error:+.1f} %" in res.output
    assert f"{100 * per_move:+.1f} %" not in res.output
    js = CliRunner().invoke(app, ["simulate", str(path), "--no-fit", "--json"])
    out = json.loads(js.stdout)
    assert out["verdict"]["over"]["error"] == pytest.approx(v.over.error)


def test_the_flow_limit_of_the_advice_holds_in_the_twin() -> None:
    # wide, thick lines so the flows are reachable within the printer's speeds
    w, h = 1.2, 0.4
    a = _area(w, h)

    def run(speed: float) -> SimulationResult:
        return simulate(_gcode(["G1 X20 Y100 F6000", _line(20, 200, 100, speed, w, h),
                                "G1 E-0.8 F2100", "G1 X20 Y110 F6000"]))

    base = build_verdict(run(20.0))
    # the advice keeps to the smaller of the grip's steady flow limit and the machine's
    # maximum volumetric flow (the melt cools at high flow: K rises with it)
    q_limit = min(base.grinding.flow_limit_mm3_s, base.grinding.machine_flow_limit_mm3_s)
    safety = base.grinding.safety
    assert 5.0 < q_limit < 500.0
    # just below the limit: the twin's force stays below safety × grip ("safe")
    below = run(0.95 * q_limit / a)
    vb = build_verdict(below)
    k = int(np.argmax(below.dynamics.moves["cmd_mm3"]))
    grip = vb.grinding.grip_n
    assert below.dynamics.moves["peak_force_n"][k] < safety * grip
    assert vb.grinding.level == "safe" and vb.grinding.moves_over_machine_limit == 0
    # far beyond it (the steady force formula at 1.6 × the grip): the twin flags the risk
    q_grip = base.grinding.flow_limit_mm3_s
    above = run(1.6 / safety * q_grip / a)
    va = build_verdict(above)
    assert va.grinding.level in ("at risk", "grinds")
    assert any("--guard" in adv.command for adv in va.advice)
    assert va.grinding.speed_limit_mm_s < 1.6 / safety * q_grip / a
    assert va.grinding.moves_over_machine_limit > 0
    assert any("maximum volumetric flow" in adv.text for adv in va.advice)
