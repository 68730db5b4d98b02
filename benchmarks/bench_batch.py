"""``flowtwin batch`` throughput on dask, against calling the Python API in a loop.

Files: the reference corpus (tests/data/corpus, 18 real slicer files); without it, generated
prints (said so in the output). For each engine (``simulate``, the default, and ``plan``):

* loop — :func:`flowtwin.batch.run_job` on every file in this process, one after the
  other (the same work with no dask, no Parquet parts);
* batch, 1 and 2 workers — :func:`flowtwin.batch.run_batch` on a LocalCluster of that many
  worker processes, already started and warmed up (one unmeasured pass), so the time is
  the steady state of a long batch; cluster start-up is reported apart;
* overhead per task — (batch with 1 worker − loop) / files: what dask, pickling the job,
  fetching the row and the streaming writer add to each file; split with dask's task
  stream into the time the worker was not computing (scheduling, transfer, writer) and the
  worker's own compute time against the loop's (a worker process computes more slowly
  than the main process when the cores are shared);
* tiny tasks — a 64-point sweep of a 2-layer print, where the work per task is ~1 ms, to
  show the fixed cost per task on its own.

Each timed figure is the median of ``repeat`` runs. The machine has 2 cores shared with
other work: the load average is printed with the figures.
"""

from __future__ import annotations

import os
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from distributed import get_task_stream

from benchmarks import corpus_dir
from flowtwin.batch import (
    DEFAULT_ENGINE,
    ENGINES,
    Engine,
    Job,
    MachineBuilder,
    RunSummary,
    dask_client,
    grid_points,
    load_base,
    parse_axis,
    row_identity,
    run_batch,
    run_job,
    run_sweep,
)
from flowtwin.gcode.generator import PrintSpec, write_print

HERE = Path(__file__).resolve().parent
SWEEP = "setup.temperature_c=185:240:0.859375"  # 65 values (binary-exact step)


