"""Fixtures of the post-processing tests: Debian's real PrusaSlicer and OpenSCAD, a test part,
and the installed ``flowtwin`` command exactly as a slicer runs it."""

from __future__ import annotations

import gzip
import os
import re
import shutil
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / "data"
#: A Klipper printer.cfg carried with the tests (reference config B, tests/data/klipper).
KLIPPER_CFG = DATA / "klipper" / "B.cfg"
CORPUS = DATA / "corpus"


@pytest.fixture(scope="session")
def prusa_slicer() -> str:
    """Debian's ``prusa-slicer`` (installed with ``openscad`` when missing)."""
    proc = subprocess.run([sys.executable, str(HERE / "slicer_install.py")],
                          capture_output=True, text=True, timeout=1900, check=False)
    if proc.returncode != 0:
        pytest.fail(f"installing prusa-slicer failed:\n{proc.stdout}\n{proc.stderr}")
    return proc.stdout.strip().splitlines()[-1]


@pytest.fixture(scope="session")
def part_stl(prusa_slicer: str, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The test part (``part.scad``) as an STL made by OpenSCAD."""
    out = tmp_path_factory.mktemp("part") / "part.stl"
    subprocess.run(["openscad", "-o", str(out), str(HERE / "part.scad")], check=True,
                   capture_output=True, timeout=300)
    return out


@pytest.fixture(scope="session")
def flowtwin_exe() -> str:
    """The ``flowtwin`` command of this installation (what a user puts in the slicer)."""
    exe = Path(sys.executable).parent / "flowtwin"
    assert exe.exists(), exe
    return str(exe)


def slice_part(prusa_slicer: str, stl: Path, out: Path, *options: str,
               post_process: str | None = None, keep_before: Path | None = None
               ) -> subprocess.CompletedProcess[str]:
    """Slice ``stl`` with PrusaSlicer's command line into ``out`` (a Marlin 2 printer with
    M73 progress and its machine limits in the G-code), with an optional post-processing
    script; ``keep_before``: a first script copies the slicer's file there before it runs
    (PrusaSlicer runs its scripts in order; two slicings of one model need not agree move
    for move, its seams are placed in parallel)."""
    cmd = [prusa_slicer, "--export-gcode", "--gcode-flavor", "marlin2", "--remaining-times",
           "--machine-limits-usage", "emit_to_gcode", "--center", "100,100",
           "--layer-height", "0.2", *options]
    if keep_before is not None:
        cmd += ["--post-process", f"/bin/sh -c 'cp \"$0\" {keep_before}'"]
    if post_process is not None:
        cmd += ["--post-process", post_process]
    cmd += ["-o", str(out), str(stl)]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=900, check=False)


def flowtwin_json(exe: str, *args: str) -> dict[str, object]:
    """Run ``flowtwin ARGS --json`` in a fresh process and return its JSON object."""
    import json

    proc = subprocess.run([exe, *args, "--json"], capture_output=True, text=True,
                          timeout=900, check=False)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)  # type: ignore[no-any-return]


def dhms(seconds: float) -> str:
    """PrusaSlicer's ``1h 2m 3s`` form, to the nearest second (the test's own copy)."""
    s = int(round(seconds))
    parts = [(s // 86400, "d"), (s % 86400 // 3600, "h"), (s % 3600 // 60, "m")]
    lead = [f"{v}{u}" for k, (v, u) in enumerate(parts) if v or any(p[0] for p in parts[:k])]
    return " ".join([*lead, f"{s % 60}s"])


def corpus_copy(name: str, dest: Path) -> Path:
    """A corpus file decompressed to ``dest``."""
    dest.write_bytes(gzip.decompress((CORPUS / f"{name}.gcode.gz").read_bytes()))
    return dest


def embedded_config(text: str) -> dict[str, str]:
    """The ``; key = value`` lines of a G-code's configuration block(s)."""
    out: dict[str, str] = {}
    for m in re.finditer(r"^; ([a-z_][a-z0-9_]*) = (.*)$", text, re.MULTILINE):
        out[m.group(1)] = m.group(2)
    return out


