"""One worker of the fuzz campaign (a module of its own so that spawned processes import it)."""

from __future__ import annotations

import hashlib
import os
import random
import tempfile
import time
import traceback
import warnings
from pathlib import Path
from typing import Any

#: A document whose run takes longer than this (wall clock, s) is recorded as a finding.
SLOW_DOCUMENT_S = 30.0


def _signature(exc: BaseException) -> str:
    frames = traceback.extract_tb(exc.__traceback__)
    inner = [f for f in frames if "flowtwin" in f.filename] or frames
    where = f"{Path(inner[-1].filename).name}:{inner[-1].lineno}" if inner else "?"
    return f"{type(exc).__name__}@{where}"


def run_worker(args: tuple[int, int, int, int, str, list[str]]) -> dict[str, Any]:
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
        started = time.monotonic()
        try:
            target.run(path, run_rng)
        except FlowtwinError:
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
        took = time.monotonic() - started
        if took > SLOW_DOCUMENT_S:
            # a document that takes this long is a finding too (a compiled kernel cannot be
            # interrupted, so a document that never ends stops its worker: watch the log)
            sig = f"{target.name}:slow"
            slow = failures.setdefault(sig, {"count": 0, "file": "", "seconds": 0.0})
            slow["count"] += 1
            if took > slow["seconds"]:
                folder = Path(out) / "failures" / target.name
                folder.mkdir(parents=True, exist_ok=True)
                digest = hashlib.sha256(data).hexdigest()[:12]
                (folder / f"slow-{digest}{target.suffix}").write_bytes(data)
                slow.update(file=str(folder / f"slow-{digest}{target.suffix}"),
                            seconds=round(took, 1))
            print(f"[worker {index}] SLOW {target.name} document: {took:.1f} s", flush=True)
        if index == 0 and (i + 1) % 5000 == 0:
            rate = (i + 1) / (time.monotonic() - t0)
            print(f"[worker 0] {i + 1:,}/{share:,} documents, {rate:,.0f}/s", flush=True)
    return {"made": made, "stages": {t.name: t.stages for t in targets},
            "failures": failures, "seconds": time.monotonic() - t0}
