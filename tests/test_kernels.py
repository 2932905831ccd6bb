"""Compiled kernels: one warm-up covers every solve, and their cache always has somewhere to go."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from arap.cli.bench import bench_constraints
from arap.meshes.shapes import builtin_mesh
from arap.solve.solver import ArapSolver
from arap.warmup import _counts, warm_up_kernels


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