def slicer_environment(config: Mapping[str, str], *, output_name: Path,
                       host: str = "File") -> dict[str, str]:
    """The environment a Slic3r-family slicer gives a post-processing script
    (``ConfigBase::setenv_``: every option as ``SLIC3R_<NAME IN CAPITALS>``, plus
    ``SLIC3R_PP_HOST`` and ``SLIC3R_PP_OUTPUT_NAME``), on top of this process's."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("SLIC3R_")}
    env.update({"SLIC3R_" + k.upper(): v for k, v in config.items()})
    env["SLIC3R_PP_HOST"] = host
    env["SLIC3R_PP_OUTPUT_NAME"] = str(output_name)
    return env


def run_like_slicer(script: str, gcode: Path, env: Mapping[str, str]
                    ) -> subprocess.CompletedProcess[str]:
    """Run a post-processing script the way PrusaSlicer and OrcaSlicer do on POSIX
    (``PostProcessor.cpp``): ``$SHELL -c "<script> '<path>'"``, stderr captured."""
    shell = env.get("SHELL") or shutil.which("sh") or "/bin/sh"
    quoted = "'" + str(gcode).replace("'", "'\\''") + "'"
    return subprocess.run([shell, "-c", f"{script} {quoted}"], env=dict(env),
                          capture_output=True, text=True, timeout=900, check=False)


@pytest.fixture(scope="session")
def pph() -> object:
    """The helpers of this module (``slice_part``, ``flowtwin_json``, ``dhms``, …) for the
    tests, which cannot import a conftest under ``--import-mode=importlib``."""
    return sys.modules[__name__]


def percent(elapsed_s: float, total_s: float) -> int:
    """PrusaSlicer's ``M73 P``: ``⌊100·t/T⌋``, 100 at the end (the test's own copy; 1e-9
    guards against 100·t/T falling just below an integer in floating point)."""
    return 100 if elapsed_s >= total_s else int(100 * elapsed_s / total_s + 1e-9)


_LAST_PLAN: list[tuple[Any, np.ndarray, np.ndarray, dict[int, list[tuple[int, float]]]]] = []


def _plan_lines(plan: Any) -> tuple[np.ndarray, np.ndarray, dict[int, list[tuple[int, float]]]]:
    """The plan's move lines (contiguous), its moves' end times (the timeline works them
    out on every call) and its dwells as ``(line, seconds)`` by the move they come before,
    kept for the last plan asked about (a test asks for every line of a file)."""
    if not _LAST_PLAN or _LAST_PLAN[0][0] is not plan:
        lines = np.ascontiguousarray(plan.table.moves["line"])
        dwells: dict[int, list[tuple[int, float]]] = {}
        for move, seconds, reason in plan.timeline.dwell_s:
            if m := re.search(r"line (\d+)$", reason):
                dwells.setdefault(min(int(move), lines.size), []).append(
                    (int(m.group(1)), float(seconds)))
        end = np.asarray(plan.timeline.end_time_s, dtype=np.float64)
        _LAST_PLAN[:] = [(plan, lines, end, dwells)]
    return _LAST_PLAN[0][1], _LAST_PLAN[0][2], _LAST_PLAN[0][3]


def elapsed_at(plan: Any, line: int) -> float:
    """When the printer reaches ``line`` (the test's own definition): the end of the last
    move from an earlier line, plus the dwells of earlier lines since that move (the
    planner names each dwell's line in its reason)."""
    lines, end, dwells = _plan_lines(plan)
    k = int(np.searchsorted(lines, line))
    t = float(end[k - 1]) if k else 0.0
    for dwell_line, seconds in dwells.get(k, ()):
        if dwell_line < line:
            t += seconds
    return t
