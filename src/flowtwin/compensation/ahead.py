"""The written file's bytes made in a second thread while the main thread simulates its
draft.

The last stage of a run knows the draft it will hand on before it simulates it (the slip's
last round: its simulation only decides whether the round is kept). The text that draft is
written as (:func:`flowtwin.compensation.emit.draft_text`, a kernel that lets other
threads run), its read-back (:func:`flowtwin.compensation.readback.read_back`) and the
bytes stored (:func:`~flowtwin.compensation.emit.store_text`) are then made by a worker
thread meanwhile, on the second core. They are used only when the stage hands on that very
draft and layout, so the file is the same bytes as when made afterwards; a check that
refuses the layout raises where the serial write would (:meth:`Pending.text`), and a text
that cannot be read back raises where the serial read-back would (:meth:`Pending.checked`).
"""

from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

from flowtwin.compensation.draft import Draft
from flowtwin.compensation.emit import Layout, draft_text, store_text
from flowtwin.compensation.readback import ReadBack, read_back
from flowtwin.gcode.reader import ReadOptions

__all__ = ["Pending", "WriteAhead"]


class Pending:
    """The text and stored bytes of one draft and layout, being made by a worker.

    :meth:`text` and :meth:`stored` are ``None`` where the writer stores something else
    (the original's own bytes when nothing changed, a binary G-code).
    """

    def __init__(self, draft: Draft, layout: Layout, options: ReadOptions) -> None:
        self.draft = draft
        self.layout = layout
        self.options = options
        self._text: Future[bytes | None] = Future()
        self._checked: Future[ReadBack] = Future()
        self.stored_future: Future[bytes | None] | None = None

    def make(self) -> bytes | None:
        """The worker's job: check, text (handed over at once), stored bytes."""
        try:
            self.draft.check(self.layout)
            if self.layout.changed_lines.size == 0 or self.draft.original.bgcode:
                text = None
            else:
                text = draft_text(self.draft, self.layout)
        except BaseException as exc:
            self._text.set_exception(exc)
            self._checked.set_exception(exc)
            raise
        self._text.set_result(text)
        if text is None:  # nothing to read back: the caller writes the file itself
            return None
        try:
            self._checked.set_result(read_back(text, self.layout, self.options))
        except Exception as exc:  # raised where the caller asks for it
            self._checked.set_exception(exc)
        return store_text(self.draft, text)

    def text(self) -> bytes | None:
        """The G-code text, once made.

        Raises
        ------
        GcodeError
            The layout cannot be written (the check of :meth:`Draft.check`).
        """
        return self._text.result()

    def checked(self) -> ReadBack:
        """The text read back (once :meth:`text` gave a text).

        Raises
        ------
        GcodeError
            The text cannot be read back.
        """
        return self._checked.result()

    def stored(self) -> bytes | None:
        """The bytes to store, once made (after :meth:`text`)."""
        assert self.stored_future is not None
        return self.stored_future.result()


class WriteAhead:
    """At most one draft's bytes, being made by a worker thread.

    Use as a context manager: leaving it lets a pending encoding go (its result unused).
    """

    def __init__(self, options: ReadOptions) -> None:
        self._options = options  # the reader's options, for the read-back
        self._pool: ThreadPoolExecutor | None = None
        self._pending: Pending | None = None

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
        pending = Pending(draft, layout, self._options)
        pending.stored_future = self._pool.submit(pending.make)
        self._pending = pending

    def take(self, draft: Draft, layout: Layout | None) -> Pending | None:
        """The bytes begun for exactly this draft and layout, or ``None`` (any other
        begun are let go)."""
        pending = self._pending
        if pending is None or draft is not pending.draft or layout is not pending.layout:
            self.drop()
            return None
        self._pending = None
        return pending

    def drop(self) -> None:
        """Let a pending encoding go."""
        pending, self._pending = self._pending, None
        if pending is not None and pending.stored_future is not None:
            pending.stored_future.cancel()

    def close(self) -> None:
        """Let a pending encoding go and the worker thread end (without waiting for it)."""
        self.drop()
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None
