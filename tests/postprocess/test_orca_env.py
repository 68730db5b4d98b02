"""``flowtwin postprocess`` run the way OrcaSlicer runs a post-processing script.

OrcaSlicer's ``run_post_process_scripts`` (``src/libslic3r/GCode/PostProcessor.cpp``, the same
mechanism as PrusaSlicer's) puts every option of the print's full configuration into the
environment as ``SLIC3R_<NAME>`` (``ConfigBase::setenv_``), sets ``SLIC3R_PP_HOST`` and
``SLIC3R_PP_OUTPUT_NAME``, and runs ``$SHELL -c "<script> '<path>'"``. On "Export G-code"
for a printer that is not a Bambu Lab one (``BackgroundSlicingProcess::finalize_gcode``) the
path is a copy ``<temporary G-code>.pp`` in the system's temporary folder and the output
name is the final path; the slicer copies the processed file there afterwards.

The environment here is that of the OrcaSlicer 2.3.0-beta2 file of the corpus (a Creality K1
Max, Klipper flavor): its embedded configuration is the full print configuration OrcaSlicer
exported, and ``setenv_`` turns exactly those options into variables.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from flowtwin.planner.plan_file import plan_gcode
from flowtwin.profiles.toml_io import profile_from_dict, save_profile

pytestmark = [pytest.mark.corpus]

ORCA = "orcaslicer_2.3.0b2"


@pytest.fixture
def orca_job(pph: Any, tmp_path: Path) -> tuple[Path, Path, dict[str, str], str]:
    """The temporary copy OrcaSlicer hands the script, the final output name, the
    environment, and the original text."""
    temp_dir = tmp_path / "tmp"
    export_dir = tmp_path / "export"
    temp_dir.mkdir()
    export_dir.mkdir()
    gcode = pph.corpus_copy(ORCA, temp_dir / ".4242.gcode.pp")
    text = gcode.read_text()
    config = pph.embedded_config(text)
    assert config["gcode_flavor"] == "klipper" and "machine_max_speed_x" in config
    output = export_dir / "K1 part.gcode"
    return gcode, output, pph.slicer_environment(config, output_name=output), text


def test_orca_environment_plans_with_the_slicers_limits(
        orca_job: tuple[Path, Path, dict[str, str], str], flowtwin_exe: str, pph: Any,
        tmp_path: Path) -> None:
    gcode, output, env, original = orca_job
    proc = pph.run_like_slicer(f"{flowtwin_exe} postprocess", gcode, env)
    assert proc.returncode == 0, proc.stderr
    assert "flowtwin:" in proc.stderr
    # edited in place (the slicer's copy), sidecar beside the final name, nothing else there
    text = gcode.read_text()
    assert text != original and "; postprocessed by flowtwin" in text
    assert sorted(p.name for p in output.parent.iterdir()) == ["K1 part.gcode.flowtwin.json"]
    side = json.loads((output.parent / "K1 part.gcode.flowtwin.json").read_text())
    assert side["slicer"]["settings"] == "environment"
    assert side["printer"]["source"] == "slicer settings (environment)"
    assert side["printer"]["firmware"] == "klipper"
    limits = side["printer"]["profile"]["limits"]
    cfg = pph.embedded_config(original)
    assert limits["max_velocity_mm_s"] == min(float(cfg["machine_max_speed_x"].split(",")[0]),
                                              float(cfg["machine_max_speed_y"].split(",")[0]))
    assert limits["max_accel_mm_s2"] == min(
        float(cfg["machine_max_acceleration_x"].split(",")[0]),
        float(cfg["machine_max_acceleration_y"].split(",")[0]))
    # the written times are `flowtwin plan` with that printer, run on its own
    profile = tmp_path / "printer.toml"
    save_profile(profile_from_dict({"kind": "printer", **side["printer"]["profile"]}),
                 profile)
    plan = pph.flowtwin_json(flowtwin_exe, "plan", str(gcode), "--profile", str(profile))
    total = float(plan["total_time_s"])
    assert abs(side["times"]["total_s"] - total) < 1e-9
    assert f"; estimated printing time (normal mode) = {pph.dhms(total)}\n" in text
    first = next(r["time_s"] for r in plan["per_layer"] if r["layer"] == 0)
    assert f"; estimated first layer printing time (normal mode) = {pph.dhms(first)}\n" in text
    # every M73 P R line by PrusaSlicer's formulas (OrcaSlicer inherited them)
    p = plan_gcode(gcode, printer=profile)
    n = 0
    for number, line in enumerate(text.splitlines(), start=1):
        if line.startswith("M73 P"):
            e = pph.elapsed_at(p, number)
            assert line == f"M73 P{pph.percent(e, total)} R{int((total - e + 0.5) / 60)}"
            n += 1
    assert n == original.count("\nM73 P") > 100


def test_a_print_host_upload_keeps_the_sidecar_beside_the_gcode(
        orca_job: tuple[Path, Path, dict[str, str], str], flowtwin_exe: str,
        pph: Any) -> None:
    # uploading to a print host, the output name is the name on the host, not a path here
    gcode, _, env, _ = orca_job
    env = {**env, "SLIC3R_PP_HOST": "OctoPrint", "SLIC3R_PP_OUTPUT_NAME": "K1 part.gcode"}
    proc = pph.run_like_slicer(f"{flowtwin_exe} postprocess --klipper-config "
                               f"{pph.KLIPPER_CFG}", gcode, env)
    assert proc.returncode == 0, proc.stderr
    side = json.loads(gcode.with_name(gcode.name + ".flowtwin.json").read_text())
    assert side["slicer"]["host"] == "OctoPrint"
    assert side["printer"]["source"] == "klipper-config"
    assert side["output"] == str(gcode)
