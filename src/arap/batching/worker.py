"""Running a chunk of batch jobs in one process: the mesh loaded and the system factorised once per constraint set,
then each job solved and written as ``arap deform`` would (same start, tolerance and output vertex order).

Everything here runs in the worker (a process of a pool, a Ray task or a Dask task): it takes and returns plain
data, and catches every error of a job into that job's outcome so that the other jobs go on.
"""

from __future__ import annotations

import contextlib
import os
import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from arap.batching.jobs import Job, JobOutcome
from arap.batching.locks import exit_with_parent, output_lock

if TYPE_CHECKING:
    from arap.solve.solver import ArapSolver

__all__ = ["run_chunk", "start_worker", "worker_environment"]


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


def _load(mesh: str) -> tuple[np.ndarray, np.ndarray, Any, int]:
    """The mesh to solve: its vertices, its triangles (or a volume file's tetrahedra or triangles), what repair did,
    and a volume file's coordinates per vertex (0 for a surface)."""
    from arap.io import load_mesh_with_report
    from arap.io.volume import is_volume_file, volume_for_solving
    from arap.meshes.repair import RepairResult
    from arap.meshes.shapes import builtin_mesh

    if os.path.isabs(mesh) and is_volume_file(mesh):
        V, T, columns = volume_for_solving(mesh)
        return V, T, RepairResult.identity(V), columns
    if os.path.isabs(mesh):
        return (*load_mesh_with_report(mesh), 0)
    V, F = builtin_mesh(mesh)
    return V, F, RepairResult.identity(V, F), 0


def _structure(c: Any) -> tuple[bytes, ...]:
    """What the solver of a constraint set depends on (its targets aside)."""
    parts = [c.fixed, c.handles, np.array([]) if c.roi is None else c.roi,
             np.array([]) if c.stiffness is None else c.stiffness]
    if c.points is not None:
        parts += [c.points.faces, c.points.barycentric, c.points.weights]
        # the pins that hold an angle have hidden rings (their angles only move the rings' targets)
        parts.append(np.array([a is not None for a in c.pin_angles or []], dtype=bool))
    return tuple(np.ascontiguousarray(p).tobytes() + str(np.asarray(p).dtype).encode() for p in parts)


@dataclass
class _Chunk:
    """What the jobs of a chunk share: the mesh (or why it could not be loaded) and the last solver."""

    mesh: tuple[np.ndarray, np.ndarray, Any, int] | None = None
    load_error: str = ""
    solver: ArapSolver | None = None
    built_for: tuple[bytes, ...] | None = None


_stop: Any = None
"""In a pool's worker process, the pool's stop event (see :func:`start_worker`)."""
LOCK_POLL_SECONDS = 0.2
"""How often a pool's worker waiting for another batch's lock looks again (and at its stop event)."""


def _stop_if_asked(*iteration: object) -> None:
    """In a pool's worker, a KeyboardInterrupt once the batch is stopped (see :func:`start_worker`); also the solver's
    iteration callback."""
    if _stop is not None and _stop.is_set():
        raise KeyboardInterrupt


