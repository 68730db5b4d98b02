"""Scale-out: many G-code files (``batch``) or many profile variants (``sweep``) on dask.

Quick start::

    from flowtwin.batch import read_results, run_batch, run_sweep

    run_batch(["prints/"], out="farm.parquet", profile="tronvoll2019")
    run_sweep("part.gcode", ["setup.temperature_c=190:230:5", "drive.pinch_force_n=60,80,100"],
              out="sweep.parquet")
    table = read_results("sweep.parquet")        # pyarrow.Table, also of an interrupted run

By default a local cluster of worker processes (one per CPU) runs the jobs; ``scheduler=``
uses an existing dask cluster. See docs/batch.md.
"""

from typing import TYPE_CHECKING

from flowtwin._lazy import lazy_exports

if TYPE_CHECKING:
    from flowtwin.batch.api import GCODE_SUFFIXES, RunSummary, expand_inputs, run_batch, run_sweep
    from flowtwin.batch.cluster import (
        DEFAULT_RETRIES,
        ClusterError,
        Progress,
        RunStats,
        dask_client,
        default_workers,
        run_jobs,
    )
    from flowtwin.batch.jobs import (
        DEFAULT_ENGINE,
        ENGINES,
        Engine,
        Job,
        JobResult,
        error_row,
        evaluate,
        flatten_summary,
        machine_fingerprint,
        row_identity,
        run_job,
    )
    from flowtwin.batch.overrides import (
        DEFAULT_SETUP,
        MachineBuilder,
        check_axes,
        count_points,
        grid_points,
        load_base,
        sample_points,
    )
    from flowtwin.batch.params import ALIASES, PARTS, Axis, describe_path, parse_axis, resolve_path
    from flowtwin.batch.store import ResultWriter, parts_dir, read_results

__all__ = [
    "ALIASES",
    "DEFAULT_ENGINE",
    "DEFAULT_RETRIES",
    "DEFAULT_SETUP",
    "ENGINES",
    "GCODE_SUFFIXES",
    "PARTS",
    "Axis",
    "ClusterError",
    "Engine",
    "Job",
    "JobResult",
    "MachineBuilder",
    "Progress",
    "ResultWriter",
    "RunStats",
    "RunSummary",
    "check_axes",
    "count_points",
    "dask_client",
    "default_workers",
    "describe_path",
    "error_row",
    "evaluate",
    "expand_inputs",
    "flatten_summary",
    "grid_points",
    "load_base",
    "machine_fingerprint",
    "parse_axis",
    "parts_dir",
    "read_results",
    "resolve_path",
    "row_identity",
    "run_batch",
    "run_job",
    "run_jobs",
    "run_sweep",
    "sample_points",
]

# names resolve on first use: `flowtwin batch --help` does not import dask or pyarrow
__getattr__, __dir__ = lazy_exports(__name__, {
    "GCODE_SUFFIXES": "flowtwin.batch.api",
    "RunSummary": "flowtwin.batch.api",
    "expand_inputs": "flowtwin.batch.api",
    "run_batch": "flowtwin.batch.api",
    "run_sweep": "flowtwin.batch.api",
    "DEFAULT_RETRIES": "flowtwin.batch.cluster",
    "ClusterError": "flowtwin.batch.cluster",
    "Progress": "flowtwin.batch.cluster",
    "RunStats": "flowtwin.batch.cluster",
    "dask_client": "flowtwin.batch.cluster",
    "default_workers": "flowtwin.batch.cluster",
    "run_jobs": "flowtwin.batch.cluster",
    "DEFAULT_ENGINE": "flowtwin.batch.jobs",
    "ENGINES": "flowtwin.batch.jobs",
    "Engine": "flowtwin.batch.jobs",
    "Job": "flowtwin.batch.jobs",
    "JobResult": "flowtwin.batch.jobs",
    "error_row": "flowtwin.batch.jobs",
    "evaluate": "flowtwin.batch.jobs",
    "flatten_summary": "flowtwin.batch.jobs",
    "machine_fingerprint": "flowtwin.batch.jobs",
    "row_identity": "flowtwin.batch.jobs",
    "run_job": "flowtwin.batch.jobs",
    "DEFAULT_SETUP": "flowtwin.batch.overrides",
    "MachineBuilder": "flowtwin.batch.overrides",
    "check_axes": "flowtwin.batch.overrides",
    "count_points": "flowtwin.batch.overrides",
    "grid_points": "flowtwin.batch.overrides",
    "load_base": "flowtwin.batch.overrides",
    "sample_points": "flowtwin.batch.overrides",
    "ALIASES": "flowtwin.batch.params",
    "PARTS": "flowtwin.batch.params",
    "Axis": "flowtwin.batch.params",
    "describe_path": "flowtwin.batch.params",
    "parse_axis": "flowtwin.batch.params",
    "resolve_path": "flowtwin.batch.params",
    "ResultWriter": "flowtwin.batch.store",
    "parts_dir": "flowtwin.batch.store",
    "read_results": "flowtwin.batch.store",
})
