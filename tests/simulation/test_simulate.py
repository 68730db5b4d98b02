"""Whole-print simulation on G-code the project generates."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from flowtwin.errors import DataError, GcodeError, ProfileError
from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.profiles import load_machine
from flowtwin.simulation import simulate
from flowtwin.simulation.parameters import operating_point

REQUIRED = ("commanded_volume_mm3", "delivered_volume_mm3", "rms_flow_error",
            "max_feed_force_n", "min_force_margin_n", "grinding_events", "ooze_volume_mm3")


@pytest.fixture(scope="module")
def demo_gcode(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("sim") / "demo.gcode"
    write_print(path, PrintSpec(layers=4))
    return path


def test_summary_has_the_required_figures_and_conserves_mass(demo_gcode: Path) -> None:
    result = simulate(demo_gcode)
    s = result.summary().as_dict()
    for key in REQUIRED:
        assert key in s and s[key] is not None, key
    d = result.dynamics
    # filament in = melt out + what stays compressed in the column at the end
    fed = float(np.sum(d.moves["fed_mm3"])) + float(np.sum(d.before_first_move["fed_mm3"]))
    out = float(s["delivered_volume_mm3"]) + float(np.sum(d.before_first_move["out_mm3"]))
    stored = d.final_compression_mm * result.parameters.params.filament_area_mm2
    assert fed == pytest.approx(out + stored, rel=1e-9, abs=1e-9)
    # slip only removes filament: delivered < commanded, by about the mean slip
    assert 0.0 < float(s["commanded_volume_mm3"]) - float(s["delivered_volume_mm3"])
    assert s["grinding_events"] == 0 and float(s["min_force_margin_n"]) > 0  # type: ignore[arg-type]


def test_steady_line_delivers_the_slip_reduced_flow_at_nominal_width(tmp_path: Path) -> None:
    """A long straight line at constant feed: after the lag, the bead is the commanded one
    minus the steady slip of the operating point (the dynamics settle to it)."""
    machine = load_machine("tronvoll2019")
    width, height, speed = 0.48, 0.2, 20.0
    area_bead = width * height - (1 - math.pi / 4) * height ** 2
    e_per_mm = area_bead / machine.filament.area_mm2
    lines = ["G21", "G90", "M83", "G28", "G1 Z0.2 F600", "G1 X0 Y10 F3000",
             f"G1 X200 Y10 E{200 * e_per_mm:.6f} F{speed * 60:.0f}", "G1 X201 Y10 F3000"]
    path = tmp_path / "line.gcode"
    path.write_text("\n".join(lines) + "\n")
    result = simulate(path, machine=machine)
    feed = speed * e_per_mm
    op = operating_point(machine, feed_mm_s=feed, layer_height_mm=height)
    i = int(np.flatnonzero(result.plan.table.moves["line"] == 7)[0])
    slip = float(result.dynamics.moves["slip"][i])
    assert slip == pytest.approx(op.slip, rel=0.03)  # mean over the move includes the start
    w = float(result.metrics["width_mean_mm"][i])
    assert w == pytest.approx(width, rel=0.05)
    assert float(result.metrics["width_nominal_mm"][i]) == pytest.approx(width, rel=1e-6)


def test_greeff_machine_slips_about_10_percent_end_to_end(tmp_path: Path) -> None:
    machine = load_machine("greeff2017")
    # 2 mm/s of 2.85 mm filament for 60 s, as a slow line in the air (no layer below)
    lines = ["G21", "G90", "M83", "G28", "G1 Z10 F600",
             "G1 X120 E120 F60", "G1 X121 F600"]
    path = tmp_path / "greeff.gcode"
    path.write_text("\n".join(lines) + "\n")
    result = simulate(path, machine=machine)
    i = int(np.flatnonzero(result.plan.table.moves["line"] == 6)[0])
    slip = float(result.dynamics.moves["slip"][i])
    assert slip == pytest.approx(0.10, abs=0.025)


def test_series_written_as_parquet_and_csv(demo_gcode: Path, tmp_path: Path) -> None:
    result = simulate(demo_gcode, series_dt_s=0.05)
    cols = {"t_s", "e_cmd_mm", "v_fil_mm_s", "q_out_mm3_s", "feed_force_n", "slip"}
    table = pq.read_table(result.write_series(tmp_path / "s.parquet"))
    assert cols <= set(table.column_names)
    t = table.column("t_s").to_numpy()
    assert np.all(np.diff(t) > 0)
    header = (tmp_path / "s.csv")
    result.write_series(header)
    assert cols <= set(header.read_text().splitlines()[0].split(","))
    with pytest.raises(DataError, match=r"parquet or \.csv"):
        result.write_series(tmp_path / "s.xlsx")


def test_pressure_advance_changes_the_prediction_not_the_volume(demo_gcode: Path) -> None:
    from flowtwin.profiles import load_builtin
    from flowtwin.profiles.machine import Machine

    base = load_machine("tronvoll2019")
    pa_printer = load_builtin("generic-klipper").model_copy(  # type: ignore[union-attr]
        update={"pressure_advance": load_builtin("generic-klipper")  # type: ignore[union-attr]
                .pressure_advance.model_copy(update={"k_s": 0.06})})
    m = Machine(setup=base.setup, printer=pa_printer, drive=base.drive, roller=base.roller,
                hotend=base.hotend, material=base.material, filament=base.filament)
    with_pa = simulate(demo_gcode, machine=m).summary()
    without = simulate(demo_gcode, machine=m, pressure_advance=False).summary()
    assert with_pa.commanded_volume_mm3 == pytest.approx(without.commanded_volume_mm3)
    # K_LA = K of the twin: the advance brings the delivered flow closer to the command
    assert with_pa.rms_flow_error < without.rms_flow_error


def test_empty_file_is_a_clear_error(tmp_path: Path) -> None:
    path = tmp_path / "empty.gcode"
    path.write_text("; nothing\nM104 S200\n")
    with pytest.raises(GcodeError, match="no moves to simulate"):
        simulate(path)


def test_impossible_profile_is_a_clear_error(tmp_path: Path) -> None:
    setup = tmp_path / "bad.toml"
    setup.write_text('kind = "material"\nname = "x"\ndensity_g_cm3 = -1\n')
    with pytest.raises(ProfileError, match="density_g_cm3"):
        from flowtwin.profiles import load_profile

        load_profile(setup)


def test_summary_is_json_serialisable(demo_gcode: Path) -> None:
    s = simulate(demo_gcode).summary().as_dict()
    json.dumps(s, allow_nan=False)
