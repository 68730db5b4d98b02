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

It is installed only when numba's cache class has the form this was measured on (checked by
attribute, not by version); otherwise numba is left as it is, only slower to start. The whole
test suite runs with it, and ``tests/core/test_jit.py`` checks it is in place and that a fresh
process loads kernels from the cache without importing ``scipy``.
"""

from __future__ import annotations

from typing import Any

from numba import njit, prange
from numba.core import caching

__all__ = ["LEAN_CACHE_LOAD", "njit", "prange"]


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
