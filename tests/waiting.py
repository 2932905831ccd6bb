"""Waiting for a condition instead of sleeping for a fixed time: a test goes on as soon as what it waits for has
happened, and fails with a message naming it when it does not happen in time.

Deadlines are those of an idle machine times :func:`time_factor`: on a loaded machine (a CI runner running other jobs,
a laptop compiling) everything takes longer, and a test should then pass slowly rather than fail.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any, TypeVar

T = TypeVar("T")

POLL_SECONDS = 0.01
"""Pause between two looks at the condition."""
TIME_FACTOR_ENV = "ARAP_TEST_TIME_FACTOR"
"""Environment variable: how many times longer than on an idle machine a test may wait (a number, at least 1)."""
MAX_LOAD_FACTOR = 8.0
"""Most that the measured load stretches deadlines by (without :data:`TIME_FACTOR_ENV`)."""


def time_factor() -> float:
    """How many times longer than on an idle machine waits may take now: :data:`TIME_FACTOR_ENV` when set, else the
    load average of the last minute per CPU core (at least 1, at most :data:`MAX_LOAD_FACTOR`)."""
    value = os.environ.get(TIME_FACTOR_ENV, "").strip()
    if value:
        try:
            return max(1.0, float(value))
        except ValueError:
            raise ValueError(f"{TIME_FACTOR_ENV}={value!r} is not a number") from None
    try:
        load = os.getloadavg()[0] / (os.cpu_count() or 1)
    except OSError:  # no load average on this platform
        return 1.0
    return min(MAX_LOAD_FACTOR, max(1.0, load))


def scaled(seconds: float) -> float:
    """A deadline of ``seconds`` on an idle machine, stretched by :func:`time_factor`."""
    return seconds * time_factor()


def scaled_ms(seconds: float) -> float:
    """:func:`scaled` in milliseconds (Playwright's timeouts)."""
    return 1000.0 * scaled(seconds)


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
    """Wait until ``predicate()`` returns a true value and return it; fail naming ``what`` after ``timeout`` seconds
    (those of an idle machine, stretched by :func:`time_factor`).

    ``predicate`` may itself raise (an ``assert`` on a child process still running, say) to fail at once.
    """
    factor = time_factor()
    value = poll_until(predicate, timeout * factor, interval, pause)
    if not value:
        raise AssertionError(f"timed out after {timeout * factor:g} s ({timeout:g} s × load factor {factor:.3g}) "
                             f"waiting for {what}")
    return value


def page_wait_until(page: Any, predicate: Callable[[], T], timeout: float = 30.0, what: str = "the condition") -> T:
    """:func:`wait_until` for a condition on the Python side of a Playwright test (a message a route relayed, a
    dialog handled): between two looks the page's events are dispatched (``page.wait_for_timeout``), which a
    ``time.sleep`` would hold back. Conditions on the page itself use ``page.wait_for_function``."""
    return wait_until(predicate, timeout, what, interval=0.02,
                      pause=lambda seconds: page.wait_for_timeout(max(1.0, 1000 * seconds)))
