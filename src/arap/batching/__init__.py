"""Batches of deformations on a process pool, a Ray cluster or a Dask cluster (``arap batch``, :func:`batch`).

Jobs (:mod:`arap.batching.jobs`) are grouped by solver: jobs on the same mesh with the same options and constraint set
(their targets aside) run one after another in one worker, which factorises the system once for all of them
(:mod:`arap.batching.worker`). Where there are fewer groups than workers, large groups are split so that every worker
has work, each part factorising once.

A job whose output exists is skipped (a second run finishes what the first left), unless ``skip_existing=False``.
Outputs are written atomically, and an interrupted batch (a Ctrl-C, or a SIGINT to its process alone) stops the job
under way in every worker, so it leaves finished files and no partial ones. A job that fails (a bad file, a
constraint set with a free part no constraint holds) is reported with its manifest line and reason while the others
finish.

Before any worker starts, the batch checks the jobs' files in its own process (:mod:`arap.batching.preflight`): a
missing or unreadable mesh or constraints file, a FIFO or a device named as one, an output that cannot be written
fail their jobs there, and missing output folders are made (on a cluster at ``address``, the workers check and make
them). While a job runs it holds a lock on its output (:mod:`arap.batching.locks`), so that two batches writing
into one folder never both run it; the workers of a pool end with the batch, even when it is killed.

Example
-------
>>> import json, pathlib, tempfile, numpy as np, arap
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> V, F = arap.builtin_mesh("bar")
>>> y = V[:, 1]
>>> fixed, top = np.flatnonzero(y < 0.2).tolist(), np.flatnonzero(y > 4.8)
>>> for k in range(2):
...     pose = {"fixed": fixed, "handles": top.tolist(), "targets": (V[top] + [0.2 * k, 0, 0]).tolist()}
...     _ = (folder / f"pose{k}.json").write_text(json.dumps(pose))
>>> jobs = [{"mesh": "bar", "constraints": f"pose{k}.json", "output": f"bar{k}.ply"} for k in range(2)]
>>> report = batch(jobs, backend="serial", base=folder, progress=False)
>>> report.counts()
{'done': 2, 'skipped': 0, 'failed': 0}
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from arap.batching.backends import BACKENDS, run_chunks
from arap.batching.jobs import Job, JobOutcome, chunks_for, job_from_json, read_manifest
from arap.batching.preflight import preflight
from arap.errors import ArapError, OptionError

__all__ = ["BACKENDS", "BatchReport", "Job", "JobOutcome", "batch", "read_manifest"]


@dataclass
class BatchReport:
    """Outcomes of a batch, in manifest order, with the backend, workers and wall time."""

    outcomes: list[JobOutcome]
    backend: str
    workers: int
    seconds: float
    started: bool = True
    """Whether any job reached a worker (False when every job was skipped or failed the checks before)."""

    def counts(self) -> dict[str, int]:
        """Jobs done, skipped and failed."""
        return {s: sum(o.status == s for o in self.outcomes) for s in ("done", "skipped", "failed")}

    @property
    def failed(self) -> list[JobOutcome]:
        return [o for o in self.outcomes if o.status == "failed"]

    @property
    def preflight_failed(self) -> list[JobOutcome]:
        """The failed jobs that the checks before the workers started refused (see :mod:`arap.batching.preflight`)."""
        return [o for o in self.failed if o.extra.get("preflight")]

    @property
    def factorisations(self) -> int:
        """Factorisations run (fewer than jobs done where jobs shared a constraint set)."""
        return sum(o.factorised for o in self.outcomes)

    def summary(self) -> str:
        """One line: counts, factorisations, wall time and throughput."""
        c = self.counts()
        rate = c["done"] / self.seconds if self.seconds > 0 else 0.0
        early = len(self.preflight_failed)
        checks = f" ({early} before any worker started)" if early else ""
        where = (f" on {self.workers} {self.backend} worker{'s' if self.workers != 1 else ''}" if self.started
                 else ", no worker started")
        return (f"{c['done']} done, {c['skipped']} skipped (output exists), {c['failed']} failed{checks}; "
                f"{self.factorisations} factorisations; {self.seconds:.1f} s{where} ({rate:.2f} jobs/s)")


def _jobs(jobs: Iterable[Job | Mapping[str, Any]], base: Path) -> tuple[list[Job], list[JobOutcome]]:
    out: list[Job] = []
    failed: list[JobOutcome] = []
    for k, job in enumerate(jobs, start=1):
        if isinstance(job, Job):
            out.append(job)
            continue
        try:
            out.append(job_from_json(job, k, base))
        except ArapError as exc:
            failed.append(JobOutcome(line=k, output="", status="failed", reason=str(exc)))
    return out, failed


def batch(jobs: Iterable[Job | Mapping[str, Any]] | str | os.PathLike[str], backend: str = "process",
          workers: int | None = None, address: str | None = None, *, skip_existing: bool = True,
          progress: bool = True, base: str | os.PathLike[str] | None = None) -> BatchReport:
    """Run deformation jobs.

    Parameters
    ----------
    jobs : iterable of Job or dict, or a manifest path
        Jobs as :class:`Job` or as manifest-line dicts (see :mod:`arap.batching.jobs`), or a JSON Lines manifest.
    backend : {"process", "ray", "dask", "serial"}
        ``process``: a pool of worker processes on this machine; ``ray`` / ``dask``: tasks on a Ray or Dask cluster
        (a local one started for the batch, or the one at ``address``); ``serial``: this process, one job after
        another.
    workers : int or None
        Worker processes (None: the machine's cores); for a cluster at ``address``, the tasks run at once.
    address : str or None
        A running cluster: Ray's ``ray://host:10001`` or ``auto``, Dask's scheduler ``tcp://host:8786``.
    skip_existing : bool
        Skip jobs whose output exists.
    progress : bool
        A progress bar (tqdm) on stderr.
    base : path-like or None
        Folder that relative paths in dict jobs are relative to (default: the current folder; a manifest's paths
        are relative to the manifest's folder).

    Returns
    -------
    BatchReport

    Examples
    --------
    Two poses of one built-in mesh, solved in this process (they share one factorisation):

    >>> import json, os, tempfile, arap
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     jobs = []
    ...     for k, height in enumerate([1.5, 2.0]):
    ...         pose = os.path.join(folder, f"pose{k}.json")
    ...         with open(pose, "w") as file:
    ...             json.dump({"fixed": [0], "handles": [5], "targets": [[0.0, height, 0.0]]}, file)
    ...         jobs.append({"mesh": "sphere:42", "constraints": pose, "output": os.path.join(folder, f"out{k}.obj")})
    ...     report = arap.batch(jobs, backend="serial")
    ...     print(report.counts(), report.factorisations, sorted(f for f in os.listdir(folder) if f.startswith("out")))
    {'done': 2, 'skipped': 0, 'failed': 0} 1 ['out0.obj', 'out1.obj']
    """
    if backend not in BACKENDS:
        raise OptionError(f"unknown backend {backend!r}; expected one of {BACKENDS}")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
        raise OptionError(f"workers must be a positive integer, got {workers!r}")
    if address is not None and backend not in ("ray", "dask"):
        raise OptionError(f"address is for the ray and dask backends, not {backend!r}")
    t0 = time.perf_counter()
    if isinstance(jobs, str | os.PathLike):
        todo, failed = read_manifest(jobs)
    else:
        todo, failed = _jobs(jobs, Path(base) if base is not None else Path.cwd())
    outcomes = list(failed)
    seen: dict[str, int] = {}
    runnable: list[Job] = []
    for job in todo:
        if job.output in seen:
            outcomes.append(JobOutcome(line=job.line, output=job.output, status="failed",
                                       reason=f"line {seen[job.output]} writes the same output"))
        elif skip_existing and os.path.exists(job.output):
            seen[job.output] = job.line
            outcomes.append(JobOutcome(line=job.line, output=job.output, status="skipped"))
        else:
            seen[job.output] = job.line
            runnable.append(job)
    if address is None:  # a cluster elsewhere may see files this machine does not: its workers check them
        runnable, refused = preflight(runnable)
        outcomes += refused
    count = workers or os.cpu_count() or 1
    if backend == "serial":
        count = 1
    chunks = chunks_for(runnable, count) if runnable else []
    outcomes += run_chunks(chunks, backend, count, address, progress, total=len(runnable), skip_existing=skip_existing)
    outcomes.sort(key=lambda o: o.line)
    return BatchReport(outcomes=outcomes, backend=backend, workers=count, seconds=time.perf_counter() - t0,
                       started=bool(chunks))
