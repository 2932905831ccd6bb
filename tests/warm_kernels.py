"""Compile numba's kernels into the checkout's cache before tests run in several processes at once
(``python -m tests.warm_kernels``, as ``.ci/run`` does before its jobs start).

The tests solve with every energy and acceleration, and ask for energies and distortions: on an empty cache each
pytest-xdist worker of each job would compile those itself, at the same moment. Here they are compiled once, by
what ``arap warmup`` runs (:func:`arap.warmup.warm_up_kernels` with ``every_energy``, serial and threaded variants
alike). Compiling or not changes no result, so a kernel this misses is only compiled later, by the test that needs it.
"""

from __future__ import annotations

import time

from arap.warmup import warm_up_kernels


def main() -> None:
    t0 = time.perf_counter()
    warm_up_kernels(every_energy=True)
    print(f"kernels warm ({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
