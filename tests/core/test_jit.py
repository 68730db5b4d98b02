"""The kernels' decorator (:mod:`flowtwin._jit`): numba's cache loads without refreshing every
lowering registry, and compiling afterwards still works."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from flowtwin._jit import LEAN_CACHE_LOAD

_PROBE = r"""
import json, sys
import numpy as np
import flowtwin
from flowtwin.gcode.generator import PrintSpec, write_print
write_print(sys.argv[1], PrintSpec())
before = "scipy.linalg" in sys.modules
plan = flowtwin.plan(sys.argv[1])            # cached kernels: reader, planner, totals
loaded_scipy = sorted(m for m in sys.modules if m.startswith("scipy"))

from flowtwin._jit import njit

@njit(cache=False)
def fresh(a):                                # compiled now: needs the full registries
    return np.linalg.norm(a) + np.sort(a)[0] + np.sum(np.cumsum(a))

value = fresh(np.array([3.0, 4.0, -1.0]))
print(json.dumps({"before": before, "after_plan": loaded_scipy,
                  "moves": len(plan.table.moves), "value": value}))
"""


def test_lean_cache_load_is_installed() -> None:
    """Fails when a numba release changes the cache class this relies on (then the
    start-up saving is gone and :mod:`flowtwin._jit` needs a look)."""
    assert LEAN_CACHE_LOAD


def test_cached_kernels_load_without_scipy_and_compiling_still_works(tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-c", _PROBE, str(tmp_path / "example.gcode")],
                          capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert not out["before"]
    # numba's BLAS probe (numba.np.linalg) imports scipy.linalg during a registry refresh;
    # loading cached kernels must not refresh
    assert not [m for m in out["after_plan"] if m.startswith("scipy.linalg")], out
    assert out["moves"] > 100
    # norm([3, 4, -1]) + min + sum(cumsum) = sqrt(26) - 1 + (3 + 7 + 6)
    assert abs(out["value"] - (26 ** 0.5 - 1.0 + 16.0)) < 1e-12
