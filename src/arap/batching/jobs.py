"""Batch jobs: one deformation each (a mesh, a constraints file, an output), read from a JSON Lines manifest, and
grouped so that jobs sharing a mesh and a constraint set share one factorisation.

A manifest has one JSON object a line (blank lines are skipped)::

    {"mesh": "armadillo.obj", "constraints": "pose_001.json", "output": "out/pose_001.obj"}
    {"mesh": "armadillo.obj", "constraints": "pose_002.json", "output": "out/pose_002.obj", "energy": "spokes"}

``mesh``, ``constraints`` and ``output`` are paths, relative to the manifest's folder unless absolute; ``mesh`` may
also name a built-in mesh (``bar``, ``sphere:10000``, ...). The optional keys are the options of ``arap deform``:
``energy``, ``weights``, ``alpha``, ``tolerance`` and ``max_iterations``.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from arap.errors import ArapError
from arap.meshes.shapes import BUILTIN_MESHES
from arap.options import (
    DEFAULT_ALPHA,
    DEFAULT_ENERGY,
    DEFAULT_TOLERANCE,
    DEFAULT_WEIGHTS,
    check_alpha,
    check_energy_and_weights,
    check_solve_options,
)

__all__ = ["JOB_KEYS", "MAX_MANIFEST_LINE", "Job", "JobOutcome", "chunks_for", "job_from_json", "read_manifest"]

JOB_KEYS = ("mesh", "constraints", "output", "energy", "weights", "alpha", "tolerance", "max_iterations")
"""The keys of a manifest line."""
MAX_MANIFEST_LINE = 1 << 20
"""Longest manifest line, in characters (a line names files; it holds no mesh)."""

Status = Literal["done", "skipped", "failed"]


@dataclass(frozen=True)
class Job:
    """One deformation.

    Attributes
    ----------
    line : int
        Its line in the manifest (1-based), or its position in the list given to :func:`arap.batch`.
    mesh : str
        A mesh file (absolute path; a surface, or a volume file of tetrahedra or planar triangles) or a built-in mesh
        name.
    constraints : str
        A constraints file (absolute path).
    output : str
        Where the deformed mesh is written (absolute path; the format by its extension): a solid written to a
        surface format is its boundary surface, as ``arap deform`` writes it.
    energy : str or None
        None: the default ``arap deform`` takes for the mesh and the job's targets
        (:func:`arap.meshes.domain.default_energy`): ``elements`` for a solid and for a flat mesh that the targets keep
        in its plane, else the surface energy.
    weights : str
    alpha, tolerance : float
    max_iterations : int or None
    """

    line: int
    mesh: str
    constraints: str
    output: str
    energy: str | None = None
    weights: str = DEFAULT_WEIGHTS
    alpha: float = DEFAULT_ALPHA
    tolerance: float = DEFAULT_TOLERANCE
    max_iterations: int | None = None

    def solver_key(self) -> tuple[str, ...]:
        """What its solver depends on besides the constraint set: jobs with equal keys and constraint sets share one
        factorisation."""
        return (self.mesh, self.energy or "", self.weights, repr(self.alpha))


@dataclass
class JobOutcome:
    """What became of a job: ``done`` (written), ``skipped`` (its output existed) or ``failed`` (``reason``)."""

    line: int
    output: str
    status: Status
    reason: str = ""
    iterations: int = 0
    converged: bool = False
    seconds: float = 0.0
    factorised: bool = False
    extra: dict[str, Any] = field(default_factory=dict)


def _is_builtin(name: str) -> bool:
    return name in BUILTIN_MESHES or name == "sphere" or name.startswith("sphere:")


def job_from_json(data: object, line: int, base: Path) -> Job:
    """A job from one parsed manifest line; paths relative to ``base``.

    Raises
    ------
    ArapError
        Not an object, unknown keys, missing paths, option values that ``arap deform`` refuses.
    """
    if not isinstance(data, Mapping):
        raise ArapError(f"a manifest line must be a JSON object, got {type(data).__name__}")
    unknown = sorted(str(k)[:40] for k in set(data) - set(JOB_KEYS))
    if unknown:
        raise ArapError(f"unknown keys {unknown}; expected some of {list(JOB_KEYS)}")
    paths = {}
    for key in ("mesh", "constraints", "output"):
        value = data.get(key)
        if not isinstance(value, str) or not value:
            raise ArapError(f'"{key}" must be a path (a non-empty string)')
        paths[key] = value if key == "mesh" and _is_builtin(value) else str((base / value).resolve())
    energy = data.get("energy")
    weights = data.get("weights", DEFAULT_WEIGHTS)
    if not isinstance(energy, str | None) or not isinstance(weights, str):
        raise ArapError('"energy" and "weights" must be names')
    check_energy_and_weights(DEFAULT_ENERGY if energy is None else energy, weights)
    alpha = check_alpha(data.get("alpha", DEFAULT_ALPHA))
    tolerance = data.get("tolerance", DEFAULT_TOLERANCE)
    cap = data.get("max_iterations")
    check_solve_options(cap, tolerance, "lbfgs", None)
    if not math.isfinite(float(tolerance)):
        raise ArapError(f"tolerance must be finite, got {tolerance!r}")
    return Job(line=line, mesh=paths["mesh"], constraints=paths["constraints"], output=paths["output"], energy=energy,
               weights=weights, alpha=float(alpha), tolerance=float(tolerance),
               max_iterations=None if cap is None else int(cap))


def read_manifest(path: str | os.PathLike[str]) -> tuple[list[Job], list[JobOutcome]]:
    """The jobs of a JSON Lines manifest, and a failed outcome for each line that is not a valid job.

    Raises
    ------
    ArapError
        The manifest cannot be read (a line that cannot be parsed fails that job only).
    """
    from arap.io.paths import read_regular_file

    path = Path(path)
    try:
        text = read_regular_file(path).decode("utf-8")
    except OSError as exc:
        raise ArapError(f"cannot read manifest {path}: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise ArapError(f"manifest {path} is not UTF-8 text") from None
    base = path.resolve().parent
    jobs: list[Job] = []
    failed: list[JobOutcome] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        if not raw.strip():
            continue
        try:
            if len(raw) > MAX_MANIFEST_LINE:
                raise ArapError(f"the line is {len(raw):,} characters long, more than {MAX_MANIFEST_LINE:,}")
            try:
                data = json.loads(raw)
            except (json.JSONDecodeError, RecursionError) as exc:
                raise ArapError(f"not valid JSON ({getattr(exc, 'msg', 'nested too deeply')})") from None
            jobs.append(job_from_json(data, number, base))
        except ArapError as exc:
            failed.append(JobOutcome(line=number, output="", status="failed", reason=str(exc)))
    return jobs, failed


def _constraint_set_key(path: str) -> str:
    """A digest of the constraints file without its targets (and its pins' angles and depths, but whether each holds
    an angle): files with equal digests share a solver. A file that
    cannot be read (or is not a regular file: a FIFO would block, a device fill the memory) gets a key of its own
    (the job then fails with the reason)."""
    from arap.io.paths import read_regular_file

    try:
        data = json.loads(read_regular_file(path))
    except (OSError, ValueError, RecursionError):
        return "unreadable:" + path
    if not isinstance(data, dict):
        return "invalid:" + path
    data = {k: v for k, v in data.items() if k not in ("targets", "meta")}
    if isinstance(data.get("points"), list):  # a pin's angle moves only its ring's targets, its depth nothing
        data["points"] = [{**{k: v for k, v in p.items() if k not in ("target", "angle", "depth")},
                           "angle": p.get("angle") is not None} if isinstance(p, dict) else p for p in data["points"]]
    return hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()


def chunks_for(jobs: Iterable[Job], workers: int) -> list[list[Job]]:
    """Jobs grouped by solver (mesh, options and constraint set, targets aside), in manifest order within a group.

    Groups larger than an even share of the jobs (``ceil(jobs / workers)``) are split in halves until none is, so
    that every worker has work: each part factorises once, which costs at most about ``workers`` factorisations more
    than one per constraint set.
    """
    groups: dict[tuple[str, ...], list[Job]] = {}
    for job in jobs:
        groups.setdefault((*job.solver_key(), _constraint_set_key(job.constraints)), []).append(job)
    chunks = sorted(groups.values(), key=len, reverse=True)
    share = max(1, -(-sum(map(len, chunks)) // max(workers, 1)))
    while chunks and len(chunks[0]) > share:
        largest = chunks.pop(0)
        half = (len(largest) + 1) // 2
        chunks += [largest[:half], largest[half:]]
        chunks.sort(key=len, reverse=True)
    return chunks
