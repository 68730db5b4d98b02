"""The written file's bytes made in a second thread while the main thread simulates its
draft.

The last stage of a run knows the draft it will hand on before it simulates it (the slip's
last round: its simulation only decides whether the round is kept). The bytes that draft is
written as (:func:`flowtwin.compensation.emit.encode_draft`: the text kernel, then zlib for a
gzip original; both let other threads run) are then made by a worker thread meanwhile, on
the second core. They are used only when the stage hands on that very draft and layout,
so the file is the same bytes as when made afterwards; a check that refuses the layout
raises where the serial write would (:meth:`WriteAhead.take`).
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

from flowtwin.compensation.draft import Draft
from flowtwin.compensation.emit import Layout, encode_draft

__all__ = ["WriteAhead"]


def _checked_bytes(draft: Draft, layout: Layout) -> bytes | None:
    """The layout checked for writing, then the bytes to store (``None`` where the writer
    stores something else: the original's own bytes, a binary G-code)."""
    draft.check(layout)
    if layout.changed_lines.size == 0 or draft.original.bgcode:
        return None
    return encode_draft(draft, layout)


class WriteAhead:
    """At most one draft's bytes, being made by a worker thread.

    Use as a context manager: leaving it lets a pending encoding go (its result unused).
    """

    def __init__(self) -> None:
        self._pool: ThreadPoolExecutor | None = None
        self._draft: Draft | None = None
        self._layout: Layout | None = None
        self._future: Future[bytes | None] | None = None

    def __enter__(self) -> WriteAhead:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def start(self, draft: Draft, layout: Layout) -> None:
        """Begin making the bytes of ``draft`` written with ``layout`` (one at a time: a
        previous one is let go)."""
        self.drop()
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="flowtwin-write")
        self._draft, self._layout = draft, layout
        self._future = self._pool.submit(_checked_bytes, draft, layout)

    def take(self, draft: Draft, layout: Layout | None) -> tuple[bool, bytes | None]:
        """``(True, bytes)`` when the bytes of exactly this draft and layout were begun
        (``bytes`` ``None``: the writer stores something else), after they are made;
        ``(False, None)`` otherwise.

        Raises
        ------
        GcodeError
            The layout cannot be written (the check :meth:`Draft.check` makes).
        """
        future = self._future
        if future is None or draft is not self._draft or layout is not self._layout:
            self.drop()
            return False, None
        self._future = self._draft = self._layout = None
        return True, future.result()

    def drop(self) -> None:
        """Let a pending encoding go."""
        if self._future is not None:
            self._future.cancel()
        self._future = self._draft = self._layout = None

    def close(self) -> None:
        """Let a pending encoding go and the worker thread end (without waiting for it)."""
        self.drop()
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
