"""Checks of a batch's files in the batch's own process, before any worker starts: what would fail a job at once (a
missing or unreadable mesh or constraints file, a FIFO or a device named as one, an output that cannot be written)
fails it here with its reason, and output folders that do not exist yet are made.

Files are examined without being opened (:func:`arap.io.paths.check_regular_file`): a named pipe would block a
reader, ``/dev/zero`` would fill its memory. The workers read every file again, refusing the same things, so a file
replaced meanwhile fails its job only.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from arap.batching.jobs import Job, JobOutcome
from arap.errors import ArapError

__all__ = ["preflight"]


def _why(exc: BaseException) -> str:
    return str(exc.strerror or exc) if isinstance(exc, OSError) else str(exc)


def _readable(path: str, what: str) -> str | None:
    """Why the file ``path`` cannot be read, or None."""
    from arap.io.paths import check_regular_file

    try:
        check_regular_file(path)
        if not os.access(path, os.R_OK):
            raise PermissionError(13, "Permission denied", path)
    except OSError as exc:
        return f"cannot read {what} {path}: {_why(exc)}"
    return None


def _mesh_problem(mesh: str) -> str | None:
    from arap.io import format_of
    from arap.io.volume import is_volume_file

    if not os.path.isabs(mesh):  # a built-in mesh
        return None
    problem = _readable(mesh, "mesh")
    if problem is None and not is_volume_file(mesh):
        try:
            format_of(mesh)
        except ArapError as exc:
            return str(exc)
    return problem


def _folder_problem(folder: Path) -> str | None:
    """Make ``folder`` (and the folders above it) where it does not exist; why that failed, or None."""
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as exc:
        from arap.io.paths import folder_problem

        return f"cannot make the folder {folder}: {folder_problem(folder) or _why(exc)}"
    return None


def _output_problem(output: str, folder_done: Callable[[Path], str | None]) -> str | None:
    from arap.io import format_of
    from arap.io.paths import write_destination
    from arap.io.volume import is_volume_file

    try:
        if not is_volume_file(output):
            format_of(output)
    except ArapError as exc:
        return str(exc)
    problem = folder_done(Path(output).parent)
    if problem is not None:
        return problem
    try:
        destination = write_destination(output)
    except OSError as exc:
        return f"cannot write {output}: {_why(exc)}"
    if not os.access(destination.parent, os.W_OK):
        return f"cannot write {output}: the folder {destination.parent} is not writable"
    return None


def preflight(jobs: list[Job]) -> tuple[list[Job], list[JobOutcome]]:
    """The jobs that pass the checks, and a failed outcome for each other one (``extra["preflight"]`` is True).

    Each mesh, constraints file and output folder is checked once however many jobs name it. The output folders of
    the jobs whose inputs pass are made (like ``mkdir -p``).
    """
    memo: dict[tuple[str, str], str | None] = {}

    def once(kind: str, key: str, check: Callable[[], str | None]) -> str | None:
        if (kind, key) not in memo:
            memo[kind, key] = check()
        return memo[kind, key]

    def folder_done(folder: Path) -> str | None:
        return once("folder", str(folder), lambda: _folder_problem(folder))

    passed: list[Job] = []
    failed: list[JobOutcome] = []
    for job in jobs:
        problem = (once("mesh", job.mesh, lambda: _mesh_problem(job.mesh))  # noqa: B023 - called at once
                   or once("constraints", job.constraints,
                           lambda: _readable(job.constraints, "constraints file"))  # noqa: B023
                   or _output_problem(job.output, folder_done))
        if problem is None:
            passed.append(job)
        else:
            failed.append(JobOutcome(line=job.line, output=job.output, status="failed", reason=problem[:500],
                                     extra={"preflight": True}))
    return passed, failed