def _median_time(fn: Callable[[], object], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def _files(tmp: Path, quick: bool) -> tuple[list[Path], str]:
    corpus = corpus_dir()
    if corpus.is_dir():
        files = sorted(p for p in corpus.iterdir() if p.suffix == ".gcode")
        return (files[:6] if quick else files), f"corpus ({corpus})"
    files = []
    for layers in (20, 50, 100, 200, 400, 800):
        path = tmp / f"gen{layers}.gcode"
        write_print(path, PrintSpec(layers=layers))
        files.append(path)
    return files, "generated prints (corpus not found)"


def _engines(quick: bool) -> list[Engine]:
    """Both engines (the default first); the default alone when quick."""
    ordered = [DEFAULT_ENGINE, *(e for e in ENGINES if e != DEFAULT_ENGINE)]
    return ordered[:1] if quick else ordered


def _loop(files: list[Path], engine: Engine) -> Callable[[], object]:
    machine = load_base(None)
    jobs = [Job(i, row_identity(os.path.abspath(p), (), engine), str(p), os.path.abspath(p),
                machine, (), engine) for i, p in enumerate(files)]
    return lambda: [run_job(j) for j in jobs]


def _sweep_loop(source: Path, engine: Engine) -> Callable[[], object]:
    builder = MachineBuilder(load_base(None))
    jobs = []
    for i, point in enumerate(grid_points([parse_axis(SWEEP)])):
        params = tuple(point.items())
        jobs.append(Job(i, row_identity(str(source), params, engine), str(source), str(source),
                        builder.build(point), params, engine))
    return lambda: [run_job(j) for j in jobs]


def _on_cluster(workers: int, files: list[Path], tiny: Path, engine: Engine, tmp: Path,
                repeat: int, megabytes: float, n_tiny: int) -> dict[str, float]:
    """Batch and tiny-sweep times on a warmed local cluster of ``workers`` processes."""
    t0 = time.perf_counter()
    with dask_client(workers=workers) as client:
        t_start = time.perf_counter() - t0
        counter = iter(range(10 ** 6))

        def batch() -> RunSummary:
            return run_batch(files, out=tmp / f"b{next(counter)}.parquet", engine=engine,
                             client=client)

        def sweep() -> RunSummary:
            return run_sweep(tiny, [SWEEP], out=tmp / f"s{next(counter)}.parquet",
                             engine=engine, client=client)

        t1 = time.perf_counter()
        failed = batch().failed  # cold: warms the workers
        t_first = time.perf_counter() - t1
        t_batch = _median_time(batch, repeat)
        with get_task_stream(client=client) as stream:
            t_streamed = _median_time(batch, 1)
        compute_s = sum(ss["stop"] - ss["start"] for task in stream.data
                        for ss in task["startstops"] if ss["action"] == "compute")
        sweep()
        t_sweep = _median_time(sweep, repeat)
    print(f"  {workers} worker(s): start {t_start:.1f} s, first (cold) batch {t_first:.2f} s, "
          f"batch {t_batch:.2f} s = {len(files) / t_batch:.1f} files/s "
          f"({megabytes / t_batch:.1f} MB/s); tiny sweep {t_sweep:.2f} s = "
          f"{n_tiny / t_sweep:.0f} tasks/s; rows with an error: {failed}")
    print(f"    one more batch: {t_streamed:.2f} s wall, of which the workers computed "
          f"{compute_s:.2f} s (task stream)")
    return {"cluster_start_s": t_start, "first_batch_s": t_first, "rows_with_error": failed,
            "streamed_batch_s": t_streamed, "worker_compute_s": compute_s,
            "batch_s": t_batch, "files_per_s": len(files) / t_batch,
            "mb_per_s": megabytes / t_batch, "tiny_sweep_s": t_sweep,
            "tiny_tasks_per_s": n_tiny / t_sweep}


def run(quick: bool = False) -> dict[str, object]:
    """Measure and print; return the figures."""
    repeat = 1 if quick else 3
    out: dict[str, object] = {}
    with tempfile.TemporaryDirectory(prefix="bench-batch-") as tmp_text:
        tmp = Path(tmp_text)
        files, origin = _files(tmp, quick)
        tiny = tmp / "tiny.gcode"
        write_print(tiny, PrintSpec(layers=2))
        megabytes = sum(p.stat().st_size for p in files) / 1e6
        out.update(files=len(files), megabytes=round(megabytes, 2), origin=origin,
                   load_average_before=os.getloadavg())
        print(f"files: {len(files)} ({megabytes:.1f} MB), {origin}")
        print(f"load average before: {os.getloadavg()}")
        n_tiny = len(list(grid_points([parse_axis(SWEEP)])))
        for engine in _engines(quick):
            loop = _loop(files, engine)
            loop()  # warm: imports, numba cache, profile library
            t_loop = _median_time(loop, repeat)
            sweep_loop = _sweep_loop(tiny, engine)
            sweep_loop()
            t_tiny_loop = _median_time(sweep_loop, repeat)
            fig: dict[str, object] = {"loop_s": t_loop, "tiny_loop_s": t_tiny_loop}
            print(f"\n[{engine}] loop in this process: {t_loop:.2f} s "
                  f"({len(files) / t_loop:.1f} files/s); tiny sweep loop {t_tiny_loop:.3f} s "
                  f"for {n_tiny} points")
            for workers in (1, 2):
                fig[f"{workers}w"] = _on_cluster(workers, files, tiny, engine, tmp, repeat,
                                                 megabytes, n_tiny)
            one, two = fig["1w"], fig["2w"]
            assert isinstance(one, dict) and isinstance(two, dict)
            fig["overhead_per_task_ms"] = (one["batch_s"] - t_loop) / len(files) * 1e3
            # Wall time the single worker was not computing, per task: dask + writer.
            fig["idle_per_task_ms"] = ((one["streamed_batch_s"] - one["worker_compute_s"])
                                       / len(files) * 1e3)
            fig["worker_compute_over_loop"] = one["worker_compute_s"] / t_loop
            fig["tiny_overhead_per_task_ms"] = (one["tiny_sweep_s"] - t_tiny_loop) / n_tiny * 1e3
            fig["speedup_2w_over_1w"] = one["batch_s"] / two["batch_s"]
            fig["speedup_2w_over_loop"] = t_loop / two["batch_s"]
            print(f"  1 worker: not computing {fig['idle_per_task_ms']:.1f} ms per task; its "
                  f"compute took x{fig['worker_compute_over_loop']:.2f} the loop's time")
            print(f"  overhead per task (1 worker vs loop): {fig['overhead_per_task_ms']:.1f} ms "
                  f"(corpus), {fig['tiny_overhead_per_task_ms']:.1f} ms (tiny tasks); "
                  f"2 workers / 1 worker: x{fig['speedup_2w_over_1w']:.2f}; 2 workers / loop: "
                  f"x{fig['speedup_2w_over_loop']:.2f}")
            out[engine] = fig
        out["load_average_after"] = os.getloadavg()
        print(f"\nload average after: {os.getloadavg()}")
    return out


if __name__ == "__main__":
    run()
