"""End to end on a real slicer file: reader -> Klipper planner -> feed/advance -> integrator."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from flowtwin.dynamics import (
    AdvanceSettings,
    ExtrusionParams,
    apply_advance,
    integrate,
    nominal_feed,
)
from flowtwin.firmware import Firmware
from flowtwin.gcode.reader import read_gcode
from flowtwin.planner.klipper import plan_klipper
from flowtwin.planner.klipper_config import klipper_read_options, load_printer_cfg

FILE = "prusaslicer_2.8.1_minicube_small"


@pytest.mark.corpus
def test_minicube_on_klipper_b_with_and_without_pressure_advance(klipper_dir, corpus_dir):
    cfg = load_printer_cfg(klipper_dir / "B.cfg")
    table = read_gcode(corpus_dir / f"{FILE}.gcode", options=klipper_read_options(cfg))
    timeline = plan_klipper(table, cfg)
    ext = cfg.extruders[0]
    with open(klipper_dir / "print_times.tsv", newline="") as fh:
        row = next(r for r in csv.DictReader(fh, delimiter="\t")
                   if r["file"] == f"{FILE}.gcode" and r["config"] == "B")
    final_e = json.loads(row["final_e_per_tool"])["0"]
    feed = nominal_feed(table, timeline)
    pa = AdvanceSettings(Firmware.KLIPPER, k_s=ext.pressure_advance,
                         smooth_time_s=ext.pressure_advance_smooth_time)
    advanced = apply_advance(feed, table, pa)
    # Klipper's extruder ends where the G-code says, with or without pressure advance
    # (the oracle logs 5 decimals)
    assert feed.e_end_mm() == pytest.approx(final_e, abs=1e-5)
    assert advanced.e_end_mm() == pytest.approx(final_e, abs=1e-5)
    params = ExtrusionParams.build(len(table), lag_k_s=0.06, compliance_mm_per_n=0.01,
                                   filament_diameter_mm=ext.filament_diameter,
                                   slip_offset=0.01, slip_gradient_per_n=0.0032)
    plain = integrate(feed, params, tail_s=1.0)
    with_pa = integrate(advanced, params, tail_s=1.0)
    for res in (plain, with_pa):
        s = res.summary
        assert abs(s.mass_balance_error_mm3) <= 1e-9 * s.fed_mm3
        assert np.all(res.moves["out_mm3"] >= 0.0)
        assert s.fed_cmd_mm3 == pytest.approx(s.cmd_mm3, rel=1e-12)
    # pressure advance relieves the nozzle pressure before travels and stops: less ooze
    # (per-move volumes of this file's short moves are dominated by the 40 ms smoothing,
    # which shifts filament between neighbouring moves, so ooze is the telling figure)
    assert with_pa.summary.ooze_mm3 < 0.5 * plain.summary.ooze_mm3
    assert plain.summary.ooze_mm3 > 1.0
