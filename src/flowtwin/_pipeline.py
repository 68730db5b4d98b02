"""Run the producer of an iterator on a worker thread, a few items ahead of its consumer.

The streamed plan and simulation read and plan the next chunk of a file while the current
one is simulated: the compiled kernels release the GIL (``nogil=True``), so the two run on
two cores. Items arrive in order; an exception of the producer is raised in the consumer
at the item where it happened; a consumer that stops early stops the producer.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator
from typing import TypeVar

__all__ = ["read_ahead"]

T = TypeVar("T")

_END = object()


def read_ahead(items: Iterator[T], *, depth: int = 2) -> Iterator[T]:
    """Iterate ``items`` on a worker thread, at most ``depth`` items ahead of the caller.

    Parameters
    ----------
    items
        An iterator; it runs entirely on the worker thread.
    depth
        Items produced and not yet consumed (memory held ahead).

    Yields
    ------
    The items of ``items``, in order.
    """
    buffer: queue.Queue[object] = queue.Queue(maxsize=depth)
    stop = threading.Event()

    def put(item: object) -> bool:
        while not stop.is_set():
            try:
                buffer.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def produce() -> None:
        try:
            for item in items:
                if not put((item,)):
                    return
        except BaseException as exc:  # handed to the consumer, raised there
            put(exc)
            return
        put(_END)

    worker = threading.Thread(target=produce, name="flowtwin-read-ahead", daemon=True)
    worker.start()
    try:
        while True:
            got = buffer.get()
            if got is _END:
                return
            if isinstance(got, BaseException):
                raise got
            yield got[0]  # type: ignore[index]
    finally:
        stop.set()
        worker.join()
