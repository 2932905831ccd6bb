"""How ARAP scales with mesh size: geodesic spheres from about 10k to about 1M vertices.

Scenario: the bottom cap (lowest 5% along y) is fixed; the top cap (highest 5%) is rotated 30° about the x axis
through its centroid and lifted by 0.3 radius. Each size runs in a fresh subprocess so that its peak memory
(resident set size, which also counts the C and C++ allocations of the sparse factorisation) is its own.

Run: ``python benchmarks/bench_scaling.py [--max-vertices 1000000] [--iterations 5] [--repeats 3] [--quick]
[--json OUT]`` (``--quick``: one sphere of 2,000 vertices, 2 iterations, one run: a check that it runs, not a
measurement).

``--sizes 400000 1000000 --backends sksparse cholespy`` measures only those sizes, each with each sparse Cholesky
backend (old and new configuration side by side in one run), and prints where precompute goes: cells (weights and
edge terms), right-hand-side gather, the rest of the set-up, fill-reducing ordering, symbolic analysis, numeric
factorisation and conversion to the solving form.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time
from typing import Any

import numpy as np

from benchjson import add_json_option, figure, write_results

SIZES = (10_000, 40_000, 160_000, 400_000, 650_000, 1_000_000)


def current_rss_mb() -> float:
    """Resident set size of this process now, in MiB (Linux /proc)."""
    with open("/proc/self/statm") as fh:
        pages = int(fh.read().split()[1])
    return pages * resource.getpagesize() / 2**20


def peak_rss_mb() -> float:
    """Peak resident set size of this process so far, in MiB (ru_maxrss is in KiB on Linux)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def caps_scenario(V: np.ndarray, share: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """Constrained vertex indices and their targets: bottom cap at rest, top cap rotated and lifted."""
    y = V[:, 1]
    fixed = np.flatnonzero(y <= np.quantile(y, share))
    handles = np.flatnonzero(y >= np.quantile(y, 1.0 - share))
    a = np.radians(30.0)
    R = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]])
    centroid = V[handles].mean(axis=0)
    targets = (V[handles] - centroid) @ R.T + centroid + np.array([0.0, 0.3, 0.0])
    return np.concatenate([fixed, handles]), np.concatenate([V[fixed], targets])


class _Timed:
    """Wraps a function of ``arap.solve.solver`` to add its run time to ``sink[key]``."""

    def __init__(self, fn: Any, key: str, sink: dict[str, float]) -> None:
        self.fn, self.key, self.sink = fn, key, sink

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        t = time.perf_counter()
        try:
            return self.fn(*args, **kwargs)
        finally:
            self.sink[self.key] = self.sink.get(self.key, 0.0) + time.perf_counter() - t


def symbolic_seconds(solver: Any) -> float:
    """Symbolic analysis alone: CHOLMOD analysing the reduced matrix already in its chosen fill-reducing order."""
    from sksparse.cholmod import analyze

    P = solver.factor.permutation
    A = solver.reduced_matrix()
    C = A[P][:, P].tocsc()
    t = time.perf_counter()
    analyze(C, mode="supernodal", ordering_method="natural")
    return time.perf_counter() - t


def precompute_split(solver: Any, parts: dict[str, float], precompute: float) -> dict[str, float]:
    """Where precompute went, in seconds (see :data:`SPLIT_KEYS`); ``overlapped`` is not part of the total."""
    factor_parts = dict(getattr(solver.factor, "timings", {}))
    split = {"cells": parts.get("cells", 0.0), "gather": parts.get("gather", 0.0)}
    split["other"] = precompute - split["cells"] - split["gather"] - parts.get("factorize", 0.0)
    factorize = parts.get("factorize", 0.0)
    if "ordering" in factor_parts:  # a given ordering: computed on a thread beside the set-up
        split["ordering"] = factor_parts["ordering"]
        split["symbolic"] = factor_parts["analyse"]
        split["overlapped"] = factor_parts.get("ordering_thread", 0.0)
    elif "analyse" in factor_parts:  # CHOLMOD's own ordering inside its analysis
        symbolic = symbolic_seconds(solver)
        split["ordering"] = max(factor_parts["analyse"] - symbolic, 0.0)
        split["symbolic"] = symbolic
    if "analyse" in factor_parts:
        inside = factor_parts["analyse"] + factor_parts.get("ordering", 0.0) + factor_parts["convert"]
        split["factor"] = factorize - inside  # the numeric factorisation and the call's own overhead
        split["convert"] = factor_parts["convert"]
    else:
        split["factor"] = factorize
    return split


def child(target_vertices: int, iterations: int, repeats: int, backend: str | None = None) -> dict[str, Any]:
    """Measure one size in this process (called in a subprocess)."""
    import arap.solve.prepared as setup_module  # the solver's set-up calls these three through this module
    from arap.meshes.shapes import sphere, sphere_frequency_for
    from arap.solve.solver import ArapSolver

    V, F = sphere(frequency=sphere_frequency_for(target_vertices))
    b, bc = caps_scenario(V)
    # Compile the kernels on a small mesh first so that JIT time is not measured.
    Vs, Fs = sphere(2)
    bs, bcs = caps_scenario(Vs)
    ArapSolver(Vs, Fs, bs).solve(bcs, max_iterations=1)
    base = current_rss_mb()
    parts: dict[str, float] = {}
    for name, key in (("assemble", "cells"), ("build_rhs_gather", "gather"), ("factorize", "factorize")):
        setattr(setup_module, name, _Timed(getattr(setup_module, name), key, parts))
    t0 = time.perf_counter()
    solver = ArapSolver(V, F, b, backend=backend)
    precompute = time.perf_counter() - t0
    rss_built = peak_rss_mb()
    split_pre = precompute_split(solver, parts, precompute)
    per_it: list[float] = []
    split: dict[str, list[float]] = {"local": [], "rhs": [], "solve": []}
    for _ in range(repeats):
        t = time.perf_counter()
        result = solver.solve(bc, initial=V, max_iterations=iterations, tolerance=0.0, acceleration="none")
        per_it.append((time.perf_counter() - t) / result.iterations)
        for key in split:
            split[key].append(result.timings[key] / result.iterations)
    peak = max(peak_rss_mb(), rss_built)
    return {
        "vertices": len(V),
        "faces": len(F),
        "constrained": len(b),
        "precompute_s": precompute,
        "precompute_split_s": split_pre,
        "ms_per_iteration": 1e3 * statistics.median(per_it),
        "split_ms": {k: 1e3 * statistics.median(v) for k, v in split.items()},
        "peak_rss_mb": peak,
        "solver_rss_mb": peak - base,
        "backend": str(getattr(solver, "backend", "?")),
    }


