"""Byte budgets of one connection: requests waiting for the worker and answers not yet handed to the socket; and
the server-wide budget of the memory that large pieces of work of all sessions (animation exports) may take at once.

The reader stops reading frames while either budget is exhausted; the WebSocket server then stops reading the
socket (it buffers at most one frame), so a client that floods the server or never reads its answers is held
back by TCP instead of growing the server's memory.
"""

from __future__ import annotations

import asyncio
import threading
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Generic, TypeVar

__all__ = ["TEXT_MEMORY_FACTOR", "ByteBudget", "MemoryBudget", "RequestQueue", "request_cost"]

T = TypeVar("T")

TEXT_MEMORY_FACTOR = 5
"""A decoded JSON request takes about this many times its text in memory (lists of Python ints and floats)."""


def request_cost(size: int, text: bool) -> int:
    """Estimated memory, in bytes, of a decoded request whose frame had ``size`` bytes."""
    return size * TEXT_MEMORY_FACTOR if text else size


class ByteBudget:
    """Bytes queued for input and bytes being sent, against two limits; :meth:`wait_for_room` blocks past them.

    Parameters
    ----------
    max_queued : int
        Most (estimated) bytes of requests waiting for the worker before the reader stops reading. One request
        is always admitted into an empty queue, whatever its size (the frame limit bounds it).
    max_unsent : int
        Most bytes of answers produced but not yet handed to the socket before the reader stops reading.
    """

    def __init__(self, max_queued: int, max_unsent: int) -> None:
        self.max_queued = max_queued
        self.max_unsent = max_unsent
        self.queued = 0
        self.unsent = 0
        self.peak_queued = 0
        self.peak_unsent = 0
        self._changed = asyncio.Event()

    def has_room(self) -> bool:
        """Whether the reader may read another frame."""
        return self.queued < self.max_queued and self.unsent < self.max_unsent

    async def wait_for_room(self) -> None:
        """Return once :meth:`has_room` holds."""
        while not self.has_room():
            self._changed.clear()
            await self._changed.wait()

    def add_queued(self, n: int) -> None:
        self.queued += n
        self.peak_queued = max(self.peak_queued, self.queued)
        self._changed.set()

    def add_unsent(self, n: int) -> None:
        self.unsent += n
        self.peak_unsent = max(self.peak_unsent, self.unsent)
        self._changed.set()


class RequestQueue(Generic[T]):
    """Requests waiting for the worker, each with its cost charged to a :class:`ByteBudget`.

    Reads like a deque for the worker (``len``, truth value, ``[-1]``, :meth:`popleft`); the reader adds with
    :meth:`append` and :meth:`replace_last`.
    """

    def __init__(self, budget: ByteBudget) -> None:
        self.budget = budget
        self._items: deque[tuple[T, int]] = deque()

    def __len__(self) -> int:
        return len(self._items)

    def __bool__(self) -> bool:
        return bool(self._items)

    def __getitem__(self, i: int) -> T:
        return self._items[i][0]

    def append(self, item: T, cost: int) -> None:
        self._items.append((item, cost))
        self.budget.add_queued(cost)

    def replace_last(self, item: T, cost: int) -> None:
        _, old = self._items[-1]
        self._items[-1] = (item, cost)
        self.budget.add_queued(cost - old)

    def popleft(self) -> T:
        item, cost = self._items.popleft()
        self.budget.add_queued(-cost)
        return item

    def clear(self) -> None:
        while self._items:
            self.popleft()


class MemoryBudget:
    """Estimated bytes of the work in progress in all sessions of a server (animation exports), against one limit.

    Thread-safe: the work runs on worker threads. A piece of work larger than the whole limit is refused; one that
    fits waits until the others leave it room (first come, first served is not promised: whichever fits when room
    is made goes on).

    Parameters
    ----------
    limit : int
        Most bytes reserved at once.
    """

    POLL_SECONDS = 0.1
    """How often a waiting reservation asks whether it should give up."""

    def __init__(self, limit: int) -> None:
        if limit < 1:
            raise ValueError(f"the memory limit must be positive, got {limit}")
        self.limit = limit
        self.used = 0
        self.peak = 0
        self.waiting = 0
        self._room = threading.Condition()

    @contextmanager
    def reserve(self, nbytes: int, interrupted: Callable[[], bool] = lambda: False) -> Iterator[bool]:
        """Hold ``nbytes`` of the budget for the ``with`` block, once they fit; yields whether they were reserved
        (False: ``interrupted()`` turned true while waiting, and the block should give up).

        Raises
        ------
        ValueError
            ``nbytes`` is more than the whole limit: it would never fit.
        """
        if nbytes > self.limit:
            raise ValueError(f"{nbytes} bytes are more than the limit of {self.limit}")
        reserved = False
        with self._room:
            self.waiting += 1
            try:
                while self.used + nbytes > self.limit and not interrupted():
                    self._room.wait(self.POLL_SECONDS)
                if self.used + nbytes <= self.limit:
                    self.used += nbytes
                    self.peak = max(self.peak, self.used)
                    reserved = True
            finally:
                self.waiting -= 1
        if not reserved:
            yield False
            return
        try:
            yield True
        finally:
            with self._room:
                self.used -= nbytes
                self._room.notify_all()
