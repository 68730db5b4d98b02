"""Whole-print simulation throughput: read, plan, physics, dynamics and bead metrics.

Files: the largest corpus file (tests/data/corpus), a generated print of >= 2 M lines
(``bench_reader.BIG_SPEC``) and a print of >= 20 hours (the two ~11.5 h Benchy files of the
corpus, one after the other). Machines: the default set-up (``tronvoll2019``: Prusa MK2.5,
Marlin-style planner, slip and grinding on) and the same set-up planned on Klipper
``B.cfg`` with smoothed pressure advance (0.04 s).

Reported, each as wall and CPU seconds and G-code lines per second:

* *cold*: a fresh process with an empty numba cache (``NUMBA_CACHE_DIR`` set to a new
  temporary folder), i.e. including the compilation of every kernel;
* *cached*: a fresh process whose kernels load from the cache (a CLI run);
* *warm*: the best of repeated calls in one process;
* ``simulate_stream`` (bounded memory) next to ``simulate`` (whole tables), with the peak
  resident memory of each in its own process, on the big file and on it repeated twice.

Peer: pyGCodeDecode (PyPI; kinematics only: no extrusion physics) on the first 10 k lines
(3 k with ``--quick``) of the corpus file in the same run; ratio = flowtwin's warm lines/s
end to end over pyGCodeDecode's lines/s.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks import KLIPPER, corpus_dir

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
CORPUS = corpus_dir()
OUT = ROOT / "bench-out"
KLIPPER_B = KLIPPER / "B.cfg"
BENCHY_20H = ("arcwelder_1.2.0_on_slic3r_1.33.3_benchy.gcode",
              "slic3r_1.33.3prusa_benchy.gcode")

_CHILD = r"""
import json, sys, time
t_imp = time.perf_counter()
from flowtwin.simulation import simulate, simulate_stream
def hwm_mb():
    # peak resident set of this process image (VmHWM; ru_maxrss would include the parent
    # that forked it)
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return float("nan")
args = json.loads(sys.argv[1])
t0, c0 = time.perf_counter(), time.process_time()
fn = simulate_stream if args["stream"] else simulate
r = fn(args["path"], klipper_config=args["cfg"])
s = r.summary().as_dict()
out = {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0,
       "import_s": t0 - t_imp, "max_rss_mb": hwm_mb(),
       "total_time_s": s["total_time_s"], "moves": s["moves"],
       "delivered_volume_mm3": s["delivered_volume_mm3"]}
