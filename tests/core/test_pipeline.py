"""read_ahead: items in order, the producer's error raised at its place, early stop."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest

from flowtwin._pipeline import read_ahead


def test_items_arrive_in_order_from_another_thread() -> None:
    where: list[str] = []

    def produce() -> Iterator[int]:
        for i in range(100):
            where.append(threading.current_thread().name)
            yield i

    assert list(read_ahead(produce(), depth=3)) == list(range(100))
    assert set(where) == {"flowtwin-read-ahead"}


def test_producer_error_is_raised_after_the_items_before_it() -> None:
    def produce() -> Iterator[int]:
        yield 1
        yield 2
        raise ValueError("bad chunk")

    got: list[int] = []
    with pytest.raises(ValueError, match="bad chunk"):
        for item in read_ahead(produce()):
            got.append(item)
    assert got == [1, 2]


def test_consumer_stopping_early_stops_the_producer() -> None:
    made: list[int] = []

    def produce() -> Iterator[int]:
        for i in range(10_000):
            made.append(i)
            yield i

    for item in read_ahead(produce(), depth=2):
        if item == 5:
            break
    assert len(made) < 20  # it stopped a few items ahead, not at the end
