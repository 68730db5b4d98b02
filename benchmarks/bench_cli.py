"""The commands as a user types them: a fresh ``flowtwin ...`` process, wall clock and peak
resident memory of the whole command (median of 5; 1 with ``--quick``), warm numba cache.

* help and version: ``flowtwin --help``, ``flowtwin plan --help``, ``flowtwin simulate
  --help``, ``flowtwin calibrate --help``, ``flowtwin --version`` (goal <= 0.25 s);
* the built-in example print (``flowtwin demo``'s G-code, 843 lines): ``plan``,
  ``simulate``, ``plan --json``, ``simulate --json``, ``limits``, ``profiles list``,
  ``postprocess`` and ``compensate --advance`` (goal <= 0.5 s);
* the 2.82 M-line PrusaSlicer print of :mod:`benchmarks.bigprint` (generated once with
  Debian's prusa-slicer; skipped when it is missing and cannot be made): ``plan
  --klipper-config B.cfg --json`` (goal >= 1.5 M lines/s), ``simulate --json`` (default
  set-up; goal >= 600 k lines/s) and ``simulate --klipper-config B.cfg --json`` (Klipper's
  smoothed pressure advance, 0.04 s; goal >= 500 k lines/s), with peak memory per line
  (goal <= 150 bytes);
* cold start: ``flowtwin simulate`` and ``flowtwin plan`` of the example with an empty
  numba cache (``NUMBA_CACHE_DIR`` a new folder: every kernel compiled), once.

``python -m benchmarks.bench_cli --gigabyte`` runs the bounded-memory check of issue #21.3
instead: ``flowtwin plan`` and ``flowtwin simulate`` (and a ``batch`` row) of a generated
~1 GB G-code file (:func:`benchmarks.bigprint.gigabyte_print`), peak memory against 1 GB.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks import KLIPPER

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
#: The installed ``flowtwin`` command next to this Python (else ``python -m flowtwin``).
_SCRIPT = Path(sys.executable).with_name("flowtwin")
FLOWTWIN = [str(_SCRIPT)] if _SCRIPT.exists() else [sys.executable, "-m", "flowtwin"]
KLIPPER_B = KLIPPER / "B.cfg"


def _command(args: list[str], *, env: dict[str, str] | None = None,
             cwd: Path | None = None) -> dict[str, float]:
    """One fresh ``flowtwin ARGS`` process: wall s, user + system CPU s, peak RSS MB."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([*FLOWTWIN, *args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, env=env, cwd=cwd)
    _pid, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise RuntimeError(f"flowtwin {' '.join(args)} failed ({proc.returncode}): "
                           f"{err[-1500:]}")
    return {"wall_s": wall, "cpu_s": usage.ru_utime + usage.ru_stime,
            "max_rss_mb": usage.ru_maxrss / 1024.0}


def _median(args: list[str], repeat: int, **kw: object) -> dict[str, float]:
    runs = [_command(args, **kw) for _ in range(repeat)]  # type: ignore[arg-type]
    return {k: statistics.median(r[k] for r in runs) for k in runs[0]} | {"runs": repeat}


def _lines(path: Path) -> int:
    with path.open("rb") as fh:
        return sum(1 for _ in fh)


def _example(folder: Path) -> Path:
    from flowtwin.gcode.generator import PrintSpec, write_print

    path = folder / "example.gcode"
    write_print(path, PrintSpec())
    return path


def _copy(path: Path, name: str) -> Path:
    """A copy of ``path`` beside it (postprocess edits its file in place)."""
    target = path.with_name(name)
    target.write_bytes(path.read_bytes())
    return target


def _load() -> float:
    return os.getloadavg()[0]


