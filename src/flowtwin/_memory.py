"""Give the C heap's free memory back to the system between the stages of a long command.

glibc's ``malloc`` keeps the memory of freed arrays for reuse; above its (adaptive) mmap
threshold a freed array is returned, below it stays in the heap, and after a few large
frees the threshold has risen to 32 MB, so a command whose stages each build and drop
hundreds of MB of arrays grows its resident size by the largest stage's garbage on top of
the next stage's live set. ``malloc_trim(0)`` returns the heap's free pages; it costs a
pass over the free lists (milliseconds). Elsewhere than glibc it does nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util
from functools import lru_cache
from typing import Any

__all__ = ["release_free_memory"]


@lru_cache(maxsize=1)
def _trim() -> Any:
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        trim = libc.malloc_trim
    except (OSError, AttributeError):
        return None
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int
    return trim


def release_free_memory() -> bool:
    """Return the C heap's free memory to the system (glibc); ``True`` when some was."""
    trim = _trim()
    return bool(trim(0)) if trim is not None else False
