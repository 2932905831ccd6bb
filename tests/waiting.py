"""Waiting for a condition instead of sleeping for a fixed time: a test goes on as soon as what it waits for has
happened, and fails with a message naming it when it does not happen in time."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, TypeVar

T = TypeVar("T")

POLL_SECONDS = 0.01
"""Pause between two looks at the condition."""


def poll_until(predicate: Callable[[], T], timeout: float, interval: float = POLL_SECONDS,
               pause: Callable[[float], Any] = time.sleep) -> T:
    """Call ``predicate`` until it returns a true value or ``timeout`` seconds have passed; returns its last value
    (false on a timeout). ``pause(seconds)`` waits between two calls."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value or time.monotonic() >= deadline:
            return value
        pause(min(interval, max(0.0, deadline - time.monotonic())))


def wait_until(predicate: Callable[[], T], timeout: float = 10.0, what: str = "the condition",
               interval: float = POLL_SECONDS, pause: Callable[[float], Any] = time.sleep) -> T:
    """Wait until ``predicate()`` returns a true value and return it; fail naming ``what`` after ``timeout`` seconds.

    ``predicate`` may itself raise (an ``assert`` on a child process still running, say) to fail at once.
    """
    value = poll_until(predicate, timeout, interval, pause)
    if not value:
        raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")
    return value


def page_wait_until(page: Any, predicate: Callable[[], T], timeout: float = 30.0, what: str = "the condition") -> T:
    """:func:`wait_until` for a condition on the Python side of a Playwright test (a message a route relayed, a
    dialog handled): between two looks the page's events are dispatched (``page.wait_for_timeout``), which a
    ``time.sleep`` would hold back. Conditions on the page itself use ``page.wait_for_function``."""
    return wait_until(predicate, timeout, what, interval=0.02,
                      pause=lambda seconds: page.wait_for_timeout(max(1.0, 1000 * seconds)))
