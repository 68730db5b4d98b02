"""Compensation in the same pass: ``--advance --slip`` through the public ``compensate``,
the times written are those of the compensated file, and ``--report`` writes the before /
after report beside the output."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

pytestmark = [pytest.mark.slow, pytest.mark.corpus]


def test_advance_and_slip_in_the_same_pass_with_the_report(flowtwin_exe: str, pph: Any,
                                                           tmp_path: Path) -> None:
    plain = pph.corpus_copy("prusaslicer_2.8.1_minicube_small", tmp_path / "plain.gcode")
    comp = pph.corpus_copy("prusaslicer_2.8.1_minicube_small", tmp_path / "comp.gcode")
    cfg = str(pph.KLIPPER_CFG)
    pph.flowtwin_json(flowtwin_exe, "postprocess", "--klipper-config", cfg, str(plain))
    side = pph.flowtwin_json(flowtwin_exe, "postprocess", "--klipper-config", cfg,
                             "--advance", "--slip", "--report", str(comp))
    c = side["compensation"]
    assert "advance" in c["transformations"]
    assert c["rms_flow_error_after"] < c["rms_flow_error_before"]
    assert c["firmware_pressure_advance"] is False
    # the file written is the compensated one (other E values), with its own times
    a, b = plain.read_text().splitlines(), comp.read_text().splitlines()
    assert a != b and "compensation: advance" in b[-1]
    plan = pph.flowtwin_json(flowtwin_exe, "plan", str(comp), "--klipper-config", cfg)
    assert side["times"]["total_s"] == pytest.approx(plan["total_time_s"], rel=0, abs=1e-9)
    assert f"; estimated printing time (normal mode) = {pph.dhms(plan['total_time_s'])}" in b
    report = tmp_path / "comp.gcode.report.html"
    assert side["report"] == str(report)
    html = report.read_text()
    assert html.startswith("<!DOCTYPE html>") and "flowtwin compensate" in html
    assert json.loads((tmp_path / "comp.gcode.flowtwin.json").read_text())["written"]