print("RESULT " + json.dumps(out))
"""


def _child(path: Path, cfg: Path | None, *, stream: bool = False,
           cache_dir: str | None = None) -> dict[str, float]:
    """Run one simulation in a fresh process; its timings and peak memory."""
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    arg = json.dumps({"path": str(path), "cfg": str(cfg) if cfg else None, "stream": stream})
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _CHILD, arg], capture_output=True, text=True,
                          env=env, check=False)
    total = time.perf_counter() - t0
    line = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
    if proc.returncode != 0 or not line:
        raise RuntimeError(f"benchmark child failed: {proc.stderr[-2000:]}")
    res: dict[str, float] = json.loads(line[0][7:])
    res["process_wall_s"] = total
    return res


def _lines(path: Path) -> int:
    with path.open("rb") as fh:
        return sum(1 for _ in fh)


def _warm(path: Path, cfg: Path | None, repeat: int, *, stream: bool = False
          ) -> dict[str, float]:
    from flowtwin.simulation import simulate, simulate_stream

    fn = simulate_stream if stream else simulate
    best_w = best_c = float("inf")
    hours = 0.0
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        r = fn(path, klipper_config=cfg)
        best_w = min(best_w, time.perf_counter() - t0)
        best_c = min(best_c, time.process_time() - c0)
        hours = r.summary().total_time_s / 3600.0
    return {"wall_s": best_w, "cpu_s": best_c, "print_hours": hours}


def _stages(path: Path, cfg: Path | None, repeat: int) -> dict[str, float]:
    """Process CPU seconds of each stage of ``simulate`` (best of ``repeat``): read, plan,
    parameters, nominal feed, pressure advance, integration, bead metrics."""
    from flowtwin.dynamics import AdvanceSettings, apply_advance, integrate
    from flowtwin.dynamics.feed import nominal_feed
    from flowtwin.firmware import Firmware
    from flowtwin.gcode.reader import read_gcode
    from flowtwin.planner.from_profile import marlin_settings, read_options
    from flowtwin.planner.klipper import plan_klipper
    from flowtwin.planner.klipper_config import klipper_read_options, load_printer_cfg
    from flowtwin.planner.marlin import plan_marlin
    from flowtwin.planner.plan_file import PlanResult
    from flowtwin.profiles.machine import load_machine
    from flowtwin.simulation.parameters import move_parameters
    from flowtwin.simulation.pipeline import DEFAULT_MACHINE
    from flowtwin.simulation.result import deposition_metrics

    best: dict[str, float] = {}
    for _ in range(repeat):
        m = load_machine(DEFAULT_MACHINE)
        marks = [("", time.process_time())]

        def lap(name: str, marks: list[tuple[str, float]] = marks) -> None:
            marks.append((name, time.process_time()))

        if cfg is not None:
            ks = load_printer_cfg(cfg)
            table = read_gcode(path, options=klipper_read_options(ks))
            lap("read")
            settings: object = ks
            timeline = plan_klipper(table, ks)
            ex = ks.extruders[0]
            adv = AdvanceSettings(Firmware.KLIPPER, k_s=ex.pressure_advance,
                                  smooth_time_s=ex.pressure_advance_smooth_time)
        else:
            table = read_gcode(path, options=read_options(m.printer))
            lap("read")
            settings = marlin_settings(m.printer)
            timeline = plan_marlin(table, settings)  # type: ignore[arg-type]
            adv = AdvanceSettings(Firmware.MARLIN, k_s=m.printer.pressure_advance.k_s)
        lap("plan")
        params = move_parameters(m, table, timeline)
        lap("parameters")
        feed = nominal_feed(table, timeline)
        lap("feed")
        feed = apply_advance(feed, table, adv)
        lap("advance")
        dyn = integrate(feed, params.params)
        lap("integrate")
        deposition_metrics(PlanResult(table, timeline, "", settings), dyn, params)  # type: ignore[arg-type]
        lap("metrics")
        st = {marks[i][0]: marks[i][1] - marks[i - 1][1] for i in range(1, len(marks))}
        st["total"] = sum(st.values())
        st["segments"] = float(feed.n_segments)
        for k, v in st.items():
            best[k] = min(best.get(k, math.inf), v)
        del table, timeline, params, feed, dyn
    return best


def _pygcodedecode(path: Path, k: int) -> dict[str, float] | None:
    """Lines/s of pyGCodeDecode's simulation of the first ``k`` lines of ``path``."""
    try:
        import pyGCodeDecode
        from pyGCodeDecode import gcode_interpreter as gi
    except ImportError:
        return None
    with tempfile.TemporaryDirectory() as tmp:
        part = Path(tmp) / "part.gcode"
        with path.open("rb") as src:
            part.write_bytes(b"".join(next(src) for _ in range(k)))
        presets = Path(pyGCodeDecode.__file__).parent / "data" / "default_printer_presets.yaml"
        setup = gi.setup(presets_file=presets, printer="prusa_mini")
        t0 = time.perf_counter()
        gi.simulation(gcode_path=part, initial_machine_setup=setup, verbosity_level=0)
        t = time.perf_counter() - t0
    return {"lines": k, "wall_s": t, "lines_per_s": k / t}


def _files(quick: bool) -> dict[str, Path]:
    from benchmarks.bench_reader import BIG_SPEC
    from flowtwin.gcode.generator import PrintSpec, write_print

    OUT.mkdir(exist_ok=True)
    files: dict[str, Path] = {}
    corpus = sorted(CORPUS.glob("*.gcode"), key=lambda p: p.stat().st_size)
    if corpus:
        files["corpus"] = corpus[-1]
    big = OUT / ("simulate_big_quick.gcode" if quick else "simulate_big.gcode")
    spec = PrintSpec(layers=150, infill_density=1.0) if quick else BIG_SPEC
    if not big.exists():
        write_print(big, spec)
    files["big"] = big
    if all((CORPUS / f).exists() for f in BENCHY_20H):
        twenty = OUT / "benchy_x2_23h.gcode"
        if not twenty.exists():
            twenty.write_bytes(b"".join((CORPUS / f).read_bytes() for f in BENCHY_20H))
        files["20h"] = twenty
    return files


