"""Run the fuzz campaign: ``python -m fuzz [--documents N] [--workers W] [--seed S]``.

Each worker process makes documents of every target in proportion to its weight, writes
each to a scratch file, and runs the target on it. A document that raises anything but a
:class:`~flowtwin.errors.FlowtwinError` (or ``KeyboardInterrupt``) is a failure, grouped by
signature (exception type and the innermost flowtwin frame); the first document of each
signature is minimised and saved under ``--out`` with its traceback. The summary (documents
per target and stage, failures) is printed and written to ``OUT/summary.json``; the exit
status is 1 when anything failed.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import multiprocessing as mp
import os
import platform
import random
import sys
import tempfile
import time
import traceback
import warnings
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]


def _signature(exc: BaseException) -> str:
    frames = traceback.extract_tb(exc.__traceback__)
    inner = [f for f in frames if "flowtwin" in f.filename] or frames
    where = f"{Path(inner[-1].filename).name}:{inner[-1].lineno}" if inner else "?"
    return f"{type(exc).__name__}@{where}"


def _worker(args: tuple[int, int, int, int, str, list[str]]) -> dict[str, Any]:
    index, workers, documents, seed, out, only = args
    warnings.simplefilter("ignore")
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    from flowtwin.errors import FlowtwinError
    from fuzz.minimize import ddmin
    from fuzz.targets import all_targets

    rng = random.Random(seed * 1000 + index)
    targets = all_targets(seed, only)
    weights = [t.weight for t in targets]
    made = {t.name: 0 for t in targets}
    failures: dict[str, dict[str, Any]] = {}
    scratch = Path(tempfile.mkdtemp(prefix=f"fuzz{index}-"))
    t0 = time.monotonic()
    share = documents // workers + (index < documents % workers)
    for i in range(share):
        target = rng.choices(targets, weights)[0]
        data = target.make(rng)
        made[target.name] += 1
        path = scratch / f"doc{target.suffix}"
        path.write_bytes(data)
        run_rng = random.Random(rng.random())
        try:
            target.run(path, run_rng)
        except (FlowtwinError, KeyboardInterrupt):
            pass
        except Exception as exc:
            sig = f"{target.name}:{_signature(exc)}"
            if sig in failures:
                failures[sig]["count"] += 1
                continue
            tb = "".join(traceback.format_exception(exc))
            state = run_rng.getstate()
            counted = {t.name: dict(t.stages) for t in targets}

            def fails(candidate: bytes, _t=target, _sig=sig, _state=state,
                      path=path) -> bool:
                path.write_bytes(candidate)
                r = random.Random()
                r.setstate(_state)
                try:
                    _t.run(path, r)
                except FlowtwinError:
                    return False
                except Exception as again:
                    return f"{_t.name}:{_signature(again)}" == _sig
                return False

            small = ddmin(data, fails)
            for t in targets:  # minimisation runs are not campaign documents
                t.stages = counted[t.name]
            digest = hashlib.sha256(small).hexdigest()[:12]
            folder = Path(out) / "failures" / target.name
            folder.mkdir(parents=True, exist_ok=True)
            (folder / f"{digest}{target.suffix}").write_bytes(small)
            (folder / f"{digest}.txt").write_text(f"{sig}\n\n{tb}")
            failures[sig] = {"count": 1, "file": str(folder / f"{digest}{target.suffix}"),
                             "original_bytes": len(data), "minimised_bytes": len(small)}
            print(f"[worker {index}] FAILURE {sig} -> {folder / digest}{target.suffix}",
                  flush=True)
        if index == 0 and (i + 1) % 5000 == 0:
            rate = (i + 1) / (time.monotonic() - t0)
            print(f"[worker 0] {i + 1:,}/{share:,} documents, {rate:,.0f}/s", flush=True)
    return {"made": made, "stages": {t.name: t.stages for t in targets},
            "failures": failures, "seconds": time.monotonic() - t0}


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
        results = [_worker(jobs[0])]
    else:
        with mp.get_context("spawn").Pool(args.workers) as pool:
            results = pool.map(_worker, jobs)
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
