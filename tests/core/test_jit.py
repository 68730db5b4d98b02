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



_LINK_PROBE = r"""
import json, sys
import llvmlite.binding as ll
from numba.core import codegen
import flowtwin
from flowtwin._jit import elf_defined_symbols, njit
from flowtwin.gcode.generator import PrintSpec, write_print

parsed = []
parse = ll.parse_bitcode
def counting_parse(*args, **kwargs):
    parsed.append(1)
    return parse(*args, **kwargs)
ll.parse_bitcode = counting_parse

loaded = []
load = codegen.CPUCodeLibrary._unserialize.__func__
def capturing_load(cls, code_generator, state):
    loaded.append(state)
    return load(cls, code_generator, state)
codegen.CPUCodeLibrary._unserialize = classmethod(capturing_load)

write_print(sys.argv[1], PrintSpec())
plan = flowtwin.plan(sys.argv[1])             # kernels from numba's cache
from flowtwin.physics._melt_kernel import theta_scalar
from flowtwin.physics.melt import theta_scalar as theta_python
first = theta_scalar(0.3)                     # one more, with a scalar signature
parsed_loading = len(parsed)

# the object's symbol table against LLVM's own view of the kernel's bitcode
mismatched = []
for name, kind, (obj, bitcode) in (s for s in loaded if s[1] == "object"):
    module = parse(bitcode)
    llvm = {g.name for group in (module.functions, module.global_variables) for g in group
            if not g.is_declaration}
    if elf_defined_symbols(obj) != llvm:
        mismatched.append(name)

@njit(cache=False)
def caller(fo):                               # compiled now: links the loaded kernel in
    return 2.0 * theta_scalar(fo)

linked = caller(0.3)
print(json.dumps({"kernels": len(loaded), "parsed_loading": parsed_loading,
                  "mismatched": mismatched, "parsed_linking": len(parsed) - parsed_loading,
                  "linked": linked, "python": 2.0 * theta_python(0.3), "first": first,
                  "moves": len(plan.table.moves)}))
"""


def test_cached_kernels_load_without_their_bitcode_until_linked(tmp_path: Path) -> None:
    from flowtwin._jit import LAZY_BITCODE

    assert LAZY_BITCODE
    proc = subprocess.run([sys.executable, "-c", _LINK_PROBE, str(tmp_path / "example.gcode")],
                          capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["kernels"] >= 5 and out["moves"] > 100
    assert out["parsed_loading"] == 0  # no kernel's bitcode was read to load it
    assert out["mismatched"] == []     # the symbols registered are the kernel's own
    assert out["parsed_linking"] >= 1  # linking the kernel into new code reads it
    assert out["linked"] == out["python"] == 2.0 * out["first"]


def test_elf_symbols_refuse_other_formats() -> None:
    from flowtwin._jit import elf_defined_symbols

    assert elf_defined_symbols(b"\xcf\xfa\xed\xfe" + bytes(60)) is None  # Mach-O
    assert elf_defined_symbols(b"\x7fELF\x01\x01" + bytes(58)) is None    # 32-bit


_NRT_PROBE = r"""
import json, sys
from pathlib import Path
import flowtwin._jit as jit
jit.NRT_CACHE_DIR = Path(sys.argv[1])
from numba.core.runtime import nrtdynmod
made = []
create = nrtdynmod.create_nrt_module
def counting_create(ctx):
    made.append(1)
    return create(ctx)
nrtdynmod.create_nrt_module = counting_create

import numpy as np

@jit.njit(cache=False)
def work(n):                                  # allocates, counts references, frees
    a = np.arange(n) * 2.0
    pieces = [a, a + 1.0]
    return pieces[1].sum()

value = work(1000)
print(json.dumps({"compiled": len(made), "value": value,
                  "files": sorted(p.name for p in Path(sys.argv[1]).iterdir())}))
"""


def test_numbas_runtime_is_compiled_once_and_loaded_after(tmp_path: Path) -> None:
    from flowtwin._jit import NRT_CACHE

    assert NRT_CACHE

    def run() -> dict[str, object]:
        proc = subprocess.run([sys.executable, "-c", _NRT_PROBE, str(tmp_path)],
                              capture_output=True, text=True, timeout=600, check=False)
        assert proc.returncode == 0, proc.stderr
        out: dict[str, object] = json.loads(proc.stdout.strip().splitlines()[-1])
        assert out["value"] == 1_000_000.0  # sum(2k + 1, k < 1000)
        return out

    first = run()
    assert first["compiled"] == 1
    [name] = first["files"]  # type: ignore[misc]
    assert run()["compiled"] == 0  # loaded from the file
    (tmp_path / name).write_bytes(b"\x80\x04 not a pickle")  # a damaged file: compiled anew
    assert run()["compiled"] == 1
    assert run() == first | {"compiled": 0}
