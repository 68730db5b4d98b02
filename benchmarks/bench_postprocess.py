"""``flowtwin postprocess`` as a slicer runs it: a fresh process per file, warm numba cache.

Prints, on the PrusaSlicer 2.7.1 Benchy of the corpus (180 k lines, 112 k moves; carried in
``tests/data/corpus``) with the environment PrusaSlicer gives a post-processing script
(its embedded configuration as ``SLIC3R_*`` variables, ``ConfigBase::setenv_``):

* wall time of ``flowtwin postprocess FILE`` (times written + verdict + sidecar) in a fresh
  process, best and median of several runs after one warm-up run; the same with
  ``--klipper-config`` (the Klipper planner) and on the file stored as ``.bgcode``;
* the process's CPU time and peak resident memory (``wait4``), and the same on a file three
  times as long (the Benchy's moves repeated) to show how memory grows with the file;
* one run with ``--advance --slip`` (as fast as ``compensate`` is);
* the streamed pass (``--stream``, bounded memory: what files above 32 MB get on their own)
  on the Benchy and on the file three times as long;
* ``--gigabyte``: ``flowtwin postprocess`` on the ~1 GB print of
  :func:`benchmarks.bigprint.gigabyte_print` (streamed by size; issue #21.3: < 1 GB of
  memory), wall time and peak resident memory.

Goal (issue #16): ≤ 1 s wall for times + verdict on the Benchy, memory flat in file size.
"""

from __future__ import annotations

import gzip
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / "tests" / "data"
BENCHY = DATA / "corpus" / "prusaslicer_2.7.1_benchy.gcode.gz"
KLIPPER_CFG = DATA / "klipper" / "B.cfg"
FLOWTWIN = str(Path(sys.executable).parent / "flowtwin")


def _slicer_env(text: str, output: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("SLIC3R_")}
    for m in re.finditer(r"^; ([a-z_][a-z0-9_]*) = (.*)$", text, re.MULTILINE):
        env["SLIC3R_" + m.group(1).upper()] = m.group(2)
    env["SLIC3R_PP_HOST"] = "File"
    env["SLIC3R_PP_OUTPUT_NAME"] = str(output)
    return env


