"""Planner throughput: Klipper and Marlin look-ahead on the corpus and on 2 M random moves.

Peer: pyGCodeDecode (PyPI), a kinematic G-code simulator, on the same corpus file — its
figure is G-code lines per second of its whole simulation (it has no separate planner).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from benchmarks import corpus_dir
from flowtwin.gcode.moves import MOVE_DTYPE, Event, MoveTable
from flowtwin.gcode.reader import read_gcode
from flowtwin.planner.from_profile import klipper_settings
from flowtwin.planner.klipper import plan_klipper
from flowtwin.planner.klipper_config import klipper_read_options
from flowtwin.planner.marlin import MarlinSettings, plan_marlin
from flowtwin.planner.plan_file import load_printer

HERE = Path(__file__).resolve().parent


def _random_table(n: int) -> MoveTable:
    rng = np.random.default_rng(0)
    heading = np.cumsum(rng.normal(0, 0.8, n))
    step = rng.uniform(0.1, 5, n)
    m = np.zeros(n, MOVE_DTYPE)
    m["x"] = np.cumsum(step * np.cos(heading))
    m["y"] = np.cumsum(step * np.sin(heading))
    m["de"] = np.where(rng.random(n) < 0.85, 0.035 * step, 0.0)
    m["e"] = np.cumsum(m["de"])
    m["feed_mm_s"] = rng.uniform(20, 200, n)
    m["flow"] = 1.0
    m["line"] = np.arange(1, n + 1)
    events = [Event(k, k, "M204", {"S": float(rng.choice([500.0, 1000.0, 2000.0]))})
              for k in range(0, n, 25)]
    return MoveTable(moves=m, events=events, start_xyze=np.zeros(4))


def _timed(fn: object, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()  # type: ignore[operator]
        best = min(best, time.perf_counter() - t0)
    return best


def run(quick: bool = False) -> dict[str, object]:
    n = 200_000 if quick else 2_000_000
    table = _random_table(n)
    ks = klipper_settings(load_printer("generic-klipper"))
    out: dict[str, object] = {"random_moves": n}
    plan_klipper(table, ks)
    t = _timed(lambda: plan_klipper(table, ks), 1 if quick else 3)
    out["klipper_moves_per_s"] = n / t
    print(f"klipper look-ahead      {n / t / 1e6:6.2f} M moves/s ({n:,} random moves)")
    for name, s in {"jd": MarlinSettings(),
                    "classic": MarlinSettings(junction_deviation_mm=None)}.items():
        plan_marlin(table, s)
        t = _timed(lambda s=s: plan_marlin(table, s), 1 if quick else 3)
        out[f"marlin_{name}_moves_per_s"] = n / t
        print(f"marlin ({name:<7}) look-ahead {n / t / 1e6:6.2f} M moves/s")
    corpus = sorted(corpus_dir().glob("*.gcode"), key=lambda p: p.stat().st_size)
    if corpus:
        path = corpus[-1]
        lines = sum(1 for _ in path.open("rb"))
        opts = klipper_read_options(ks)
        tab = read_gcode(path, options=opts)
        t_plan = _timed(lambda: plan_klipper(tab, ks), 3)
        t_all = _timed(lambda: plan_klipper(read_gcode(path, options=opts), ks), 3)
        out[path.name] = {"lines": lines, "moves": len(tab), "plan_s": t_plan,
                          "read_plan_s": t_all, "read_plan_lines_per_s": lines / t_all}
        print(f"{path.name}: plan {len(tab) / t_plan / 1e6:.2f} M moves/s, "
              f"read+plan {lines / t_all / 1e6:.2f} M lines/s")
        try:
            out[path.name]["pygcodedecode"] = _pygcodedecode(path, lines, quick)  # type: ignore[index]
        except ImportError:
            print("pyGCodeDecode not installed (make bench installs it)")
    return out


def _pygcodedecode(path: Path, lines: int, quick: bool) -> dict[str, float]:
    """Lines/s of pyGCodeDecode's simulation of the first ``k`` lines of ``path``."""
    import tempfile

    from pyGCodeDecode import gcode_interpreter as gi

    k = 3000 if quick else 10000
    with tempfile.TemporaryDirectory() as tmp:
        part = Path(tmp) / "part.gcode"
        with path.open("rb") as src:
            part.write_bytes(b"".join(next(src) for _ in range(k)))
        import pyGCodeDecode

        presets = Path(pyGCodeDecode.__file__).parent / "data" / "default_printer_presets.yaml"
        setup = gi.setup(presets_file=presets, printer="prusa_mini")
        t0 = time.perf_counter()
        gi.simulation(gcode_path=part, initial_machine_setup=setup, verbosity_level=0)
        t = time.perf_counter() - t0
    print(f"pyGCodeDecode: {k / t:,.0f} lines/s on the first {k:,} lines")
    return {"lines": k, "lines_per_s": k / t}
