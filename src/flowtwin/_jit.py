"""The compiled kernels' decorator: numba's ``njit``, with its on-disk cache loading cheaply.

Every kernel module imports ``njit`` from here (``cache=True`` on each kernel, warmed at
install by :mod:`flowtwin.warmup`). Loading a kernel from numba's cache calls
``target_context.refresh()`` first, which imports and installs every lowering registry of
numba (the array maths, linear algebra and its BLAS probe, which imports ``scipy.linalg``,
typed containers, random, ...): 0.25-0.45 s of start-up for a command such as ``flowtwin
plan``, spent before the first kernel runs although nothing is being compiled. The cached
machine code needs only numba's runtime (NRT, its allocator) to be initialised; compiling,
when a cache entry is missing or stale, refreshes the contexts itself
(``numba.core.compiler.CompilerBase``). So :func:`_install_lean_cache_load` replaces the
cache's load step with one that initialises the runtime and loads, as proposed upstream in
numba pull request 9806 ("Only refresh target_context if objmode is used"; flowtwin's
kernels use no object mode).

A cached kernel is stored as its machine code (an ELF object on Linux) plus the LLVM
bitcode of the same functions, which numba keeps so that code compiled later can link the
kernel in. numba parses that bitcode and walks its functions for every kernel it loads:
two thirds of the load (0.03-0.05 s of a ``flowtwin simulate`` on a small print, 0.1 s of
a ``compensate``), though nothing compiled later links most kernels.
:func:`_install_lazy_bitcode` makes the load register the kernel's symbols from the
object's own symbol table (:func:`elf_defined_symbols`; the same names, checked by the
tests against LLVM's view of the bitcode) and parse the bitcode only when a compilation
links the kernel. Objects that are not 64-bit little-endian ELF are loaded as numba does.

numba's runtime library (its reference counting and atomics, which every kernel calls) is
compiled by LLVM in every process, 0.015 s before the first kernel runs;
:func:`_install_nrt_cache` saves it once the way numba saves a kernel and loads it after.

All three are installed only when numba's classes have the form this was measured on
(checked by attribute, not by version); otherwise numba is left as it is, only slower to
start. The whole test suite runs with them, and ``tests/core/test_jit.py`` checks they are
in place, that a fresh process loads kernels from the cache without importing ``scipy`` or
parsing bitcode, that compiling code that calls a loaded kernel still works, and that the
runtime is compiled once, loaded afterwards and compiled again from a damaged file.
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any

import llvmlite.binding as ll
import numpy as np
from numba import njit, prange
from numba.core import caching, codegen

__all__ = ["LAZY_BITCODE", "LEAN_CACHE_LOAD", "NRT_CACHE", "NRT_CACHE_DIR", "elf_defined_symbols",
           "njit", "prange"]


def _install_lean_cache_load() -> bool:
    """Make numba's cache load initialise only the runtime; ``True`` when installed."""
    cache = getattr(caching, "Cache", None)
    if cache is None or getattr(cache.load_overload, "_flowtwin_lean", False):
        return cache is not None
    if not all(hasattr(cache, name) for name in
               ("_guard_against_spurious_io_errors", "_load_overload")):
        return False
    try:
        from numba.core.runtime import rtsys
    except ImportError:
        return False

    def load_overload(self: Any, sig: Any, target_context: Any) -> Any:
        rtsys.initialize(target_context)  # the allocator the cached code calls
        with self._guard_against_spurious_io_errors():
            return self._load_overload(sig, target_context)
        return None  # the guard swallowed an I/O error: numba compiles instead

    load_overload._flowtwin_lean = True  # type: ignore[attr-defined]
    cache.load_overload = load_overload
    return True


#: Whether cache loads skip numba's registry refresh in this process.
LEAN_CACHE_LOAD = _install_lean_cache_load()


#: An ELF64 symbol table entry (``Elf64_Sym``), little-endian.
_ELF64_SYM = np.dtype([("name", "<u4"), ("info", "u1"), ("other", "u1"), ("shndx", "<u2"),
                       ("value", "<u8"), ("size", "<u8")])
_SHT_SYMTAB = 2
_STT_SECTION, _STT_FILE = 3, 4


