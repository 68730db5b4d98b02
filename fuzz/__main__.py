"""Run the fuzz campaign: ``python -m fuzz [--documents N] [--workers W] [--seed S]``.

Each worker process makes documents of every target in proportion to its weight, writes
each to a scratch file, and runs the target on it. A document that raises anything but a
:class:`~flowtwin.errors.FlowtwinError` is a failure (Ctrl-C or SIGTERM stops the campaign),
grouped by signature (exception type and the innermost flowtwin frame); the first document of each
signature is minimised and saved under ``--out`` with its traceback. The summary (documents
per target and stage, failures) is printed and written to ``OUT/summary.json``; the exit
status is 1 when anything failed.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

from fuzz.campaign import run_worker

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m fuzz", description=__doc__.splitlines()[0])
    parser.add_argument("--documents", type=int, default=1_000_000)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--seed", type=int, default=int(time.time()) % 100000)
    parser.add_argument("--out", default=str(ROOT / "fuzz-out"))
    parser.add_argument("--target", action="append", default=[],
                        help="only these targets (default: all)")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    t0 = time.monotonic()
    jobs = [(i, args.workers, args.documents, args.seed, args.out, args.target)
            for i in range(args.workers)]
    if args.workers == 1:
        results = [run_worker(jobs[0])]
    else:
        with mp.get_context("spawn").Pool(args.workers) as pool:
            results = pool.map(run_worker, jobs)
    made: dict[str, int] = {}
    stages: dict[str, dict[str, int]] = {}
    failures: dict[str, dict[str, Any]] = {}
    for r in results:
        for k, v in r["made"].items():
            made[k] = made.get(k, 0) + v
        for k, st in r["stages"].items():
            for s, v in st.items():
                stages.setdefault(k, {})[s] = stages.get(k, {}).get(s, 0) + v
        for sig, f in r["failures"].items():
            if sig in failures:
                failures[sig]["count"] += f["count"]
            else:
                failures[sig] = f
    summary = {"documents": sum(made.values()), "seed": args.seed, "workers": args.workers,
               "wall_s": round(time.monotonic() - t0, 1), "per_target": made,
               "per_stage": stages, "failures": failures,
               "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python "
                          f"{platform.python_version()}"}
    Path(args.out).mkdir(parents=True, exist_ok=True)
    (Path(args.out) / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    print(json.dumps(summary, indent=1))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
