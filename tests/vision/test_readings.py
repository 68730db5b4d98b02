"""CSV, Parquet and PNG outputs: complete, atomic, and faithful to the series."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from flowtwin.vision import (
    Frame,
    Quality,
    measure_frames,
    plot_png,
    write_csv,
    write_parquet,
    write_plot,
)
from flowtwin.vision.synth import MotionSeries, SceneSpec

from .conftest import render


@pytest.fixture(scope="module")
def result():
    scene = SceneSpec(blank_frames=(4,), dropped_frames=(9,), seed=13)
    frames = render(scene, MotionSeries.constant(duration_s=19 / 30, gear_speed_mm_s=2.0,
                                                 slip=0.1))
    seq = [Frame(f.index, f.t_s, f.image) for f in frames]
    return measure_frames(seq, scene.vision_config(), frame_size=(640, 480))


def test_csv_round_trip(tmp_path: Path, result) -> None:
    path = tmp_path / "out" / "vision.csv"
    write_csv(result, path)
    with path.open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(result.series) == 19
    assert [p.name for p in path.parent.iterdir()] == ["vision.csv"]   # no temp files left
    s = result.series
    for i in (2, 7):
        assert float(rows[i]["filament_speed_mm_s"]) == s.filament_speed_mm_s[i]
        assert float(rows[i]["slip_pct"]) == pytest.approx(100 * s.slip[i])
    assert rows[0]["gear_speed_mm_s"] == "" and rows[0]["flag_names"] == "FIRST"
    assert rows[4]["flag_names"] == "BLANK" and rows[4]["width_mm"] == ""
    assert "GAP" in rows[9]["flag_names"]


def test_parquet_round_trip_with_summary_metadata(tmp_path: Path, result) -> None:
    path = tmp_path / "vision.parquet"
    write_parquet(result, path)
    table = pq.read_table(path)
    assert table.num_rows == 19
    np.testing.assert_array_equal(table["gear_speed_mm_s"].to_numpy(),
                                  result.series.gear_speed_mm_s)
    np.testing.assert_array_equal(table["flags"].to_numpy(), result.series.flags)
    assert table["flag_names"][4].as_py() == "BLANK"
    meta = json.loads(table.schema.metadata[b"flowtwin.vision.summary"])
    assert meta["frames"] == 19 and meta["blank_frames"] == 1
    assert meta["slip"] == pytest.approx(result.summary.slip)
    assert set(meta) >= {"gear_speed_mm_s", "filament_speed_mm_s", "slip", "width_mm",
                         "frames", "valid_frames"}


def test_summary_is_json_ready_and_flags_have_names(result) -> None:
    d = result.summary.to_dict()
    json.dumps(d, allow_nan=False)
    assert d["valid_frames"] == 19 - 2 and d["dropped_frames"] == 1
    assert Quality(int(Quality.GAP | Quality.WIDTH_INVALID)).names() == "GAP|WIDTH_INVALID"
    assert not math.isnan(result.summary.volume_flow_mm3_s)


def test_plot_png(tmp_path: Path, result) -> None:
    png = plot_png(result, title="test")
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
    write_plot(result, tmp_path / "p.png")
    assert (tmp_path / "p.png").read_bytes()[:4] == b"\x89PNG"
