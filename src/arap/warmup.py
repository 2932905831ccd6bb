"""The compiled (numba) kernels: warm them up before timing anything, where their machine code is cached, and
whether a background warm-up still compiles them.

numba compiles a kernel on its first call (seconds for the whole set) and, as every kernel is declared with
``cache=True``, stores the machine code for later processes: in ``__pycache__`` next to the modules when that folder
is writable, else in the user's cache folder (``~/.cache/numba``), or in ``NUMBA_CACHE_DIR`` when it is set. So only
the first run in a new environment (or after an update of arap or numba) pays for compilation.

>>> from arap.warmup import warm_up_kernels
>>> warm_up_kernels().compiled     # doctest: +SKIP
0
"""

from __future__ import annotations

import sys
import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["KERNELS_READY", "KernelWarmUp", "warm_up_kernels"]

KERNELS_READY = threading.Event()
"""Set unless a warm-up runs in the background (``arap studio`` serves the page while the kernels compile): the studio
server greets a new connection once it is set, so that the page says the solver is being prepared instead of
hanging on its first drag."""
KERNELS_READY.set()


@dataclass(frozen=True)
class KernelWarmUp:
    """What :func:`warm_up_kernels` did.

    Attributes
    ----------
    seconds : float
        Wall time of the warm-up (compiling, or loading from the cache, plus a tiny solve).
    compiled : int
        Kernel signatures compiled now (0 when everything came from the cache).
    loaded : int
        Kernel signatures loaded from the cache.
    cache_dir : str or None
        Folder of the cached machine code of the first kernel (None when caching is off).
    """

    seconds: float
    compiled: int
    loaded: int
    cache_dir: str | None

    def record(self) -> dict[str, object]:
        """What a JSON report says of the warm-up: whether it compiled, its seconds and the cache folder."""
        return {"compiled": self.compiled > 0, "seconds": self.seconds, "cache_dir": self.cache_dir}


def _dispatchers() -> list[Any]:
    """The numba dispatchers defined in arap's loaded modules."""
    from numba.core.dispatcher import Dispatcher

    found: dict[int, Any] = {}
    for name, module in list(sys.modules.items()):
        if module is None or not (name == "arap" or name.startswith("arap.")):
            continue
        for value in vars(module).values():
            if isinstance(value, Dispatcher):
                found[id(value)] = value
    return list(found.values())


def _counts() -> tuple[int, int]:
    hits = misses = 0
    for dispatcher in _dispatchers():
        stats = dispatcher.stats
        hits += sum(stats.cache_hits.values())
        misses += sum(stats.cache_misses.values())
    return hits, misses


def warm_up_kernels(quiet: bool = True) -> KernelWarmUp:
    """Compile (or load from the cache) every kernel a solve uses, with tiny solves on a 42-vertex sphere (serial,
    then with the threaded variants that large meshes use).

    The kernels take the same argument types for every mesh, energy and weighting, so after this no solve
    compiles anything and its timings are those of the iterations alone. The lower half of the sphere is fixed,
    so that some cells see only constrained vertices (their energy is computed once, with the same kernel).

    Parameters
    ----------
    quiet : bool
        False: say on stderr, when kernels were compiled, how long it took and where they are cached (the command
        line's note before timing anything).

    Returns
    -------
    KernelWarmUp
    """
    from arap.kernels.parallel import policy
    from arap.meshes.shapes import sphere
    from arap.solve.solver import ArapSolver

    t0 = time.perf_counter()
    hits0, misses0 = _counts()
    V, F = sphere(frequency=2)
    fixed = np.flatnonzero(V[:, 2] < 0.0)
    handle = np.array([int(np.argmax(V[:, 2]))])
    constrained = np.concatenate([fixed, handle])
    targets = np.concatenate([V[fixed], V[handle] + [0.1, 0.0, 0.0]])
    ArapSolver(V, F, constrained).solve(targets, max_iterations=2)
    # The paper's spokes energy assembles its cells from the edge weight matrix, which the default energy does not.
    ArapSolver(V, F, constrained, energy="spokes").solve(targets, max_iterations=2)
    # Large meshes run the threaded variants: make the size rule pick them for this tiny solve too.
    saved = policy.min_work, policy.work_per_thread
    try:
        policy.min_work, policy.work_per_thread = 0, 1
        policy.reset()
        ArapSolver(V, F, constrained).solve(targets, max_iterations=2)
    finally:
        policy.min_work, policy.work_per_thread = saved
        policy.reset()
    hits, misses = _counts()
    paths = [d.stats.cache_path for d in _dispatchers() if d.stats.cache_path]
    warm = KernelWarmUp(seconds=time.perf_counter() - t0, compiled=misses - misses0, loaded=hits - hits0,
                        cache_dir=paths[0] if paths else None)
    if warm.compiled and not quiet:
        where = f"cached in {warm.cache_dir}"
        sys.stderr.write(f"arap: compiling kernels (first run only)… {warm.seconds:.1f} s ({where})\n")
        sys.stderr.flush()
    return warm
