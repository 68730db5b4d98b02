"""The shortest travel relieved depends on what a relief costs the firmware."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from flowtwin.compensation import compensate
from flowtwin.compensation.advance import AdvanceOptions
from flowtwin.errors import ProfileError

from .test_relief_along import CUP


def _dashes(path: Path, gap_mm: float) -> Path:
    """Rows of 10 mm dashes at 80 mm/s joined by unretracted travels of ``gap_mm`` in line
    with them (the head does not stop: the travel lasts ``gap_mm/80`` s)."""
    lines = ["G21", "G90", "M83", "M104 S215", "G28", "G1 Z0.2 F600", "G1 X10 Y20 F6000"]
    e_mm = 0.2 * 0.45 * 10 / (math.pi * 0.875 ** 2)
    for row in range(4):
        y, x = 20 + 2 * row, 10.0
        lines.append(f"G0 X10 Y{y} F6000")
        for _ in range(12):
            x += 10
            lines.append(f"G1 X{x:.3f} Y{y} E{e_mm:.5f} F4800")
            x += gap_mm
            lines.append(f"G0 X{x:.3f} Y{y} F4800")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_the_default_threshold_is_the_firmwares() -> None:
    assert AdvanceOptions().relief_lags("marlin") == 0.25
    assert AdvanceOptions().relief_lags("klipper") == 0.5
    assert AdvanceOptions(relief_min_lags=1.0).relief_lags("klipper") == 1.0
    with pytest.raises(ProfileError, match="relief_min_lags"):
        AdvanceOptions(relief_min_lags=-0.1)


def test_marlin_relieves_travels_of_a_quarter_lag_and_the_ooze_stops(tmp_path: Path) -> None:
    # 2 mm at 80 mm/s: 25 ms, between a quarter and a half of this set-up's lag factor;
    # unrelieved, the column oozes through every travel and the next dash starts short
    src = _dashes(tmp_path / "dashes.gcode", 2.0)
    runs = {}
    for name, lags in (("default", None), ("quarter", 0.25), ("half", 0.5)):
        report = compensate(src, tmp_path / f"{name}.gcode",
                            advance=AdvanceOptions(relief_min_lags=lags))
        runs[name] = (report, (tmp_path / f"{name}.gcode").read_bytes())
    (default, text), (_quarter, quarter_text), (half, _) = (
        runs["default"], runs["quarter"], runs["half"])
    assert text == quarter_text
    assert half.advance[0].relief_travels < 5 < 40 < default.advance[0].relief_travels
    assert default.after.rms_flow_error < 0.5 * half.after.rms_flow_error
    # the head stops for each relief's two E-only moves: that is the price, in the report
    assert default.time_after_s > half.time_after_s


def test_klipper_keeps_half_a_lag_by_default(tmp_path: Path) -> None:
    # 1 mm at 80 mm/s on the Volcano: between a quarter and a half of its lag factor;
    # Klipper runs a relief's E-only moves at max_extrude_only_accel, so there the
    # relief of such short travels costs more print time than it is worth by default
    src = _dashes(tmp_path / "dashes.gcode", 1.0)
    setup, cfg = CUP / "klipper-volcano.toml", CUP / "printer.cfg"
    out = {}
    for name, lags in (("default", None), ("half", 0.5), ("quarter", 0.25)):
        report = compensate(src, tmp_path / f"{name}.gcode", machine=setup,
                            klipper_config=cfg, advance=AdvanceOptions(relief_min_lags=lags))
        out[name] = ((tmp_path / f"{name}.gcode").read_bytes(), report)
    assert out["default"][0] == out["half"][0] != out["quarter"][0]
    half, quarter = out["half"][1], out["quarter"][1]
    assert half.advance[0].relief_travels < 5 < 40 < quarter.advance[0].relief_travels
    assert quarter.time_after_s > 1.2 * half.time_after_s