def run(quick: bool = False) -> dict[str, object]:
    """Every command of the module docstring; prints a table and returns the figures."""
    repeat = 1 if quick else 5
    results: dict[str, object] = {"load_average_start": _load()}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        example = _example(folder)
        _command(["simulate", str(example), "--json"])  # warm the numba cache
        _command(["plan", str(example), "--json"])
        _command(["compensate", str(example), "--advance", "-o", str(folder / "comp.gcode")])
        rows: dict[str, dict[str, float]] = {}
        cases = {
            "--help": ["--help"], "--version": ["--version"],
            "plan --help": ["plan", "--help"], "simulate --help": ["simulate", "--help"],
            "calibrate --help": ["calibrate", "--help"],
            "plan example": ["plan", str(example)],
            "plan example --json": ["plan", str(example), "--json"],
            "simulate example": ["simulate", str(example)],
            "simulate example --json": ["simulate", str(example), "--json"],
            "limits": ["limits"], "profiles list": ["profiles", "list"],
            "postprocess example": ["postprocess", str(_copy(example, "pp.gcode"))],
            "compensate example --advance": ["compensate", str(example), "--advance",
                                             "-o", str(folder / "comp.gcode")],
        }
        for name, args in cases.items():
            rows[name] = _median(args, repeat)
            r = rows[name]
            print(f"flowtwin {name:<26} {r['wall_s']:6.3f} s wall  {r['cpu_s']:6.3f} s CPU  "
                  f"{r['max_rss_mb']:6.0f} MB", flush=True)
        results["small"] = rows
        # cold start: an empty numba cache
        cold: dict[str, dict[str, float]] = {}
        for name, args in (("simulate example", ["simulate", str(example), "--json"]),
                           ("plan example", ["plan", str(example), "--json"])):
            env = dict(os.environ, NUMBA_CACHE_DIR=str(folder / f"numba-{len(cold)}"))
            cold[name] = _command(args, env=env)
            print(f"cold start (empty numba cache): flowtwin {name}: "
                  f"{cold[name]['wall_s']:.1f} s wall", flush=True)
        results["cold_start"] = cold
    results["big"] = _big(repeat if not quick else 1)
    results["load_average_end"] = _load()
    print(f"load average: {results['load_average_start']:.1f} at the start, "
          f"{results['load_average_end']:.1f} at the end")
    return results


def _big(repeat: int) -> dict[str, object]:
    from benchmarks.bigprint import big_print

    try:
        path = big_print()
    except (SystemExit, subprocess.CalledProcessError) as exc:
        print(f"big print not available ({exc}): skipped")
        return {}
    n = _lines(path)
    out: dict[str, object] = {"file": path.name, "lines": n}
    cases = {
        "plan --klipper-config B.cfg --json": ["plan", str(path), "--klipper-config",
                                               str(KLIPPER_B), "--json"],
        "simulate --json": ["simulate", str(path), "--json"],
        "simulate --klipper-config B.cfg --json": ["simulate", str(path), "--klipper-config",
                                                   str(KLIPPER_B), "--json"],
    }
    for name, args in cases.items():
        r = _median(args, max(1, min(repeat, 3)))
        r["lines_per_s"] = n / r["wall_s"]
        r["lines_per_cpu_s"] = n / r["cpu_s"]
        r["bytes_per_line"] = r["max_rss_mb"] * 1024 * 1024 / n
        out[name] = r
        print(f"flowtwin {name} ({n:,} lines): {r['wall_s']:.2f} s wall "
              f"({r['lines_per_s']:,.0f} lines/s), {r['cpu_s']:.2f} s CPU, "
              f"{r['max_rss_mb']:.0f} MB ({r['bytes_per_line']:.0f} bytes/line)", flush=True)
    return out


def gigabyte(size_bytes: int = 1_000_000_000) -> dict[str, object]:
    """Issue #21.3: plan, simulate and a batch row of a ~1 GB G-code file, peak memory."""
    from benchmarks.bigprint import gigabyte_print

    path = gigabyte_print(size_bytes=size_bytes)
    size = path.stat().st_size
    out: dict[str, object] = {"file": path.name, "bytes": size}
    with tempfile.TemporaryDirectory() as tmp:
        cases = {
            "plan --json": ["plan", str(path), "--json"],
            "plan --klipper-config B.cfg --json": ["plan", str(path), "--klipper-config",
                                                   str(KLIPPER_B), "--json"],
            "simulate --json": ["simulate", str(path), "--json"],
            "batch (plan row)": ["batch", str(path), "--engine", "plan", "--workers", "1",
                                 "--no-progress", "--out", str(Path(tmp) / "rows.csv")],
        }
        for name, args in cases.items():
            r = _command(args)
            out[name] = r
            print(f"flowtwin {name} on {size / 1e9:.2f} GB: {r['wall_s']:.1f} s wall, "
                  f"peak {r['max_rss_mb']:.0f} MB (goal < 1000 MB)", flush=True)
    return out


if __name__ == "__main__":
    if "--gigabyte" in sys.argv:
        gigabyte()
    else:
        run(quick="--quick" in sys.argv)
