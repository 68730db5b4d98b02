"""Reader (and read + plan) throughput against the Python G-code readers on PyPI.

Files: the largest corpus file (tests/data/corpus) and a generated print of >= 2 M lines.
Peers, run on the same files in the same process: Printrun's ``printrun.gcoder``,
``gcodeparser``, ``gcode-lib``, ``pygcode`` (line by line) and a plain regex loop.
Peers that are not installed are reported as such (``make bench`` installs them).

Times are process CPU time (``time.process_time``, best of several runs: the machine is
shared, CPU time is what one core spends) with the wall-clock time next to them; the peers
are timed the same way in the same run.

Memory: peak traced allocation (tracemalloc, numpy included) per move of a whole-file read,
and the peak of a streaming read of a file 1x and 4x as long (it must not grow).

First run: the numba kernels are compiled once and cached on disk (``cache=True``); the
cost of a first read with an empty cache and with the warm cache is measured in fresh
processes.
"""

from __future__ import annotations

import functools
import gc
import os
import re
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

from benchmarks import corpus_dir
from flowtwin.gcode.generator import PrintSpec, write_print
from flowtwin.gcode.reader import iter_move_chunks, read_gcode

HERE = Path(__file__).resolve().parent
OUT = HERE.parent / "bench-out"

#: A generated print of about 2.1 M lines: 0.45 mm lines, dense infill, polygon pillar.
BIG_SPEC = PrintSpec(size_x_mm=120.0, size_y_mm=120.0, layers=1450, infill_density=1.0,
                     use_arcs=False, polygon_segments=360, pillar_radius_mm=20.0)


def _best_of(fn: Callable[[], object], repeat: int) -> tuple[float, float]:
    """Best process CPU time and best wall time of ``repeat`` calls, s."""
    best_cpu = best_wall = float("inf")
    for _ in range(repeat):
        gc.collect()
        c0, t0 = time.process_time(), time.perf_counter()
        fn()
        best_cpu = min(best_cpu, time.process_time() - c0)
        best_wall = min(best_wall, time.perf_counter() - t0)
    return best_cpu, best_wall


_FIRST_READ = """
import sys, time
t0 = time.perf_counter()
from flowtwin.gcode.reader import read_gcode
read_gcode(sys.argv[1])
print(time.perf_counter() - t0)
"""


def _first_read_s(path: Path, cache_dir: str) -> float:
    """Wall time of import + first read in a fresh process with ``NUMBA_CACHE_DIR``."""
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    out = subprocess.run([sys.executable, "-c", _FIRST_READ, str(path)], env=env, check=True,
                         capture_output=True, text=True).stdout
    return float(out.split()[-1])


def _compile_cost(path: Path) -> dict[str, float]:
    """First read with an empty numba cache (compiles) and again with the cache filled."""
    with tempfile.TemporaryDirectory() as cache:
        cold = _first_read_s(path, cache)
        warm = _first_read_s(path, cache)
    return {"cold_cache_s": cold, "warm_cache_s": warm}


def _regex_loop(path: Path) -> int:
    word = re.compile(r"([A-Z])([-+]?[0-9.]+)")
    n = 0
    with path.open("rb") as fh:
        for raw in fh:
            line = raw.split(b";", 1)[0].decode("ascii", "replace").upper()
            if line:
                n += len(word.findall(line))
    return n


def _peers(path: Path) -> dict[str, Callable[[], object]]:
    text_lines: list[str] = path.read_text(errors="replace").splitlines()
    peers: dict[str, Callable[[], object]] = {"regex loop": lambda: _regex_loop(path)}
    try:
        from printrun import gcoder

        peers["printrun.gcoder"] = lambda: gcoder.GCode(text_lines)
    except ImportError:
        pass
    try:
        import gcodeparser

        peers["gcodeparser"] = lambda: gcodeparser.GcodeParser(path.read_text(errors="replace"),
                                                              include_comments=False).lines
    except ImportError:
        pass
    try:
        import gcode_lib

        peers["gcode-lib"] = lambda: gcode_lib.parse_lines(path.read_text(errors="replace"))
    except ImportError:
        pass
    try:
        from pygcode import Line

        def _pygcode() -> int:
            count = 0
            for raw in text_lines:
                try:
                    Line(raw)
                except Exception:
                    count += 1
            return count

        peers["pygcode"] = _pygcode
    except ImportError:
        pass
    return peers


def _plan_fn(path: Path) -> Callable[[], object]:
    from flowtwin.planner.from_profile import klipper_settings
    from flowtwin.planner.klipper import plan_klipper
    from flowtwin.planner.klipper_config import klipper_read_options
    from flowtwin.planner.plan_file import load_printer

    settings = klipper_settings(load_printer("generic-klipper"))
    opts = klipper_read_options(settings)
    return lambda: plan_klipper(read_gcode(path, options=opts), settings)