def elf_defined_symbols(obj: bytes) -> set[str] | None:
    """Names of the symbols an ELF64 little-endian object file defines; ``None`` for any
    other object format.

    Defined: a section index other than ``SHN_UNDEF``; section and file symbols, which
    name no function or variable, are left out. The layout is the System V ABI's ("ELF-64
    Object File Format", section header at ``e_shoff``, ``SHT_SYMTAB`` entries of 24 bytes
    whose names index the string table of the section's ``sh_link``).

    Raises
    ------
    struct.error, ValueError, IndexError
        A truncated or inconsistent object.
    """
    if obj[:4] != b"\x7fELF" or obj[4] != 2 or obj[5] != 1:
        return None
    (shoff,) = struct.unpack_from("<Q", obj, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", obj, 0x3A)
    names: set[str] = set()
    for k in range(shnum):
        header = shoff + k * shentsize
        (sh_type,) = struct.unpack_from("<I", obj, header + 4)
        if sh_type != _SHT_SYMTAB:
            continue
        offset, size = struct.unpack_from("<QQ", obj, header + 24)
        (link,) = struct.unpack_from("<I", obj, header + 40)
        str_offset, str_size = struct.unpack_from("<QQ", obj, shoff + link * shentsize + 24)
        strtab = obj[str_offset:str_offset + str_size]
        syms = np.frombuffer(obj, dtype=_ELF64_SYM, count=size // _ELF64_SYM.itemsize,
                             offset=offset)
        kind = syms["info"] & 0xF
        keep = (syms["shndx"] != 0) & (kind != _STT_SECTION) & (kind != _STT_FILE)
        for start in syms["name"][keep].tolist():
            end = strtab.index(b"\0", start)
            if end > start:
                names.add(strtab[start:end].decode())
    return names


def _install_lazy_bitcode() -> bool:
    """Make numba's cached-library load parse the shared bitcode only when it is linked;
    ``True`` when installed."""
    library = getattr(codegen, "CPUCodeLibrary", None)
    if library is None or getattr(library._unserialize, "_flowtwin_lazy", False):
        return library is not None
    if not all(hasattr(library, name) for name in
               ("_unserialize", "_get_module_for_linking", "enable_object_caching",
                "_set_compiled_object", "_finalize_final_module")):
        return False
    numba_unserialize = library._unserialize.__func__
    numba_linking_module = library._get_module_for_linking

    def unserialize(cls: Any, code_generator: Any, state: Any) -> Any:
        name, kind, data = state
        engine: Any = getattr(code_generator, "_engine", None)
        symbols = None
        if kind == "object" and isinstance(getattr(engine, "_defined_symbols", None), set):
            try:
                symbols = elf_defined_symbols(data[0])
            except (struct.error, ValueError, IndexError):
                symbols = None
        if not symbols:
            return numba_unserialize(cls, code_generator, state)
        object_code, shared_bitcode = data
        self = code_generator.create_library(name)
        self.enable_object_caching()
        self._set_compiled_object(object_code)
        self._flowtwin_bitcode = shared_bitcode  # parsed by _get_module_for_linking
        self._finalize_final_module()
        engine._defined_symbols |= symbols
        return self

    def get_module_for_linking(self: Any) -> Any:
        bitcode = self.__dict__.pop("_flowtwin_bitcode", None)
        if bitcode is not None:
            self._shared_module = ll.parse_bitcode(bitcode)
        return numba_linking_module(self)

    unserialize._flowtwin_lazy = True  # type: ignore[attr-defined]
    library._unserialize = classmethod(unserialize)
    library._get_module_for_linking = get_module_for_linking
    return True


#: Whether cached kernels' bitcode is parsed only when linked, in this process.
LAZY_BITCODE = _install_lazy_bitcode()


#: Where :func:`_install_nrt_cache` keeps numba's runtime library: numba's cache folder when
#: ``NUMBA_CACHE_DIR`` is set, else this package's ``__pycache__`` (read at each use).
NRT_CACHE_DIR: Path | None = None


def _nrt_cache_file(code_generator: Any) -> Path:
    """The runtime library's file for this numba, llvmlite, Python, CPU and options."""
    import hashlib
    import os
    import sys

    import llvmlite
    import numba
    from numba.core import config

    folder = NRT_CACHE_DIR or Path(os.environ.get("NUMBA_CACHE_DIR") or
                                   Path(__file__).resolve().parent / "__pycache__")
    key = repr((numba.__version__, llvmlite.__version__, sys.version, getattr(config, "OPT", None),
                code_generator.magic_tuple()))
    return Path(folder) / f"numba_nrt-{hashlib.sha256(key.encode()).hexdigest()[:20]}.nbc"


def _install_nrt_cache() -> bool:
    """Keep numba's runtime library (NRT) compiled on disk like a kernel; ``True`` when
    installed.

    numba compiles the runtime's LLVM functions (reference counts, atomics) in every process
    before the first kernel runs: 0.015 s of LLVM passes for a few small functions. Compiled
    once, its object code and bitcode are saved as numba saves a kernel
    (``serialize_using_object_code``) in :func:`_nrt_cache_file`, written atomically, and
    loaded from there afterwards. A file that cannot be read or loaded is compiled anew; a
    library holding process addresses (``has_dynamic_globals``) is never saved.
    """
    try:
        from numba.core.runtime import nrtdynmod
    except ImportError:
        return False
    if getattr(nrtdynmod.compile_nrt_functions, "_flowtwin_cached", False):
        return True
    if not all(hasattr(nrtdynmod, name) for name in
               ("compile_nrt_functions", "create_nrt_module")):
        return False

    def compile_nrt_functions(ctx: Any) -> Any:
        import pickle

        code_generator = ctx.codegen()
        path = _nrt_cache_file(code_generator)
        try:
            state = pickle.loads(path.read_bytes())
            if isinstance(state, tuple) and len(state) == 3 and state[1] == "object":
                return code_generator.unserialize_library(state)
        except (OSError, pickle.UnpicklingError, EOFError, ValueError, TypeError,
                AttributeError):
            pass
        ir_module, library = nrtdynmod.create_nrt_module(ctx)
        library.enable_object_caching()
        library.add_ir_module(ir_module)
        library.finalize()
        if not library.has_dynamic_globals:
            _save(path, pickle.dumps(library.serialize_using_object_code(), protocol=4))
        return library

    compile_nrt_functions._flowtwin_cached = True  # type: ignore[attr-defined]
    nrtdynmod.compile_nrt_functions = compile_nrt_functions
    return True


def _save(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` whole or not at all (a read-only folder: not at all)."""
    from flowtwin.atomic import atomic_open
    from flowtwin.errors import FlowtwinError

    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_open(path, "wb") as out:
            out.write(data)
    except (OSError, FlowtwinError):
        pass


#: Whether numba's runtime library is loaded from disk after its first compilation.
NRT_CACHE = _install_nrt_cache()
