"""Running a chunk of batch jobs in one process: the mesh loaded and the system factorised once per constraint set,
then each job solved and written as ``arap deform`` would (same start, tolerance and output vertex order).

Everything here runs in the worker (a process of a pool, a Ray task or a Dask task): it takes and returns plain
data, and catches every error of a job into that job's outcome so that the other jobs go on.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from arap.batching.jobs import Job, JobOutcome

__all__ = ["run_chunk", "worker_environment"]


def worker_environment(threads: int) -> dict[str, str]:
    """Environment for a worker process that may use ``threads`` threads (kernels and BLAS), so that workers side by
    side do not oversubscribe the cores."""
    value = str(max(1, int(threads)))
    return {"NUMBA_NUM_THREADS": value, "OMP_NUM_THREADS": value, "OPENBLAS_NUM_THREADS": value,
            "MKL_NUM_THREADS": value}


@contextmanager
def environment(values: dict[str, str]) -> Iterator[None]:
    """``os.environ`` with ``values`` set for the block (the processes started inside inherit them)."""
    saved = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _load(mesh: str) -> tuple[np.ndarray, np.ndarray, Any]:
    from arap.io import load_mesh_with_report
    from arap.meshes.repair import RepairResult
    from arap.meshes.shapes import builtin_mesh

    if os.path.isabs(mesh):
        return load_mesh_with_report(mesh)
    V, F = builtin_mesh(mesh)
    return V, F, RepairResult.identity(V, F)


def _structure(c: Any) -> tuple[bytes, ...]:
    """What the solver of a constraint set depends on (its targets aside)."""
    parts = [c.fixed, c.handles, np.array([]) if c.roi is None else c.roi,
             np.array([]) if c.stiffness is None else c.stiffness]
    if c.points is not None:
        parts += [c.points.faces, c.points.barycentric, c.points.weights]
    return tuple(np.ascontiguousarray(p).tobytes() + str(np.asarray(p).dtype).encode() for p in parts)


def run_chunk(jobs: list[Job]) -> list[JobOutcome]:
    """Solve and write ``jobs`` (one mesh and options; constraint sets usually equal) in order.

    Returns
    -------
    list of JobOutcome
        One per job: ``done`` with its iterations, or ``failed`` with the reason (the others still run).
    """
    from arap.constraints import load_constraints
    from arap.errors import ArapError
    from arap.io import format_of, save_mesh
    from arap.solve.solver import ArapSolver

    outcomes: list[JobOutcome] = []
    loaded: tuple[np.ndarray, np.ndarray, Any] | None = None
    load_error = ""
    solver: Any = None
    built_for: tuple[bytes, ...] | None = None
    for job in jobs:
        t0 = time.perf_counter()
        try:
            if loaded is None and not load_error:
                try:
                    loaded = _load(job.mesh)
                except (ArapError, OSError, ValueError, MemoryError) as exc:
                    load_error = f"{job.mesh}: {exc}"
            if loaded is None:
                raise ArapError(load_error)
            V, F, repair = loaded
            constraints = load_constraints(job.constraints, len(repair.vertex_map), len(F))
            if repair.renumbers:
                constraints = constraints.remapped(repair.vertex_map)
            indices, targets = constraints.indices_and_targets(V)
            structure = _structure(constraints)
            factorised = solver is None or structure != built_for
            if factorised:
                solver = None  # the previous factor goes before the next is built
                solver = ArapSolver(V, F, indices, energy=job.energy, weights=job.weights, roi=constraints.roi,  # type: ignore[arg-type]
                                    stiffness=constraints.stiffness, alpha=job.alpha, points=constraints.points)
                built_for = structure
            result = solver.solve(targets, initial="auto", max_iterations=job.max_iterations,
                                  tolerance=job.tolerance, point_targets=constraints.point_targets)
            if not np.isfinite(result.vertices).all():
                raise ArapError("the solve produced non-finite positions; nothing was written")
            U, F_out = result.vertices, F
            if repair.renumbers and not (os.path.isabs(job.mesh) and format_of(job.mesh) == "stl"):
                back = repair.in_input_order(result.vertices)
                if back is not None:
                    U, F_out = back
            save_mesh(job.output, U, F_out)
            outcomes.append(JobOutcome(line=job.line, output=job.output, status="done",
                                       iterations=result.iterations, converged=result.converged,
                                       seconds=time.perf_counter() - t0, factorised=factorised))
        except (ArapError, OSError, ValueError, MemoryError) as exc:
            reason = " ".join(str(exc).split()) or type(exc).__name__
            outcomes.append(JobOutcome(line=job.line, output=job.output, status="failed", reason=reason[:500],
                                       seconds=time.perf_counter() - t0))
    return outcomes