def _memory(path: Path) -> tuple[float, float, int]:
    """Peak and retained traced bytes per move of a whole-file read (table + events)."""
    gc.collect()
    tracemalloc.start()
    table = read_gcode(path)
    current, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    n = max(1, len(table.moves))
    return peak / n, current / n, len(table.moves)


def _stream_peak(path: Path) -> int:
    gc.collect()
    tracemalloc.start()
    for _chunk in iter_move_chunks(path, chunk_bytes=4 * 1024 * 1024):
        pass
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak


def run(quick: bool = False) -> dict[str, object]:
    OUT.mkdir(exist_ok=True)
    files: list[Path] = []
    corpus = sorted(corpus_dir().glob("*.gcode"), key=lambda p: p.stat().st_size)
    if corpus:
        files.append(corpus[-1])
    # the quick run has its own files: it must not replace the 2 M-line print
    stem = "generated_quick" if quick else "generated_big"
    big = OUT / f"{stem}.gcode"
    spec = BIG_SPEC if not quick else PrintSpec(layers=200, infill_density=1.0)
    if not big.exists() or quick:
        write_print(big, spec)
    files.append(big)
    read_gcode(files[0])  # compile (or load the numba cache) outside the timings
    results: dict[str, object] = {}
    for path in files:
        n_lines = sum(1 for _ in path.open("rb"))
        repeat = 1 if quick else 7
        t_read, w_read = _best_of(functools.partial(read_gcode, path), repeat)
        row: dict[str, object] = {"lines": n_lines, "read_cpu_s": t_read, "read_wall_s": w_read,
                                  "read_lines_per_s": n_lines / t_read,
                                  "read_lines_per_wall_s": n_lines / w_read}
        plan = _plan_fn(path)
        plan()
        t_plan, w_plan = _best_of(plan, 1 if quick else 3)
        row["read_plan_cpu_s"] = t_plan
        row["read_plan_lines_per_s"] = n_lines / t_plan
        row["read_plan_lines_per_wall_s"] = n_lines / w_plan
        bytes_per_move, kept_per_move, moves = _memory(path)
        row["moves"] = moves
        row["peak_bytes_per_move"] = bytes_per_move
        row["retained_bytes_per_move"] = kept_per_move
        peers: dict[str, float] = {}
        if not quick or path == files[0]:
            for name, fn in _peers(path).items():
                try:
                    t, _wall = _best_of(fn, 1 if quick or n_lines > 500_000 else 2)
                except Exception as exc:
                    print(f"  {name:<20} failed on this file: {type(exc).__name__}: {exc}")
                    continue
                peers[name] = n_lines / t
        row["peers_lines_per_s"] = peers
        row["speedup_vs_peers"] = {k: (n_lines / t_read) / v for k, v in peers.items()}
        results[path.name] = row
        print(f"{path.name}: {n_lines:,} lines, {moves:,} moves")
        print(f"  flowtwin read        {n_lines / t_read:>12,.0f} lines/s CPU "
              f"({n_lines / w_read:,.0f} wall)")
        print(f"  flowtwin read+plan   {n_lines / t_plan:>12,.0f} lines/s CPU "
              f"({n_lines / w_plan:,.0f} wall)")
        print(f"  memory               {kept_per_move:>12,.0f} bytes/move kept (table + events), "
              f"{bytes_per_move:,.0f} at the peak of the read (input text and buffers incl.)")
        for name, rate in peers.items():
            ratio = n_lines / t_read / rate
            print(f"  {name:<20} {rate:>12,.0f} lines/s CPU  flowtwin is {ratio:6.1f}x")
    if not quick:
        cost = _compile_cost(files[0])
        results["first_read"] = cost
        print(f"first read of {files[0].name} in a fresh process: {cost['cold_cache_s']:.1f} s "
              f"with an empty numba cache (compiling), {cost['warm_cache_s']:.1f} s with the "
              "cache")
    # streaming: peak memory must not grow with the file
    small = files[-1]
    quad = OUT / f"{stem}_x4.gcode"
    if not quad.exists() or quick:
        data = small.read_bytes()
        quad.write_bytes(data * 4)
    p1, p4 = _stream_peak(small), _stream_peak(quad)
    results["streaming_peak_bytes"] = {"1x": p1, "4x": p4, "ratio": p4 / p1}
    print(f"streaming peak memory: {p1 / 1e6:.1f} MB (1x file), {p4 / 1e6:.1f} MB (4x file)")
    return results
