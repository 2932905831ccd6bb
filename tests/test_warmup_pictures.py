"""The warm-up of every solve covers the pictures' warp modes: after it, no picture solve compiles a kernel."""

from __future__ import annotations

import numpy as np

from arap.warmup import EVERY_SOLVE_KERNELS, _counts, _kernel_ready, warm_up_kernels
from tests.test_kernels import serial_then_threaded


def _picture_solves() -> None:
    """A picture other than the warm-up's, warped with three pins in each mode, as the library and the studio do."""
    from arap.puppet.warp import MODES, PuppetWarp
    from arap.server.solvers import plane_solver
    from arap.solve.solver import ArapSolver

    picture = np.zeros((30, 40, 4), dtype=np.uint8)
    picture[4:26, 5:35] = 255
    pins, targets = [[8.0, 15.0], [20.0, 15.0], [31.0, 15.0]], [[8.0, 15.0], [20.0, 12.0], [33.0, 20.0]]
    for mode in MODES:
        puppet = PuppetWarp(picture, pins, spacing=3.0, mode=mode)  # type: ignore[arg-type]
        puppet.deform(targets)
        V3 = np.column_stack([puppet.mesh.vertices, np.zeros(len(puppet.mesh.vertices))])
        inner = ArapSolver(V3, puppet.mesh.triangles, np.zeros(0, dtype=np.int64),
                           points=(puppet.faces, puppet.barycentric), energy="elements")
        studio = plane_solver(inner, mode)
        studio.solve(np.zeros((0, 3)), point_targets=np.column_stack([targets, np.zeros(3)]), max_iterations=5)


def test_a_warm_up_of_every_solve_leaves_no_picture_solve_to_compile() -> None:
    warm_up_kernels(every_energy=True)
    assert _kernel_ready("arap.puppet.blend._similarity_serial")
    assert _kernel_ready("arap.puppet.blend._similarity_parallel")
    assert all(_kernel_ready(k) for k in EVERY_SOLVE_KERNELS)
    before = _counts()
    serial_then_threaded(_picture_solves)  # the threaded variants of large pictures too
    # No kernel signature was compiled or even loaded from the cache after the warm-up (a Normal solve included).
    assert _counts() == before