def _solve_and_write(job: Job, state: _Chunk) -> JobOutcome:
    """Solve one job and write its output, reusing the mesh and the solver of the jobs before."""
    from arap.constraints import load_constraints
    from arap.errors import ArapError
    from arap.io import format_of, save_mesh
    from arap.io.volume import is_volume_file, save_deformed_volume, save_volume_mesh
    from arap.meshes.domain import default_energy
    from arap.puppet.rings import held_points
    from arap.solve.solver import ArapSolver

    t0 = time.perf_counter()
    try:
        if state.mesh is None and not state.load_error:
            try:
                state.mesh = _load(job.mesh)
            except (ArapError, OSError, ValueError, MemoryError) as exc:
                state.load_error = f"{job.mesh}: {exc}"
        if state.mesh is None:
            raise ArapError(state.load_error)
        V, F, repair, columns = state.mesh
        constraints = load_constraints(job.constraints, len(repair.vertex_map), len(F))
        if repair.renumbers:
            constraints = constraints.remapped(repair.vertex_map)
        indices, targets = constraints.indices_and_targets(V)
        # A picture's pins that hold an angle bring their hidden rings (on a flat mesh; refused elsewhere).
        points, point_targets = held_points(constraints, V, F, "arap batch")
        energy = job.energy
        if energy is None:  # as arap deform picks it: elements for a solid, or a flat mesh its targets keep flat
            asked = targets if point_targets is None else np.concatenate([targets, point_targets])
            energy = default_energy(V, F, asked)
        structure = (*_structure(constraints), energy.encode())
        solver = state.solver if structure == state.built_for else None
        factorised = solver is None
        if solver is None:
            state.solver = None  # the previous factor goes before the next is built
            solver = ArapSolver(V, F, indices, energy=energy, weights=job.weights,  # type: ignore[arg-type]
                                roi=constraints.roi, stiffness=constraints.stiffness, alpha=job.alpha,
                                points=points)
            state.solver, state.built_for = solver, structure
        result = solver.solve(targets, initial="auto", max_iterations=job.max_iterations, tolerance=job.tolerance,
                              point_targets=point_targets, callback=None if _stop is None else _stop_if_asked)
        if not np.isfinite(result.vertices).all():
            raise ArapError("the solve produced non-finite positions; nothing was written")
        U, F_out = result.vertices, F
        if repair.renumbers and not (os.path.isabs(job.mesh) and format_of(job.mesh) == "stl"):
            back = repair.in_input_order(result.vertices)
            if back is not None:
                U, F_out = back
        if columns:  # a volume file: a volume file again, or its (boundary) surface
            save_deformed_volume(job.output, U, F_out, columns)
        elif is_volume_file(job.output):
            save_volume_mesh(job.output, U, F_out)
        else:
            save_mesh(job.output, U, F_out)
        return JobOutcome(line=job.line, output=job.output, status="done", iterations=result.iterations,
                          converged=result.converged, seconds=time.perf_counter() - t0, factorised=factorised)
    except (ArapError, OSError, ValueError, MemoryError) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        return JobOutcome(line=job.line, output=job.output, status="failed", reason=reason[:500],
                          seconds=time.perf_counter() - t0)


def _locked(job: Job, state: _Chunk, skip_existing: bool, wait: bool) -> JobOutcome | None:
    """Run ``job`` holding its output's lock (:mod:`arap.batching.locks`); None when another process holds it and
    ``wait`` is false. With ``skip_existing``, a job whose output appeared meanwhile (another batch wrote it) is
    skipped."""
    with contextlib.suppress(OSError):  # made before the pool started, unless on a cluster (else save_mesh says why)
        os.makedirs(os.path.dirname(job.output), exist_ok=True)
    with output_lock(job.output, wait=wait) as held:
        if not held:
            return None
        if skip_existing and os.path.exists(job.output):
            return JobOutcome(line=job.line, output=job.output, status="skipped")
        return _solve_and_write(job, state)


def run_chunk(jobs: list[Job], skip_existing: bool = True) -> list[JobOutcome]:
    """Solve and write ``jobs`` (one mesh and options; constraint sets usually equal) in order.

    Each job holds its output's lock while it runs (:mod:`arap.batching.locks`): a job that another batch is running
    waits until the others of the chunk are done, then until that batch lets it go; it is then skipped if its output
    exists (with ``skip_existing``), or run.

    Returns
    -------
    list of JobOutcome
        One per job, in the order of ``jobs``: ``done`` with its iterations, ``skipped`` when its output appeared while
        it waited, or ``failed`` with the reason (the others still run).
    """
    state = _Chunk()
    outcomes: dict[int, JobOutcome] = {}
    busy: list[int] = []
    for k, job in enumerate(jobs):
        _stop_if_asked()
        outcome = _locked(job, state, skip_existing, wait=False)
        if outcome is None:
            busy.append(k)
        else:
            outcomes[k] = outcome
    for k in busy:
        _stop_if_asked()
        # A pool's worker looks again now and then, so that a stop reaches it while it waits.
        while (done := _locked(jobs[k], state, skip_existing, wait=_stop is None)) is None:
            time.sleep(LOCK_POLL_SECONDS)
            _stop_if_asked()
        outcomes[k] = done
    return [outcomes[k] for k in range(len(jobs))]


def start_worker(parent: int, stop: Any = None) -> None:
    """Initializer of a pool's worker process: it ends with the process ``parent`` that started the pool, however that
    one ended (see :func:`arap.batching.locks.exit_with_parent`), so that no worker of a killed batch keeps writing.

    It ignores SIGINT (a Ctrl-C at the terminal reaches every process of the batch): a KeyboardInterrupt could come
    anywhere, between two chunks (the worker would end and break the pool, which then kills the other workers in the
    middle of their jobs) or inside a kernel being loaded (where llvmlite's callbacks swallow it or crash). The batch
    sets ``stop`` instead (a :class:`multiprocessing.Event`), and the worker stops at the next safe point: before a
    job, at the end of a solver iteration, or while waiting for another batch's lock; the job under way then ends with
    a KeyboardInterrupt, its lock let go and nothing written.
    """
    global _stop
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    exit_with_parent(parent)
    _stop = stop