def _run(args: list[str], gcode: Path, env: dict[str, str]) -> tuple[float, float, float]:
    """(wall s, CPU s, peak RSS MB) of one fresh process: ``flowtwin ARGS FILE``."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([FLOWTWIN, *args, str(gcode)], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"flowtwin {' '.join(args)} failed ({proc.returncode}):\n{err}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0


def _series(label: str, args: list[str], src: bytes, folder: Path, env: dict[str, str],
            runs: int, suffix: str = ".gcode") -> dict[str, object]:
    walls, cpus, rss = [], [], []
    for i in range(runs + 1):                       # the first run warms the cache
        gcode = folder / f"benchy{suffix}"
        gcode.write_bytes(src)
        wall, cpu, mb = _run(args, gcode, {**env, "SLIC3R_PP_OUTPUT_NAME": str(gcode)})
        if i:
            walls.append(wall)
            cpus.append(cpu)
            rss.append(mb)
    out = {"wall_best_s": min(walls), "wall_median_s": statistics.median(walls),
           "cpu_median_s": statistics.median(cpus), "peak_rss_mb": max(rss), "runs": runs}
    print(f"{label:<44} wall best {out['wall_best_s']:.2f} s, median "
          f"{out['wall_median_s']:.2f} s; CPU {out['cpu_median_s']:.2f} s; "
          f"peak RSS {out['peak_rss_mb']:.0f} MB")
    return out


def _in_process(src: bytes, folder: Path, env: dict[str, str], runs: int
                ) -> dict[str, object]:
    """The work alone: ``postprocess()`` called in this process after a warm-up call."""
    from flowtwin.postprocess import postprocess

    walls, cpus = [], []
    for i in range(runs + 1):
        gcode = folder / "inproc.gcode"
        gcode.write_bytes(src)
        c0, t0 = time.process_time(), time.perf_counter()
        postprocess(gcode, env={**env, "SLIC3R_PP_OUTPUT_NAME": str(gcode)})
        if i:
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
    out = {"wall_best_s": min(walls), "wall_median_s": statistics.median(walls),
           "cpu_median_s": statistics.median(cpus), "runs": runs}
    print(f"{'in process, after imports and a warm-up':<44} wall best "
          f"{out['wall_best_s']:.2f} s, median {out['wall_median_s']:.2f} s; CPU "
          f"{out['cpu_median_s']:.2f} s")
    return out


def run(quick: bool = False) -> dict[str, object]:
    """Time ``flowtwin postprocess`` on the Benchy (see the module docstring)."""
    runs = 3 if quick else 7
    text = gzip.decompress(BENCHY.read_bytes())
    results: dict[str, object] = {"load_average": os.getloadavg()}
    print(f"load average {results['load_average']}")
    with tempfile.TemporaryDirectory(prefix="flowtwin-bench-pp-") as tmp:
        folder = Path(tmp)
        env = _slicer_env(text.decode(errors="replace"), folder / "benchy.gcode")
        results["times_and_verdict"] = _series(
            "postprocess (slicer settings), 180 k lines", ["postprocess"], text, folder, env,
            runs)
        results["in_process"] = _in_process(text, folder, env, runs)
        results["klipper"] = _series(
            "postprocess --klipper-config, 180 k lines",
            ["postprocess", "--klipper-config", str(KLIPPER_CFG)], text, folder, env, runs)
        from flowtwin.gcode.bgcode import text_to_bgcode

        text_to_bgcode(text, folder / "src.bgcode")
        results["bgcode"] = _series(
            "postprocess on .bgcode", ["postprocess"], (folder / "src.bgcode").read_bytes(),
            folder, env, runs, suffix=".bgcode")
        # a file three times as long: memory against file size
        body = text.split(b"\n; prusaslicer_config = begin")[0]
        tail = text[len(body):]
        moves = body.split(b";LAYER_CHANGE", 1)
        triple = moves[0] + (b";LAYER_CHANGE" + moves[1]) * 3 + tail
        results["triple"] = _series(
            "postprocess, 3 x the Benchy (540 k lines)", ["postprocess"], triple, folder,
            env, max(1, runs // 3))
        results["rss_growth"] = (float(results["triple"]["peak_rss_mb"])  # type: ignore[index]
                                 / float(results["times_and_verdict"]["peak_rss_mb"]))  # type: ignore[index]
        print(f"peak memory, 3 x the file / 1 x: {results['rss_growth']:.2f}")
        results["stream"] = _series(
            "postprocess --stream, 180 k lines", ["postprocess", "--stream"], text, folder,
            env, runs)
        results["stream_triple"] = _series(
            "postprocess --stream, 3 x the Benchy", ["postprocess", "--stream"], triple,
            folder, env, max(1, runs // 3))
        results["stream_rss_growth"] = (
            float(results["stream_triple"]["peak_rss_mb"])  # type: ignore[index]
            / float(results["stream"]["peak_rss_mb"]))  # type: ignore[index]
        print(f"streamed peak memory, 3 x the file / 1 x: {results['stream_rss_growth']:.2f}")
        if not quick:
            results["advance_slip"] = _series(
                "postprocess --advance --slip", ["postprocess", "--advance", "--slip"], text,
                folder, env, 1)
    return results


def gigabyte(size_bytes: int = 1_000_000_000) -> dict[str, object]:
    """``flowtwin postprocess`` on a ~1 GB G-code (a copy: the command edits in place), in a
    fresh process without slicer variables (settings from the embedded configuration):
    wall, CPU, peak resident memory."""
    import shutil

    from benchmarks.bigprint import gigabyte_print

    src = gigabyte_print(size_bytes=size_bytes)
    out: dict[str, object] = {"file": src.name, "bytes": src.stat().st_size,
                              "load_average": os.getloadavg()}
    env = {k: v for k, v in os.environ.items() if not k.startswith("SLIC3R_")}
    with tempfile.TemporaryDirectory(prefix="flowtwin-bench-pp-gb-") as tmp:
        gcode = Path(tmp) / src.name
        shutil.copyfile(src, gcode)
        wall, cpu, mb = _run(["postprocess"], gcode, env)
    out.update({"wall_s": wall, "cpu_s": cpu, "peak_rss_mb": mb,
                "load_average_end": os.getloadavg()})
    print(f"postprocess on {int(out['bytes']) / 1e9:.2f} GB: {wall:.0f} s wall, {cpu:.0f} s "
          f"CPU, peak {mb:.0f} MB (goal < 1000 MB); load {out['load_average']}")
    return out


if __name__ == "__main__":
    if "--gigabyte" in sys.argv:
        gigabyte()
    else:
        run(quick="--quick" in sys.argv)
