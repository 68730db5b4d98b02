"""The per-task job: a pure function from (G-code, machine) to one flat row."""

from __future__ import annotations

import dataclasses
import json
import math
import os
from pathlib import Path

import pytest

from flowtwin.batch.jobs import (
    DEFAULT_ENGINE,
    Job,
    evaluate,
    flatten_summary,
    machine_fingerprint,
    row_identity,
    run_job,
)
from flowtwin.batch.overrides import MachineBuilder, load_base
from flowtwin.errors import FlowtwinError
from flowtwin.planner.plan_file import plan_gcode


def _job(path: Path, **kw: object) -> Job:
    """A plan job (the cheaper engine) unless ``engine`` is given."""
    machine = kw.pop("machine", load_base("tronvoll2019"))
    params = kw.pop("params", ())
    engine = kw.pop("engine", "plan")
    return Job(0, row_identity(os.path.abspath(path), params, engine),  # type: ignore[arg-type]
               str(path), str(path), machine, params, engine, **kw)  # type: ignore[arg-type]


def test_row_carries_the_plan_summary_of_the_file(prints: dict[str, Path]) -> None:
    job = _job(prints["p5"])
    row = run_job(job).row
    expected = plan_gcode(prints["p5"], printer=job.machine.printer).summary().as_dict()
    assert row["error"] is None and row["error_kind"] is None
    assert row["total_time_s"] == expected["total_time_s"]
    assert row["moves"] == expected["moves"] and row["layers"] == 5
    assert row["printer"] == "prusa-i3-mk25" and row["setup"] == "tronvoll2019"
    assert row["file"] == str(prints["p5"]) and row["row_id"] == job.row_id
    # Nested tables become JSON text with the same content.
    assert json.loads(str(row["time_by_feature_s"])) == pytest.approx(
        expected["time_by_feature_s"])


def test_simulate_engine_row_is_the_twin_summary(prints: dict[str, Path]) -> None:
    from flowtwin.simulation import simulate

    assert DEFAULT_ENGINE == "simulate"
    job = _job(prints["p5"], engine="simulate")
    row = run_job(job).row
    expected = flatten_summary(simulate(str(prints["p5"]), machine=job.machine).summary()
                               .as_dict())
    assert row["error"] is None and row["engine"] == "simulate"
    for key in ("total_time_s", "commanded_volume_mm3", "delivered_volume_mm3",
                "volume_error", "rms_flow_error", "worst_width_error_mm", "max_feed_force_n",
                "min_force_margin_n", "grinding_events", "ooze_volume_mm3"):
        assert row[key] == expected[key], key
    assert run_job(job).row == row  # deterministic


def test_same_job_same_row_and_bytes_equal_path(prints: dict[str, Path]) -> None:
    job = _job(prints["p5"])
    first = run_job(job).row
    assert run_job(job).row == first
    shipped = dataclasses.replace(job, source=prints["p5"].read_bytes())
    assert run_job(shipped).row == first


def test_bad_file_gives_an_error_row_naming_file_and_line(prints: dict[str, Path]) -> None:
    row = run_job(_job(prints["bad"])).row
    assert row["error_kind"] == "input"
    assert f"{prints['bad']}:2" in str(row["error"])
    assert "total_time_s" not in row
    # Shipped as bytes, the message still names the file.
    job = _job(prints["bad"])
    shipped = dataclasses.replace(job, source=prints["bad"].read_bytes())
    assert run_job(shipped).row["error"] == row["error"]


def test_missing_file_gives_an_error_row(tmp_path: Path) -> None:
    row = run_job(_job(tmp_path / "nope.gcode")).row
    assert row["error_kind"] == "input" and "nope.gcode" in str(row["error"])


