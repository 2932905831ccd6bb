"""Batches of deformations: a plain loop against ``arap batch`` on each backend, same jobs, same machine, one run.

The jobs are a family of constraint sets on one mesh (default: the armadillo): ``--sets`` handle regions (the top
``--share`` of the vertices along a direction, the bottom along the opposite one held), each posed ``--jobs / --sets``
times (a bend of growing angle). Runs, one after another in this order:

- ``loop``: a plain Python loop as a user would write it, building a solver (one factorisation) for every job;
- ``serial``: :func:`arap.batch` in this process (one factorisation per constraint set), its kernels on all cores;
- ``serial1``: the same in a child process limited to one thread (kernels and BLAS): the one-core baseline;
- ``process``, ``ray``, ``dask``: :func:`arap.batch` on ``--workers`` workers (local pool or local cluster).

Printed per run: wall time, jobs per second, parallel efficiency against ``serial1`` (``one-core time / (workers ×
time)``), the speed-up over ``serial`` (whose kernels already use the cores part of the time), factorisations, and
the peak resident memory of the run's processes (this process and its children; Ray's and Dask's own services
included). ``--json OUT`` writes the figures.

Run: ``python benchmarks/bench_batch.py [--mesh PATH] [--jobs 200] [--sets 4] [--workers 2]
[--backends loop serial serial1 process ray dask] [--quick] [--json OUT]`` (``--quick``: 4 jobs of 2 sets on a
built-in sphere of 500 vertices, backends loop, serial and process unless ``--backends`` names others: a check that
it runs, not a measurement). Ray and Dask are left out when they are not installed.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import psutil

import arap
from arap.batching.worker import worker_environment
from benchjson import add_json_option, figure, write_results

DEFAULT_MESH = Path(__file__).resolve().parents[2] / "shared" / "meshes" / "armadillo.obj"


def make_jobs(folder: Path, mesh: Path, count: int, sets: int, share: float) -> list[dict[str, Any]]:
    """Constraint files and manifest-line dicts of a family of ``sets`` constraint sets posed ``count`` times."""
    V, _ = arap.load_mesh(mesh)
    rng = np.random.default_rng(7)
    jobs = []
    for s in range(sets):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        h = V @ axis
        fixed = np.flatnonzero(h <= np.quantile(h, share))
        top = np.flatnonzero(h >= np.quantile(h, 1 - share))
        centre = V[top].mean(axis=0)
        turn = np.cross(axis, rng.normal(size=3))
        turn /= np.linalg.norm(turn)
        for k in range(count // sets):
            angle = np.radians(10 + 40 * k / max(count // sets - 1, 1))
            K = np.array([[0, -turn[2], turn[1]], [turn[2], 0, -turn[0]], [-turn[1], turn[0], 0]])
            R = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
            targets = (V[top] - centre) @ R.T + centre
            name = f"set{s}_pose{k}"
            (folder / f"{name}.json").write_text(json.dumps({"fixed": fixed.tolist(), "handles": top.tolist(),
                                                             "targets": targets.tolist()}))
            jobs.append({"mesh": str(mesh), "constraints": f"{name}.json", "output": f"out/{name}.ply"})
    return jobs


class PeakMemory:
    """Peak resident set size of this process and all its descendants, sampled every 50 ms."""

    def __init__(self) -> None:
        self.peak = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        me = psutil.Process()
        while not self._stop.is_set():
            total = 0
            for p in [me, *me.children(recursive=True)]:
                try:
                    total += p.memory_info().rss
                except psutil.Error:
                    pass
            self.peak = max(self.peak, total)
            self._stop.wait(0.05)

    def __enter__(self) -> PeakMemory:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()


def plain_loop(jobs: list[dict[str, Any]], folder: Path) -> int:
    """What a user writes without ``arap batch``: load, build, solve and save per job."""
    for job in jobs:
        V, F = arap.load_mesh(job["mesh"])
        c = arap.load_constraints(folder / job["constraints"], len(V), len(F))
        indices, targets = c.indices_and_targets(V)
        result = arap.ArapSolver(V, F, indices).solve(targets)
        arap.save_mesh(folder / job["output"], result.vertices, F)
    return len(jobs)


def one_thread(jobs: list[dict[str, Any]], folder: Path) -> tuple[int, int]:
    """The serial batch in a child process whose kernels and BLAS use one thread: the one-core baseline."""
    env = {**os.environ, **worker_environment(1)}
    code = ("import json, sys, arap; jobs = json.loads(sys.stdin.read()); "
            "r = arap.batch(jobs, backend='serial', base=sys.argv[1], progress=False); "
            "print(json.dumps([r.counts()['done'], r.factorisations]))")
    run = subprocess.run([sys.executable, "-c", code, str(folder)], input=json.dumps(jobs), capture_output=True,
                         text=True, env=env, check=True)
    done, factorisations = json.loads(run.stdout.strip().splitlines()[-1])
    return int(done), int(factorisations)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--mesh", type=Path, default=DEFAULT_MESH)
    p.add_argument("--jobs", type=int, default=200)
    p.add_argument("--sets", type=int, default=4)
    p.add_argument("--share", type=float, default=0.1)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--backends", nargs="+", default=None,
                   help="default: loop serial serial1 process ray dask (--quick: loop serial process)")
    p.add_argument("--quick", action="store_true", help="4 jobs of 2 sets on a built-in sphere of 500 vertices")
    add_json_option(p, "bench_batch")
    args = p.parse_args(argv)
    if args.backends is None:
        args.backends = (["loop", "serial", "process"] if args.quick
                         else ["loop", "serial", "serial1", "process", "ray", "dask"])
    from arap.warmup import warm_up_kernels

    missing = [b for b, module in (("ray", "ray"), ("dask", "dask.distributed")) if b in args.backends
               and importlib.util.find_spec(module.split(".")[0]) is None]
    if missing:
        print(f"left out (not installed): {', '.join(missing)}")
        args.backends = [b for b in args.backends if b not in missing]
    warm_up_kernels()
    figures: dict[str, Any] = {"mesh": args.mesh.name, "jobs": args.jobs, "sets": args.sets,
                               "workers": args.workers, "runs": {}}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if args.quick:
            args.jobs, args.sets, args.mesh = 4, 2, folder / "sphere.ply"
            arap.save_mesh(args.mesh, *arap.builtin_mesh("sphere:500"))
            figures.update(mesh="sphere:500", jobs=args.jobs, sets=args.sets)
        jobs = make_jobs(folder, args.mesh, args.jobs, args.sets, args.share)
        for backend in args.backends:
            out = folder / "out"
            if out.exists():
                for f in out.iterdir():
                    f.unlink()
            out.mkdir(exist_ok=True)
            with PeakMemory() as memory:
                t0 = time.perf_counter()
                if backend == "loop":
                    done, factorisations = plain_loop(jobs, folder), len(jobs)
                elif backend == "serial1":
                    done, factorisations = one_thread(jobs, folder)
                else:
                    report = arap.batch(jobs, backend=backend, workers=args.workers, base=folder, progress=False)
                    done, factorisations = report.counts()["done"], report.factorisations
                    assert not report.failed, report.failed[:3]
                seconds = time.perf_counter() - t0
            figures["runs"][backend] = {"seconds": seconds, "jobs_per_second": done / seconds,
                                        "factorisations": factorisations, "peak_rss_mb": memory.peak / 2**20}
            print(f"{backend:>8}: {seconds:7.1f} s  {done / seconds:6.2f} jobs/s  {factorisations:4d} factorisations"
                  f"  peak {memory.peak / 2**20:6.0f} MiB", flush=True)
    serial = figures["runs"].get("serial")
    one = figures["runs"].get("serial1")
    for name, run in figures["runs"].items():
        if name in ("loop", "serial", "serial1"):
            continue
        if one:
            run["parallel_efficiency"] = one["seconds"] / (args.workers * run["seconds"])
        if serial:
            run["speedup_over_serial"] = serial["seconds"] / run["seconds"]
        print(f"{name:>8}: parallel efficiency {run.get('parallel_efficiency', float('nan')):.2f} on "
              f"{args.workers} workers (against one core); {run.get('speedup_over_serial', float('nan')):.2f}x "
              "the in-process batch")
        loop = figures["runs"].get("loop")
        if loop:
            print(f"factorisation reuse: serial batch {loop['seconds'] / serial['seconds']:.2f}x the plain loop's "
                  "throughput")
    if args.json:
        runs = figures["runs"]
        rows = []
        for name, run in runs.items():
            if name == "loop":
                continue
            peer = "loop" if name == "serial" else "serial"
            rows.append(figure(f"jobs per second, {name} ({args.workers} workers)" if name not in
                               ("serial", "serial1") else f"jobs per second, {name}", run["jobs_per_second"],
                               "jobs/s", peer if peer in runs and name != "serial1" else None,
                               runs[peer]["jobs_per_second"] if peer in runs else None, better="higher"))
        write_results(args.json, "bench_batch", rows, figures)


if __name__ == "__main__":
    main()