SPLIT_KEYS = ("cells", "gather", "other", "ordering", "symbolic", "factor", "convert", "overlapped")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--max-vertices", type=int, default=1_000_000, help="largest sphere (default: 1,000,000)")
    parser.add_argument("--sizes", type=int, nargs="+", help="approximate vertex counts to run instead of the "
                        "default series (at most 2,000,000 each)")
    parser.add_argument("--backends", nargs="+", help="sparse Cholesky backends to compare (default: the fastest "
                        "installed); each size runs once per backend")
    parser.add_argument("--iterations", type=int, default=5, help="iterations per run (default: 5)")
    parser.add_argument("--repeats", type=int, default=3, help="runs per size; medians reported (default: 3)")
    parser.add_argument("--timeout", type=float, default=1200.0, help="seconds allowed per size (default: 1200)")
    parser.add_argument("--quick", action="store_true", help="one sphere of 2,000 vertices, 2 iterations, one run")
    add_json_option(parser, "bench_scaling")
    parser.add_argument("--child", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--backend", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child is not None:
        print(json.dumps(child(args.child, args.iterations, args.repeats, args.backend)))
        return 0
    if args.quick:
        args.sizes, args.iterations, args.repeats = args.sizes or [2000], 2, 1
    sizes = args.sizes or [s for s in SIZES if s <= args.max_vertices]
    if any(not 0 < s <= 2_000_000 for s in sizes):
        parser.error("sizes must be between 1 and 2,000,000 vertices")
    backends: list[str | None] = list(args.backends or [None])

    header = (f"{'vertices':>10}  {'backend':>8}  {'precompute s':>12}  {'ms/iter':>8}  {'local':>6}  {'rhs':>6}  "
              f"{'solve':>6}  {'peak RSS MiB':>12}  {'solver MiB':>10}")
    print(f"geodesic spheres; {args.iterations} iterations, median of {args.repeats} runs; "
          "times per iteration in ms\n")
    print(header)
    print("-" * len(header))
    rows = []
    for size in sizes:
        for backend in backends:
            cmd = [sys.executable, __file__, "--child", str(size), "--iterations", str(args.iterations),
                   "--repeats", str(args.repeats)] + ([] if backend is None else ["--backend", backend])
            try:
                proc = subprocess.run(cmd, capture_output=True, text=True, timeout=args.timeout, check=False)
            except subprocess.TimeoutExpired:
                print(f"{size:>10,}  {backend or '':>8}  timed out after {args.timeout:.0f} s")
                continue
            if proc.returncode != 0:
                last = (proc.stderr.strip().splitlines() or ["(no output)"])[-1]
                print(f"{size:>10,}  {backend or '':>8}  failed: {last}")
                continue
            r = json.loads(proc.stdout.strip().splitlines()[-1])
            rows.append(r)
            s = r["split_ms"]
            print(f"{r['vertices']:>10,}  {r['backend']:>8}  {r['precompute_s']:>12.2f}  "
                  f"{r['ms_per_iteration']:>8.1f}  {s['local']:>6.1f}  {s['rhs']:>6.1f}  {s['solve']:>6.1f}  "
                  f"{r['peak_rss_mb']:>12.0f}  {r['solver_rss_mb']:>10.0f}", flush=True)
    if rows:
        print("\nprecompute split, seconds (ordering and symbolic only where the backend reports them; 'other': "
              "validation, adjacency, renumbering, matrices, constant-energy set-up; 'ordering': the ordering's time "
              "not hidden behind the set-up; 'overlapped': the ordering's run time on its own thread, beside "
              "cells, gather and other, not counted in the total)\n")
        head = f"{'vertices':>10}  {'backend':>8}  " + "  ".join(f"{k:>8}" for k in SPLIT_KEYS)
        print(head)
        print("-" * len(head))
        for r in rows:
            sp_ = r["precompute_split_s"]
            cells = "  ".join(f"{sp_[k]:>8.2f}" if k in sp_ else f"{'-':>8}" for k in SPLIT_KEYS)
            print(f"{r['vertices']:>10,}  {r['backend']:>8}  {cells}")
        print("\n'solver MiB' is the peak RSS growth while building and running the solver")
    if args.json:
        figures = []
        for r in rows:
            figures.append(figure(f"precompute, {r['vertices']:,} vertices, {r['backend']}", r["precompute_s"], "s"))
            figures.append(figure(f"time per iteration, {r['vertices']:,} vertices, {r['backend']}",
                                  r["ms_per_iteration"], "ms"))
            figures.append(figure(f"peak memory, {r['vertices']:,} vertices, {r['backend']}", r["peak_rss_mb"], "MiB"))
        write_results(args.json, "bench_scaling", figures, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
