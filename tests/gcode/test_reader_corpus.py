"""The reader on the 18 real slicer files of the reference corpus (reference net filament)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from flowtwin.gcode.reader import read_gcode

ANCHORS = Path(__file__).resolve().parents[1] / "data" / "corpus" / "ANCHORS.tsv"


def _anchors() -> list[dict[str, str]]:
    with ANCHORS.open() as fh:
        return list(csv.DictReader(fh, delimiter="\t"))


@pytest.mark.corpus
@pytest.mark.parametrize("row", _anchors(), ids=lambda r: r["file"])
def test_net_filament_per_tool_matches_reference(row: dict[str, str], corpus_dir: Path) -> None:
    table = read_gcode(corpus_dir / row["file"])
    expected = {int(k): v for k, v in json.loads(row["ref_net_E_mm_per_tool"]).items()}
    got = table.net_filament_mm()
    # ANCHORS.tsv gives 2 decimals; 0.01 mm is the acceptance tolerance
    for tool, value in expected.items():
        assert got.get(tool, 0.0) == pytest.approx(value, abs=0.01), tool
    for tool, value in got.items():
        if tool not in expected:
            assert abs(value) < 0.01, f"tool {tool} has {value} mm not in the reference"
    assert table.n_lines > 0 and len(table.moves) > 0


@pytest.mark.corpus
def test_slicer_metadata_from_headers(corpus_dir: Path) -> None:
    cases = {
        "prusaslicer_2.8.1_minicube_small.gcode": ("PrusaSlicer", 221.0, 252.22),
        "cura_5.9.1.gcode": ("Cura", 2848.0, 1677.14),
        "simplify3d_4.0.0_duet.gcode": ("Simplify3D", 2340.0, 5645.3),
        "ideamaker_5.1.4.gcode": ("ideaMaker", 1835.0, None),
        "orcaslicer_2.3.0b2.gcode": ("OrcaSlicer", 5563.0, 32105.52),
        "kisslicer_1.1.0.5_thinbox_small.gcode": ("KISSlicer", 150.0, None),
        "bambustudio_1.08_eline_multitool.gcode": ("Bambu Studio", 3962.0, None),
    }
    for name, (slicer, time_s, filament) in cases.items():
        md = read_gcode(corpus_dir / name).metadata
        assert md["slicer"] == slicer, name
        assert md["slicer_time_s"] == pytest.approx(time_s), name
        if filament is not None:
            assert md["slicer_filament_mm"] == pytest.approx(filament), name
    prusa = read_gcode(corpus_dir / "prusaslicer_2.7.1_benchy.gcode")
    assert prusa.metadata["layer_height_mm"] == pytest.approx(0.2)
    assert prusa.metadata["nozzle_diameter_mm"] == pytest.approx(0.4)
    assert prusa.metadata["filament_diameter_mm"] == pytest.approx(1.75)
    assert "machine_max_acceleration_x" in prusa.metadata["slicer_config"]  # type: ignore[operator]
    assert prusa.moves["layer"].max() + 1 == 240


@pytest.mark.corpus
def test_rrf_g10_is_a_temperature_not_a_retraction(corpus_dir: Path) -> None:
    table = read_gcode(corpus_dir / "slic3r_1.2.9_duet.gcode")
    g10 = [e for e in table.events if e.code == "G10"]
    assert g10 and all("P" in e.params for e in g10)
    assert table.net_filament_mm()[0] == pytest.approx(1478.61, abs=0.01)
