"""How many threads a compiled kernel runs on, and the lock that serialises the parallel launches.

numba's threading layer must not be entered from two Python threads at once (the studio solves several sessions on
worker threads), so every parallel launch holds :data:`kernel_lock`. Serial kernels hold nothing: they release the
GIL and run beside each other and beside a parallel one.

A parallel launch pays a fork/join whose cost does not shrink with the problem: a few microseconds on idle cores, but
up to a scheduler time slice (milliseconds) when the other cores are busy, because the launch waits for every worker.
Hence :class:`ThreadPolicy`:

* below :data:`PARALLEL_MIN_WORK` edge terms a kernel always runs serially (measured on a 2-core machine: below it
  threads save little even on idle cores, and a busy core makes them cost far more);
* above it, one thread per :data:`WORK_PER_THREAD` terms, at most numba's thread count;
* and the parallel launch must keep paying off: the policy times both choices for each kernel and size class and
  runs serially while parallel runs are measured slower, e.g. under load (the losing choice is timed again now and
  then, ever more rarely while it keeps losing).

The kernels are deterministic: the thread count changes the schedule, never the arithmetic, so every choice gives
bitwise the same result.
"""

from __future__ import annotations

import math
import statistics
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TypeVar

import numba

import arap.kernels.cache  # noqa: F401  (a writable cache folder before the kernel modules importing this define theirs)

kernel_lock = threading.Lock()

__all__ = ["ThreadPolicy", "kernel_lock", "policy"]

PARALLEL_MIN_WORK = 50_000
"""Edge terms below which kernels run on one thread (about 4k vertices with spoke cells, local step and right-hand
side together). On a 2-core machine, below about 20k terms one thread is faster even on idle cores; at 50k two
threads save a useful part of the time on idle cores, while a busy core can make a parallel launch many times slower
(``benchmarks/bench_armadillo.py`` times the kernels serially, on all threads and as the policy chooses)."""
WORK_PER_THREAD = 25_000
"""Edge terms per thread above :data:`PARALLEL_MIN_WORK`."""
PROBE_EVERY = 16
"""Calls between two timings of the choice not currently preferred; doubled after each probe that does not change
the preference, up to :data:`PROBE_MAX`, so that an expensive choice is retried ever more rarely."""
PROBE_MAX = 1024
SAMPLES = 7
"""Recent calls whose median times a choice."""

T = TypeVar("T")

MAX_THREADS: int = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]
"""Most threads numba's parallel kernels may use (``NUMBA_NUM_THREADS``, fixed when numba starts)."""


class _Times:
    """Recent seconds per unit of work of one kernel and size class, serial and parallel.

    The estimate of each choice is the median of its last :data:`SAMPLES` calls: a load spike that stalls one call
    (a time slice or more) must not flip the choice, a load that stalls most calls must.
    """

    __slots__ = ("countdown", "interval", "parallel", "serial")

    def __init__(self, interval: int) -> None:
        self.serial: deque[float] = deque(maxlen=SAMPLES)
        self.parallel: deque[float] = deque(maxlen=SAMPLES)
        self.countdown = interval
        self.interval = interval

    def prefers_parallel(self) -> bool:
        return statistics.median(self.parallel) < statistics.median(self.serial)


class ThreadPolicy:
    """Chooses serial or parallel execution per call from the work size and the measured times of both.

    Times per unit of work are kept per kernel name and size class (powers of two of the work), the median of the
    recent calls of each choice; the state is advisory, so races between Python threads only blur the figures.

    Parameters
    ----------
    min_work : int
        Work below which kernels always run serially.
    work_per_thread : int
        Work per thread above ``min_work``.
    probe_every : int
        Initial number of calls between probes of the choice not currently preferred.
    """

    def __init__(self, min_work: int = PARALLEL_MIN_WORK, work_per_thread: int = WORK_PER_THREAD,
                 probe_every: int = PROBE_EVERY) -> None:
        self.min_work = min_work
        self.work_per_thread = work_per_thread
        self.probe_every = probe_every
        self._times: dict[tuple[str, int], _Times] = {}

    def threads(self, work: int) -> int:
        """Threads the size rule allows for ``work`` edge terms (1 below ``min_work``)."""
        if work < self.min_work:
            return 1
        return max(1, min(MAX_THREADS, work // self.work_per_thread))

    def choose(self, name: str, work: int) -> int:
        """Threads for the next call of kernel ``name`` over ``work`` edge terms (1: serial)."""
        threads = self.threads(work)
        if threads == 1:
            return 1
        times = self._times.setdefault((name, int(math.log2(work))), _Times(self.probe_every))
        if not times.parallel:
            return threads
        if not times.serial:
            return 1
        preferred = times.prefers_parallel()
        times.countdown -= 1
        if times.countdown <= 0:
            preferred = not preferred
        return threads if preferred else 1

    def record(self, name: str, work: int, threads: int, seconds: float) -> None:
        """Account a call's wall time (see :meth:`choose`)."""
        times = self._times.get((name, int(math.log2(max(work, 1)))))
        if times is None:
            return
        samples = times.parallel if threads > 1 else times.serial
        if not (times.parallel and times.serial):
            samples.append(seconds / max(work, 1))
            return
        before = times.prefers_parallel()
        probe = times.countdown <= 0
        if probe:  # the losing choice's figures are stale: the probe replaces them
            samples.clear()
        samples.append(seconds / max(work, 1))
        if probe:
            changed = times.prefers_parallel() != before
            times.interval = self.probe_every if changed else min(2 * times.interval, PROBE_MAX)
            times.countdown = times.interval

    def run(self, name: str, work: int, serial: Callable[[], T], parallel: Callable[[], T]) -> T:
        """Run ``serial()`` or ``parallel()`` (the latter under :data:`kernel_lock` with the chosen thread count).

        Parameters
        ----------
        name : str
            Kernel name; times are kept per name and size class.
        work : int
            Edge terms the call processes.
        serial, parallel : callable
            The same computation compiled without and with threads.
        """
        threads = self.choose(name, work)
        if threads == 1 and work < self.min_work:
            return serial()
        t = time.perf_counter()
        if threads > 1:
            with kernel_lock:
                numba.set_num_threads(threads)
                result = parallel()
        else:
            result = serial()
        self.record(name, work, threads, time.perf_counter() - t)
        return result

    def reset(self) -> None:
        """Forget the measured times."""
        self._times.clear()

    @contextmanager
    def every_kernel_threaded(self) -> Iterator[None]:
        """Within: every kernel above its threading threshold, whatever its work (the threaded variants of large
        meshes run, and compile, on small ones); the rule and the measured times put back after."""
        saved = self.min_work, self.work_per_thread
        try:
            self.min_work, self.work_per_thread = 0, 1
            self.reset()
            yield
        finally:
            self.min_work, self.work_per_thread = saved
            self.reset()


policy = ThreadPolicy()
"""The policy every kernel of the package consults."""
