"""How many threads a compiled kernel runs on, and the lock that serialises the parallel launches.

numba's threading layer must not be entered from two Python threads at once (the studio solves several sessions on
worker threads), so every parallel launch holds :data:`kernel_lock`. Serial kernels hold nothing: they release the
GIL and run beside each other and beside a parallel one.

A parallel launch pays a fork/join whose cost does not shrink with the problem: a few microseconds on idle cores, but
up to a scheduler time slice (milliseconds) when the other cores are busy, because the launch waits for every worker.
Hence :class:`ThreadPolicy`:

* below :data:`PARALLEL_MIN_WORK` edge terms a kernel always runs serially (measured on a 2-core machine: below it
  the serial kernel is faster even on idle cores);
* above it, one thread per :data:`WORK_PER_THREAD` terms, at most numba's thread count;
* and the parallel launch must keep paying off: the policy times both choices for each kernel and size class (a
  serial run now and then, as a probe) and runs serially while parallel runs are measured slower, e.g. under load.

The kernels are deterministic: the thread count changes the schedule, never the arithmetic, so every choice gives
bitwise the same result.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import TypeVar

import numba

kernel_lock = threading.Lock()

PARALLEL_MIN_WORK = 60_000
"""Edge terms below which kernels run on one thread (about 10k vertices with spoke cells)."""
WORK_PER_THREAD = 30_000
"""Edge terms per additional thread above :data:`PARALLEL_MIN_WORK`."""
PROBE_EVERY = 16
"""Every this many calls of a kernel/size class, the choice not currently preferred is timed again."""

T = TypeVar("T")


class ThreadPolicy:
    """Chooses serial or parallel execution per call from the work size and the measured times of both.

    Times per unit of work are kept per kernel name and size class (powers of two of the work) as exponential moving
    averages; the state is advisory, so races between Python threads only blur the averages.

    Parameters
    ----------
    min_work : int
        Work below which kernels always run serially.
    work_per_thread : int
        Work per thread above ``min_work``.
    probe_every : int
        Calls between probes of the choice not currently preferred.
    """

    def __init__(self, min_work: int = PARALLEL_MIN_WORK, work_per_thread: int = WORK_PER_THREAD,
                 probe_every: int = PROBE_EVERY) -> None:
        self.min_work = min_work
        self.work_per_thread = work_per_thread
        self.probe_every = probe_every
        self._stats: dict[tuple[str, int], list[float]] = {}

    def threads(self, work: int) -> int:
        """Threads the size rule allows for ``work`` edge terms (1 below ``min_work``)."""
        if work < self.min_work:
            return 1
        return max(1, min(numba.config.NUMBA_NUM_THREADS, work // self.work_per_thread))

    def run(self, name: str, work: int, serial: Callable[[], T], parallel: Callable[[], T]) -> T:
        """Run ``serial()`` or ``parallel()`` (under :data:`kernel_lock`, with the chosen thread count).

        Parameters
        ----------
        name : str
            Kernel name; times are kept per name and size class.
        work : int
            Edge terms the call processes.
        serial, parallel : callable
            The same computation compiled without and with threads.
        """
        threads = self.threads(work)
        if threads == 1:
            return serial()
        key = (name, int(math.log2(work)))
        # [serial seconds per unit of work, parallel seconds per unit of work, calls]
        stats = self._stats.setdefault(key, [math.nan, math.nan, 0.0])
        stats[2] += 1
        if math.isnan(stats[1]):
            use_parallel = True
        elif math.isnan(stats[0]):
            use_parallel = False
        else:
            use_parallel = stats[1] < stats[0]
            if stats[2] % self.probe_every == 0:
                use_parallel = not use_parallel
        t = time.perf_counter()
        if use_parallel:
            with kernel_lock:
                numba.set_num_threads(threads)
                result = parallel()
        else:
            result = serial()
        elapsed = (time.perf_counter() - t) / max(work, 1)
        slot = 1 if use_parallel else 0
        stats[slot] = elapsed if math.isnan(stats[slot]) else 0.7 * stats[slot] + 0.3 * elapsed
        return result

    def reset(self) -> None:
        """Forget the measured times."""
        self._stats.clear()


policy = ThreadPolicy()
"""The policy every kernel of the package consults."""
