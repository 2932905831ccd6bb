"""Compiled kernels: one warm-up covers every solve, and their cache always has somewhere to go."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from arap.cli import main
from arap.cli.bench import bench_constraints
from arap.kernels.parallel import policy
from arap.meshes.grids import box_tetrahedra, rectangle_triangles
from arap.meshes.shapes import builtin_mesh
from arap.method.energy import arap_energy, cell_distortion
from arap.options import ACCELERATIONS, ENERGY_TYPES
from arap.solve.solver import ArapSolver
from arap.warmup import (
    EVERY_SOLVE_KERNELS,
    FIRST_KERNELS,
    LATER_KERNELS,
    _counts,
    _kernel_ready,
    compile_progress,
    warm_up_kernels,
)


def test_warm_up_covers_every_solve() -> None:
    warm = warm_up_kernels()
    assert warm.seconds > 0 and warm.compiled >= 0 and warm.cache_dir
    before = _counts()
    V, F = builtin_mesh("cactus")
    fixed, handles, targets = bench_constraints(V)
    roi = np.flatnonzero(V[:, 1] > np.median(V[:, 1]) - 0.5)
    for energy in ("spokes", "spokes_and_rims"):
        for weights, region in (("cotangent", None), ("uniform", roi)):
            solver = ArapSolver(V, F, np.concatenate([fixed, handles]), energy=energy, weights=weights, roi=region)
            solver.solve(np.concatenate([V[fixed], targets]), max_iterations=2)
    # No kernel signature was compiled or even loaded from the cache after the warm-up.
    assert _counts() == before
    assert warm_up_kernels().compiled == 0



def serial_then_threaded(run: Callable[[], object]) -> None:
    """``run()`` as the kernels' thread policy has it, then again with every kernel above its threading threshold
    (the threaded variants of large meshes too), the policy put back after."""
    run()
    with policy.every_kernel_threaded():
        run()


def _every_solve() -> None:
    """Solve other meshes than the warm-up's with every energy each takes, every acceleration and weighting."""
    cactus = builtin_mesh("cactus")
    for V, F, energies in ((*cactus, ENERGY_TYPES),
                           (*rectangle_triangles(7, 3), ("spokes", "spokes_and_rims", "elements")),
                           (*box_tetrahedra(3, 2, 1), ("elements",))):
        fixed = np.flatnonzero(V[:, 1] < V[:, 1].min() + 0.2 * np.ptp(V[:, 1]))
        handle = np.array([int(np.argmax(V[:, 1]))])
        targets = np.concatenate([V[fixed], V[handle] - 0.2 * np.ptp(V[:, 1])])
        for energy in energies:
            for weights in ("cotangent", "uniform"):
                solver = ArapSolver(V, F, np.concatenate([fixed, handle]), energy=energy, weights=weights)
                for acceleration in ACCELERATIONS:
                    solver.reset()
                    U = solver.solve(targets, max_iterations=15, tolerance=0, acceleration=acceleration).vertices
            arap_energy(V, F, U, energy=energy)
            cell_distortion(V, F, U, energy=energy)


def test_arap_warmup_covers_every_energy_and_acceleration(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["warmup"]) == 0
    assert "arap:" in capsys.readouterr().out
    assert all(_kernel_ready(k) for k in EVERY_SOLVE_KERNELS), [k for k in EVERY_SOLVE_KERNELS if not _kernel_ready(k)]
    before = _counts()
    serial_then_threaded(_every_solve)
    # No kernel signature was compiled or even loaded from the cache after ``arap warmup``.
    assert _counts() == before
    # The progress of a later default warm-up counts the default kernels again.
    assert compile_progress().total == len(FIRST_KERNELS) + len(LATER_KERNELS)
    assert warm_up_kernels(every_energy=True).compiled == 0

@pytest.mark.parametrize("preset", [False, True])
def test_cache_falls_back_to_a_temporary_folder(tmp_path: Path, preset: bool) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    code = (
        "from pathlib import Path\n"
        "import numba\n"
        "from arap.kernels.cache import ensure_writable_cache\n"
        f"print(ensure_writable_cache((Path({str(blocker)!r}) / 'cache',)), numba.config.CACHE_DIR)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["TMPDIR"] = str(tmp_path)
    if preset:
        env["NUMBA_CACHE_DIR"] = str(tmp_path / "mine")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True,
                         env=env, cwd=tmp_path).stdout.split()
    if preset:
        assert out == ["None", str(tmp_path / "mine")]
    else:
        assert out[0] == out[1] and Path(out[0]).parent == tmp_path and "arap-numba-cache" in out[0]
