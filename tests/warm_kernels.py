"""Compile numba's kernels into the checkout's cache before tests run in several processes at once
(``python -m tests.warm_kernels``, as ``.ci/run`` does before its jobs start).

``arap warmup`` compiles what a default solve of a few iterations uses; the tests also solve with every energy and
acceleration, and ask for energies and distortions. On an empty cache each pytest-xdist worker of each job would
compile those itself, at the same moment; here they are compiled once, serial and threaded variants alike (the
solves run with the size rule of :func:`arap.warmup.warm_up_kernels` that picks the threaded variants).
Compiling or not changes no result, so a kernel this misses is only compiled later, by the test that needs it.
"""

from __future__ import annotations

import time

import numpy as np

import arap
from arap.kernels.parallel import policy
from arap.meshes.spheres import sphere
from arap.warmup import warm_up_kernels

ENERGIES = ("spokes", "spokes_and_rims", "smooth_rotations")
ACCELERATIONS = ("none", "anderson", "lbfgs")
ITERATIONS = 12
"""Enough for L-BFGS to take its own steps after the plain ones it starts with."""


def _solves(V: np.ndarray, F: np.ndarray) -> None:
    fixed = np.flatnonzero(V[:, 2] < 0.0)
    handle = np.array([int(np.argmax(V[:, 2]))])
    constrained = np.concatenate([fixed, handle])
    targets = np.concatenate([V[fixed], V[handle] + [0.3, 0.0, 0.0]])
    for energy in ENERGIES:
        solver = arap.ArapSolver(V, F, constrained, energy=energy)
        for acceleration in ACCELERATIONS:
            solver.reset()
            U = solver.solve(targets, max_iterations=ITERATIONS, tolerance=0, acceleration=acceleration).vertices
        arap.arap_energy(V, F, U, energy=energy)
        arap.cell_distortion(V, F, U, energy=energy)


def main() -> None:
    t0 = time.perf_counter()
    warm_up_kernels()
    V, F = sphere(frequency=2)
    _solves(V, F)
    saved = policy.min_work, policy.work_per_thread
    try:
        policy.min_work, policy.work_per_thread = 0, 1
        policy.reset()
        _solves(V, F)
    finally:
        policy.min_work, policy.work_per_thread = saved
        policy.reset()
    print(f"kernels warm ({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
