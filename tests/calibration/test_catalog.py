"""The pattern library: every kind, every firmware, checked by the reader and the planner."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from flowtwin.calibration.patterns.catalog import PATTERN_KINDS, generate_pattern, pattern_params
from flowtwin.calibration.patterns.pattern import PrintSettings, write_pattern
from flowtwin.calibration.patterns.verify import verify_pattern
from flowtwin.errors import CalibrationError
from flowtwin.firmware import Firmware

#: Small versions of every pattern (fast to plan).
SMALL: dict[str, dict[str, Any]] = {
    "kline": {"k_end": 0.02},
    "chevron": {"k_end": 0.01, "layers": 2},
    "tower": {"height_mm": 1.0, "size_mm": 20.0},
    "flow": {"multiplier_start": 0.95, "multiplier_end": 1.05, "layers": 1},
    "maxflow": {"flow_start_mm3_s": 4.0, "flow_end_mm3_s": 12.0, "flow_step_mm3_s": 4.0},
    "flowline": {"flow_mm3_s": 6.0},
}


@pytest.mark.parametrize("kind", sorted(PATTERN_KINDS))
def test_every_kind_reads_back_and_reaches_its_speeds(kind: str, gc: Any,
                                                      firmware: Firmware) -> None:
    pattern = generate_pattern(kind, PrintSettings(firmware=firmware), SMALL[kind])
    check = verify_pattern(pattern)
    assert check.unknown_commands == {}
    assert check.ok, check.summary()
    assert check.net_filament_mm == pytest.approx(pattern.filament_mm,
                                                  abs=gc.e_tolerance(pattern))
    assert len(check.segments) == len(pattern.segments) > 0


def test_acceleration_and_smoothing_commands_are_honoured_by_the_planner(gc: Any) -> None:
    s = PrintSettings(firmware=Firmware.KLIPPER, accel_mm_s2=1500.0, pa_smooth_time_s=0.02)
    pattern = generate_pattern("kline", s, SMALL["kline"])
    assert "SET_VELOCITY_LIMIT ACCEL=1500" in pattern.lines
    assert all(line.endswith("SMOOTH_TIME=0.02") for line in pattern.lines
               if line.startswith("SET_PRESSURE_ADVANCE"))
    check = verify_pattern(pattern, printer="generic-klipper")
    assert check.ok
    # with 1500 mm/s² the fast segment still cruises, but Klipper plans at that accel:
    from flowtwin.planner.plan_file import plan_gcode

    result = plan_gcode(pattern.text().encode(), printer="generic-klipper")
    accel = result.timeline.phases["accel"][gc.extruding(result.table)]
    assert float(accel.max()) == pytest.approx(1500.0)


def test_unknown_kind_and_parameter() -> None:
    with pytest.raises(CalibrationError, match=r"\[kind\]: unknown pattern.*allowed: kline"):
        generate_pattern("spiral")
    with pytest.raises(CalibrationError, match=r"\[speed_mm_s\].*kline pattern has no "
                                               r"parameter.*allowed: fast_length_mm, "
                                               r"fast_speed_mm_s"):
        pattern_params("kline", {"speed_mm_s": 50.0})


def test_pattern_must_fit_the_bed() -> None:
    s = PrintSettings(center_xy_mm=(30.0, 110.0))      # an 80 mm line centred at x = 30
    with pytest.raises(CalibrationError, match=r"\[bed_size_mm\].*does not fit on the bed"):
        generate_pattern("kline", s, SMALL["kline"])


@pytest.mark.parametrize(("field", "value"), [
    ("line_width_mm", 0.15),          # narrower than the layer: [001 Eq. 7] ill-defined
    ("layer_height_mm", 0.5),         # thicker than the nozzle
    ("filament_diameter_mm", 0.3),
    ("fan_percent", 120.0),
])
def test_settings_are_validated(field: str, value: float) -> None:
    with pytest.raises(CalibrationError, match=rf"\[{field}\]"):
        PrintSettings(**{field: value})  # type: ignore[arg-type]


def test_smoothing_window_for_marlin_is_rejected() -> None:
    with pytest.raises(CalibrationError, match="no advance smoothing window"):
        PrintSettings(firmware=Firmware.MARLIN, pa_smooth_time_s=0.04)


def test_write_pattern_is_the_text(tmp_path: Path) -> None:
    pattern = generate_pattern("flowline", PrintSettings(), SMALL["flowline"])
    out = tmp_path / "sub" / "line.gcode"
    assert write_pattern(out, pattern) == len(pattern.lines)
    assert out.read_text() == pattern.text()
    assert [p.name for p in out.parent.iterdir()] == ["line.gcode"]   # no temporary left


def test_summary_is_plain_data() -> None:
    import json

    pattern = generate_pattern("tower", PrintSettings(), SMALL["tower"])
    summary = pattern.summary()
    assert json.loads(json.dumps(summary)) == summary
    assert summary["values"] == pytest.approx([0.005 * 0.2 * (i + 1) for i in range(5)])
