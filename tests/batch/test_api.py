"""run_batch / run_sweep on a real local dask cluster (and the checks made before it)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from flowtwin.batch import (
    DEFAULT_ENGINE,
    Job,
    expand_inputs,
    load_base,
    read_results,
    row_identity,
    run_batch,
    run_job,
    run_sweep,
)
from flowtwin.errors import FlowtwinError, GcodeError, ProfileError


def test_expand_inputs_files_globs_folders(prints: dict[str, Path], tmp_path: Path) -> None:
    folder = prints["p2"].parent
    sub = tmp_path / "farm" / "queue"
    sub.mkdir(parents=True)
    (sub / "a.gcode.gz").write_bytes(b"")
    (sub / "b.gco").write_text("")
    (sub / "notes.txt").write_text("")
    found = expand_inputs([str(prints["p5"]), str(folder / "p*.gcode"), tmp_path / "farm",
                           "missing.gcode"])
    # Explicit file first, then the sorted glob matches (p5 only once), then the folder.
    assert found[0] == prints["p5"]
    assert sorted(found[1:3]) == sorted(prints[k] for k in ("p2", "p30"))
    assert found[3:] == [sub / "a.gcode.gz", sub / "b.gco", Path("missing.gcode")]
    with pytest.raises(GcodeError, match="matches no file"):
        expand_inputs([str(tmp_path / "*.gcode")])
    (tmp_path / "empty").mkdir()
    with pytest.raises(GcodeError, match="holds no G-code"):
        expand_inputs([tmp_path / "empty"])
    with pytest.raises(GcodeError, match="standard input"):
        expand_inputs(["-"])
    with pytest.raises(GcodeError, match="no G-code files"):
        expand_inputs([])


def test_sweep_errors_are_raised_before_anything_runs(prints: dict[str, Path],
                                                      tmp_path: Path) -> None:
    out = tmp_path / "s.parquet"
    # client=None and no scheduler: a cluster would be started only after the checks.
    with pytest.raises(ProfileError) as info:
        run_sweep(prints["p2"], ["setup.temperature_c=200,210", "drive.pinch_force_n=0:600:100"],
                  out=out)
    assert info.value.field == "drive.pinch_force_n" and info.value.value == 0.0
    with pytest.raises(ProfileError, match="swept twice"):
        run_sweep(prints["p2"], ["setup.temperature_c=200", "material.temperature_c=210"],
                  out=out)
    with pytest.raises(GcodeError, match="cannot open"):
        run_sweep(tmp_path / "gone.gcode", ["setup.temperature_c=200"], out=out)
    with pytest.raises(ProfileError, match="at least one --param"):
        run_sweep(prints["p2"], [], out=out)
    with pytest.raises(FlowtwinError, match="unknown engine"):
        run_batch([prints["p2"]], out=out, engine="fea")  # type: ignore[arg-type]
    assert not out.exists() and not (tmp_path / "s.parquet.parts").exists()


@pytest.mark.service
@pytest.mark.xdist_group("batch-dask")
def test_bad_file_row_carries_the_error_others_unaffected(
        dask_cluster: object, prints: dict[str, Path], tmp_path: Path) -> None:
    files = [prints["p2"], prints["bad"], prints["p5"], tmp_path / "gone.gcode"]
    out = tmp_path / "batch.parquet"
    summary = run_batch(files, out=out, client=dask_cluster, reports_dir=tmp_path / "reports")
    assert (summary.ok, summary.failed, summary.complete) == (2, 2, True)
    rows = read_results(out).to_pylist()
    assert [r["file"] for r in rows] == [str(f) for f in files]
    assert rows[1]["error_kind"] == "input" and f"{prints['bad']}:2" in rows[1]["error"]
    assert rows[3]["error_kind"] == "input" and "gone.gcode" in rows[3]["error"]
    machine = load_base(None)
    for index in (0, 2):
        path = files[index]
        job = Job(index, row_identity(os.path.abspath(path), (), DEFAULT_ENGINE), str(path),
                  str(path), machine)
        expected = run_job(job).row
        assert {k: rows[index][k] for k in expected} == expected
    reports = sorted(p.name for p in (tmp_path / "reports").iterdir())
    assert len(reports) == 2 and reports[0].startswith("p2-")


@pytest.mark.service
@pytest.mark.xdist_group("batch-dask")
def test_sweep_rows_and_resume_skips_done_points(
        dask_cluster: object, prints: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "sweep.csv"
    first = run_sweep(prints["p5"], ["setup.temperature_c=200,210",
                                     "printer.pressure_advance.k_s=0,0.04"],
                      out=out, client=dask_cluster, ship_files=True)
    assert (first.jobs, first.ok) == (4, 4)
    # The generated print sets its nozzle temperature with M104/M109: the sweep says so.
    assert len(first.warnings) == 1 and "setup.temperature_c" in first.warnings[0]
    # A wider grid over the same machine: only the two new points run.
    second = run_sweep(prints["p5"], ["setup.temperature_c=200,210,220",
                                      "printer.pressure_advance.k_s=0,0.04"],
                       out=out, client=dask_cluster, resume=True)
    assert (second.jobs, second.skipped, second.ok) == (6, 4, 2)
    table = read_results(out)
    assert table.num_rows == 6
    assert sorted(table.column("setup.temperature_c").to_pylist()) == [200, 200, 210, 210,
                                                                        220, 220]
    # Another base profile is another run: resume refuses to mix them.
    with pytest.raises(FlowtwinError, match="different run"):
        run_sweep(prints["p5"], ["setup.temperature_c=200"], out=out, client=dask_cluster,
                  resume=True, profile="greeff2017")