def test_sweep_parameters_are_columns_and_change_the_machine(prints: dict[str, Path]) -> None:
    # Klipper printer: its acceleration limit changes the print time.
    base = load_base("tronvoll2019")
    klipper = MachineBuilder(base).build({"setup.printer": "generic-klipper"})
    slow = MachineBuilder(klipper).build({"printer.limits.max_accel_mm_s2": 500.0})
    params = (("printer.limits.max_accel_mm_s2", 500.0),)
    row_fast = run_job(_job(prints["p5"], machine=klipper)).row
    row_slow = run_job(_job(prints["p5"], machine=slow, params=params)).row
    assert row_slow["printer.limits.max_accel_mm_s2"] == 500.0
    assert float(row_slow["total_time_s"]) > float(row_fast["total_time_s"])  # type: ignore[arg-type]


def test_report_on_request(prints: dict[str, Path]) -> None:
    assert run_job(_job(prints["p2"])).report is None
    report = run_job(_job(prints["p2"], want_report=True)).report
    assert report is not None and len(report["per_layer"]) >= 2  # type: ignore[arg-type]


def test_unknown_or_missing_engine_is_a_user_error(prints: dict[str, Path]) -> None:
    machine = load_base(None)
    with pytest.raises(FlowtwinError, match="unknown engine"):
        evaluate(str(prints["p2"]), machine, engine="fea")  # type: ignore[arg-type]


def test_identity_and_fingerprint_are_stable() -> None:
    a = row_identity("/x.gcode", (("a.b", 1.0), ("c.d", 2)), "plan")
    assert a == row_identity("/x.gcode", (("c.d", 2), ("a.b", 1.0)), "plan")
    assert a != row_identity("/x.gcode", (("a.b", 1.5), ("c.d", 2)), "plan")
    assert a != row_identity("/y.gcode", (("a.b", 1.0), ("c.d", 2)), "plan")
    assert len(a) == 16
    m = load_base("tronvoll2019")
    assert machine_fingerprint(m) == machine_fingerprint(load_base("tronvoll2019"))
    assert machine_fingerprint(m) != machine_fingerprint(
        MachineBuilder(m).build({"drive.pinch_force_n": 70.0}))


def test_flatten_keeps_scalars_and_encodes_tables() -> None:
    import numpy as np

    flat = flatten_summary({"a": np.float64(1.5), "b": 3, "c": None, "d": {"z": 1, "y": 2},
                            "e": [1, 2], "f": float("nan"), "g": "text", "h": True})
    assert flat == {"a": 1.5, "b": 3, "c": None, "d": '{"y":2,"z":1}', "e": "[1,2]",
                    "f": None, "g": "text", "h": True}
    assert isinstance(flat["a"], float) and not isinstance(flat["a"], np.generic)
    assert not any(isinstance(v, float) and math.isnan(v) for v in flat.values())


def test_large_files_are_evaluated_streamed_with_the_same_row(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A row of a file above the streaming threshold has the keys and figures of the
    whole-table row (plan: sums to the bit, times to 1e-11; simulate: to 1e-9)."""
    import flowtwin.planner.plan_stream
    from flowtwin.batch.jobs import evaluate
    from flowtwin.gcode.generator import PrintSpec, write_print
    from flowtwin.profiles.machine import load_machine

    path = tmp_path / "p.gcode"
    write_print(path, PrintSpec(layers=8))
    machine = load_machine("tronvoll2019")
    whole = {e: evaluate(str(path), machine, engine=e)[0] for e in ("plan", "simulate")}
    monkeypatch.setattr(flowtwin.planner.plan_stream, "STREAM_ABOVE_BYTES", 0)
    streamed = {e: evaluate(str(path), machine, engine=e)[0] for e in ("plan", "simulate")}
    for engine, rel in (("plan", 1e-11), ("simulate", 1e-9)):
        a, b = whole[engine], streamed[engine]
        assert a.keys() == b.keys(), engine
        for key, val in a.items():
            if isinstance(val, float):
                assert b[key] == pytest.approx(val, rel=rel, abs=1e-9), (engine, key)
            elif not isinstance(val, dict):
                assert b[key] == val, (engine, key)
