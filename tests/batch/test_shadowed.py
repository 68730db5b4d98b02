"""Swept parameters that the G-code sets itself."""

from __future__ import annotations

import gzip
from pathlib import Path

from flowtwin.batch.shadowed import shadowed_parameters


def test_generated_print_sets_its_temperature(prints: dict[str, Path]) -> None:
    lines = prints["p2"].read_text().splitlines()
    first = next(i for i, t in enumerate(lines, start=1) if t.startswith(("M104", "M109")))
    (msg,) = shadowed_parameters(prints["p2"], ["setup.temperature_c", "drive.pinch_force_n"])
    assert f"{prints['p2']}:{first}:" in msg and "setup.temperature_c" in msg


def test_commands_per_parameter(tmp_path: Path) -> None:
    gcode = tmp_path / "g.gcode"
    gcode.write_text("G28\n; M104 S200 in a comment does not count\nM104 ; no S word\n"
                     "N7 M900 K0.05\nSET_VELOCITY_LIMIT ACCEL=2000\nM2040\nG1 X1\n")
    found = shadowed_parameters(gcode, ["setup.temperature_c", "printer.pressure_advance.k_s",
                                        "printer.limits.max_accel_mm_s2",
                                        "printer.marlin.print_accel_mm_s2",
                                        "drive.pinch_force_n"])
    assert [m.split(": ")[0] for m in found] == [f"{gcode}:4", f"{gcode}:5"]
    assert "pressure_advance.k_s" in found[0] and "max_accel_mm_s2" in found[1]
    packed = tmp_path / "g.gcode.gz"
    packed.write_bytes(gzip.compress(b"G28\nM109 S215\n"))
    assert len(shadowed_parameters(packed, ["setup.temperature_c"])) == 1
    assert shadowed_parameters(packed, ["drive.pinch_force_n"]) == []
