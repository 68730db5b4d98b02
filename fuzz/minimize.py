"""Shrink a failing document while it still fails the same way (delta debugging)."""

from __future__ import annotations

import time
from collections.abc import Callable


def ddmin(data: bytes, fails: Callable[[bytes], bool], *, seconds: float = 20.0) -> bytes:
    """A smaller ``data`` for which ``fails`` still holds (lines first, then bytes).

    Zeller's ddmin over lines, then over bytes when the result is one short line; stops at a
    fixed point or after ``seconds``.
    """
    deadline = time.monotonic() + seconds
    for split in (lambda d: d.split(b"\n"), lambda d: [bytes([c]) for c in d]):
        join = b"\n".join if split(b"a\nb") == [b"a", b"b"] else b"".join
        parts = split(data)
        n = 2
        while len(parts) >= 2 and time.monotonic() < deadline:
            size = max(1, len(parts) // n)
            chunks = [parts[i:i + size] for i in range(0, len(parts), size)]
            reduced = False
            for i in range(len(chunks)):
                rest = [x for j, c in enumerate(chunks) if j != i for x in c]
                if fails(join(rest)):
                    parts, n, reduced = rest, max(n - 1, 2), True
                    break
            if not reduced:
                if n >= len(parts):
                    break
                n = min(len(parts), 2 * n)
        data = join(parts)
        if len(data) > 200 or time.monotonic() >= deadline:
            break
    return data
