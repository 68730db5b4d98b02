"""Fixtures of the batch tests: small generated prints and a real local dask cluster."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path

import pytest

from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.planner.plan_file import plan_gcode
from flowtwin.simulation import simulate


@pytest.fixture(scope="session")
def prints(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Generated prints of 2, 5 and 30 layers, and a file that is not G-code."""
    folder = tmp_path_factory.mktemp("prints")
    out: dict[str, Path] = {}
    for layers in (2, 5, 30):
        out[f"p{layers}"] = folder / f"p{layers}.gcode"
        write_print(out[f"p{layers}"], PrintSpec(layers=layers))
    bad = folder / "bad.gcode"
    bad.write_text("G1 X10 E1\nG1 X20 Q\n")  # 'Q' without a number: a malformed word
    out["bad"] = bad
    # Compile (or load from numba's cache) the reader and planner kernels once here, so the
    # worker processes find the cache instead of compiling concurrently.
    plan_gcode(out["p2"], printer="prusa-i3-mk25")
    plan_gcode(out["p2"], printer="generic-klipper")
    simulate(out["p2"], machine="tronvoll2019")
    return out


@pytest.fixture(scope="session")
def dask_cluster(prints: dict[str, Path]) -> Iterator[object]:
    """A LocalCluster of two worker processes on 127.0.0.1 (no dashboard), with a client."""
    from distributed import Client, LocalCluster

    # dashboard_address=None would still bind the scheduler's health/metrics HTTP routes to
    # port 8787 (then warn and move if it is taken): ask for a free loopback port instead.
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                           host="127.0.0.1", dashboard_address="127.0.0.1:0",
                           scheduler_kwargs={"dashboard": False},
                           silence_logs=logging.CRITICAL)
    client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()