def run(quick: bool = False) -> dict[str, object]:
    """Time the simulation; print a table; return the figures."""
    files = _files(quick)
    cfg = KLIPPER_B if KLIPPER_B.exists() else None
    results: dict[str, object] = {}
    lines = {name: _lines(p) for name, p in files.items()}
    results["lines"] = lines
    # cold (empty cache) and cached first runs, in fresh processes
    ref = files.get("corpus", files["big"])
    with tempfile.TemporaryDirectory() as cache:
        cold = _child(ref, None, cache_dir=cache)
    cached = _child(ref, None)
    results["cold"] = {"file": ref.name, **cold,
                       "lines_per_s": lines_of(lines, files, ref) / cold["wall_s"]}
    results["cached"] = {"file": ref.name, **cached,
                         "lines_per_s": lines_of(lines, files, ref) / cached["wall_s"]}
    print(f"{ref.name}: cold (empty numba cache) {cold['wall_s']:.2f} s wall "
          f"(+{cold['import_s']:.2f} s import), cached first run {cached['wall_s']:.2f} s")
    # warm, in this process
    from flowtwin.simulation import simulate

    simulate(ref)  # compile / load outside the timings
    if cfg is not None:
        simulate(ref, klipper_config=cfg)
    warm: dict[str, dict[str, object]] = {}
    for name, path in files.items():
        repeat = 1 if quick else (3 if name == "big" else 5)
        for mname, mcfg in (("default", None), ("klipper_B_pa", cfg)):
            if mname != "default" and mcfg is None:
                continue
            row: dict[str, object] = {}
            for mode in ("simulate", "stream"):
                r = _warm(path, mcfg, repeat, stream=mode == "stream")
                n = lines[name]
                row[mode] = {**r, "lines_per_s_wall": n / r["wall_s"],
                             "lines_per_s_cpu": n / r["cpu_s"]}
            warm[f"{name}/{mname}"] = row
            s = row["simulate"]
            t = row["stream"]
            print(f"{path.name} [{mname}] {lines[name]:,} lines, "
                  f"{s['print_hours']:.1f} h print: simulate {s['wall_s']:.2f} s wall "  # type: ignore[index]
                  f"({s['lines_per_s_wall']:,.0f} lines/s; cpu {s['cpu_s']:.2f} s, "  # type: ignore[index]
                  f"{s['lines_per_s_cpu']:,.0f} lines/s), stream {t['wall_s']:.2f} s wall "  # type: ignore[index]
                  f"({t['lines_per_s_wall']:,.0f} lines/s)")  # type: ignore[index]
    results["warm"] = warm
    # CPU time of each stage, both set-ups, on the generated print
    stages = {}
    for mname, mcfg in (("default", None), ("klipper_B_pa", cfg)):
        if mname != "default" and mcfg is None:
            continue
        stages[mname] = _stages(files["big"], mcfg, 1 if not quick else 2)
        print(f"{files['big'].name} [{mname}] CPU s per stage: " + ", ".join(
            f"{k} {v:.2f}" for k, v in stages[mname].items() if k != "segments")
            + f" ({stages[mname]['segments']:,.0f} segments)")
    results["stages_cpu_s"] = stages
    # memory: whole tables against streaming, big file and twice the big file
    if not quick:
        double = OUT / "simulate_big_x2.gcode"
        if not double.exists():
            data = files["big"].read_bytes()
            double.write_bytes(data + data)
        mem = {}
        for label, path in (("big", files["big"]), ("big_x2", double)):
            mem[label] = {"simulate_mb": _child(path, None)["max_rss_mb"],
                          "stream_mb": _child(path, None, stream=True)["max_rss_mb"]}
        results["peak_rss_mb"] = mem
        print("peak resident memory (MB): " + ", ".join(
            f"{k}: simulate {v['simulate_mb']:.0f}, stream {v['stream_mb']:.0f}"
            for k, v in mem.items()))
    # peer
    peer = _pygcodedecode(ref, 3000 if quick else 10000)
    if peer is None:
        print("pyGCodeDecode not installed (make bench installs it)")
    else:
        key = f"{'corpus' if 'corpus' in files else 'big'}/default"
        ours = float(warm[key]["simulate"]["lines_per_s_wall"])  # type: ignore[index]
        peer["flowtwin_over_peer"] = ours / peer["lines_per_s"]
        results["pygcodedecode"] = peer
        print(f"pyGCodeDecode {peer['lines_per_s']:,.0f} lines/s on the first "
              f"{peer['lines']:,.0f} lines of {ref.name}; flowtwin (warm, end to end, "
              f"default machine) is {peer['flowtwin_over_peer']:.0f}x")
    if "20h" in files:
        r20 = warm["20h/default"]["simulate"]
        print(f"20-hour print ({r20['print_hours']:.1f} h): {r20['wall_s']:.2f} s wall")  # type: ignore[index]
    big_row = warm["big/default"]["simulate"]
    print(f"{files['big'].name}: {big_row['print_hours']:.0f} h of printing simulated in "  # type: ignore[index]
          f"{big_row['wall_s']:.2f} s wall")  # type: ignore[index]
    return results


def lines_of(lines: dict[str, int], files: dict[str, Path], path: Path) -> int:
    """Line count of ``path`` (one of ``files``)."""
    for name, p in files.items():
        if p == path:
            return lines[name]
    return _lines(path)


if __name__ == "__main__":
    run(quick=True)
