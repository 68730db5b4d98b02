"""Run every ``benchmarks/bench_*.py`` module and collect their figures.

Each module defines ``run(quick: bool = False) -> dict[str, object]`` that prints a table
of its own figures (with ratios against the peers it measures in the same run) and returns
them; everything is written to ``bench-out/results.json`` together with a description of
the machine, from which ``BENCHMARKS.md`` is updated.

Usage: ``python -m benchmarks [--quick] [name ...]``.
"""

from __future__ import annotations

import importlib
import json
import os
import platform
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def machine_description() -> dict[str, object]:
    """CPU, cores, memory and Python of this machine."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem_gib = None
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                mem_gib = round(int(line.split()[1]) / 1024 / 1024, 1)
    except OSError:
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "memory_gib": mem_gib,
            "python": sys.version.split()[0], "platform": platform.platform()}


def main(argv: list[str]) -> int:
    quick = "--quick" in argv
    wanted = [a for a in argv if not a.startswith("--")]
    names = sorted(p.stem for p in HERE.glob("bench_*.py"))
    if wanted:
        names = [n for n in names if any(w in n for w in wanted)]
    results: dict[str, object] = {"machine": machine_description(),
                                  "date": time.strftime("%Y-%m-%d %H:%M:%S %Z")}
    print(f"machine: {results['machine']}")
    for name in names:
        print(f"\n=== {name} ===", flush=True)
        module = importlib.import_module(f"benchmarks.{name}")
        results[name] = module.run(quick=quick)
    out = Path("bench-out")
    out.mkdir(exist_ok=True)
    (out / "results.json").write_text(json.dumps(results, indent=2, default=str))
    print(f"\nwrote {out / 'results.json'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
