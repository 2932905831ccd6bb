"""``arap bench``: precompute and time per iteration of the solver on a mesh, with the bend scenario of
:mod:`arap.constraints.scenarios`, as a table or as JSON."""

from __future__ import annotations

import argparse
import json
import statistics
import time

import numpy as np

from arap.cli.common import alpha_value, check_bench_runs, load_mesh_argument, out
from arap.options import DEFAULT_ALPHA, DEFAULT_ENERGY, DEFAULT_WEIGHTS, ENERGY_TYPES, WEIGHT_TYPES
from arap.warmup import warm_up_kernels

__all__ = ["add_parser", "bench_constraints", "constrained_components", "run_bench"]


def add_parser(commands: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``arap bench`` and its options to the subcommands of ``arap``."""
    p = commands.add_parser("bench", help="time the solver on a mesh",
                            description="Fix the lowest 10% along the longest axis, move the top 10% (connected parts "
                                        "with neither stay at rest), and time the precompute and the iterations.")
    p.add_argument("mesh", metavar="MESH", nargs="?", default="sphere",
                   help="default: a geodesic sphere of 40,962 vertices")
    p.add_argument("-n", "--iterations", type=int, default=10, help="iterations per run (default: 10)")
    p.add_argument("-r", "--repeats", type=int, default=3, help="runs; the median is reported (default: 3)")
    p.add_argument("--energy", choices=ENERGY_TYPES, default=DEFAULT_ENERGY)
    p.add_argument("--weights", choices=WEIGHT_TYPES, default=DEFAULT_WEIGHTS)
    p.add_argument("--alpha", type=alpha_value, default=DEFAULT_ALPHA, help="rotation term weight of smooth_rotations")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.set_defaults(func=run_bench)


def bench_constraints(V: np.ndarray, share: float = 0.1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The bend scenario of :mod:`arap.constraints.scenarios`: fix the lowest ``share`` along the longest axis, move the
    top.

    Returns
    -------
    fixed : (f,) int64 array
    handles : (h,) int64 array
    targets : (h, 3) float64 array
        Handles rotated 30° about their centroid (in the plane of the longest axis and the next one), then
        shifted along that next axis by 10% of the bounding-box diagonal.
    """
    from arap.constraints.scenarios import bend

    scenario = bend(V, share=share, angle=np.pi / 6, shift=0.1)
    return scenario.fixed, scenario.handles, scenario.targets[len(scenario.fixed):]


def constrained_components(F: np.ndarray, n: int, indices: np.ndarray) -> np.ndarray | None:
    """The vertices of the connected components holding one of ``indices``, as a region of interest, or None when
    that is every vertex: the other components (floating islands of a scan) stay at rest instead of being parts
    that no constraint pins down.

    Example
    -------
    >>> F = np.array([[0, 1, 2], [3, 4, 5]])
    >>> constrained_components(F, 6, np.array([1])).tolist()
    [0, 1, 2]
    """
    from arap.meshes.topology import connected_components

    _, labels = connected_components(F, n)
    inside = np.isin(labels, labels[indices])
    return None if inside.all() else np.flatnonzero(inside)


def run_bench(args: argparse.Namespace) -> int:
    """``arap bench``: time precompute and iterations on a mesh (the bend scenario); prints a table or JSON."""
    from arap.solve.solver import ArapSolver

    check_bench_runs(args.iterations, args.repeats)
    V, F, _, label = load_mesh_argument(args.mesh)
    fixed, handles, targets = bench_constraints(V)
    indices = np.concatenate([fixed, handles])
    all_targets = np.concatenate([V[fixed], targets])
    kernels = warm_up_kernels(quiet=args.json).record()
    t0 = time.perf_counter()
    roi = constrained_components(F, len(V), indices)
    solver = ArapSolver(V, F, indices, energy=args.energy, weights=args.weights, alpha=args.alpha, roi=roi)
    precompute = time.perf_counter() - t0
    runs = []
    for _ in range(args.repeats):
        result = solver.solve(all_targets, initial=V, max_iterations=args.iterations, tolerance=0.0,
                              acceleration="none")
        runs.append(result)
    per_it = [1e3 * (r.timings["local"] + r.timings["rhs"] + r.timings["solve"]) / r.iterations for r in runs]
    best = runs[int(np.argsort(per_it)[len(per_it) // 2])]
    k = best.iterations
    split = {key: 1e3 * best.timings[key] / k for key in ("local", "rhs", "solve")}
    backend = getattr(solver, "backend", None) or "?"
    if args.json:
        out(json.dumps({
            "mesh": label, "n_vertices": len(V), "n_faces": len(F),
            "n_fixed": len(fixed), "n_handles": len(handles),
            "energy": args.energy, "weights": args.weights, "linear_solver": str(backend),
            "kernels": kernels,
            "precompute_ms": 1e3 * precompute,
            "iterations": k, "repeats": args.repeats,
            "iteration_ms": statistics.median(per_it), "iteration_ms_runs": per_it,
            "split_ms": split,
            "energy_first": best.energies[0], "energy_last": best.energies[-1],
        }, indent=2))
        return 0
    rows = [
        ("mesh", f"{label}: {len(V):,} vertices, {len(F):,} faces"),
        ("constraints", f"{len(fixed):,} fixed, {len(handles):,} handles" + (
            "" if roi is None else f"; {len(V) - len(roi):,} vertices of parts without one held at rest")),
        ("energy / weights", f"{args.energy} / {args.weights}"),
        ("linear solver", str(backend)),
        ("precompute", f"{1e3 * precompute:.1f} ms"),
        ("per iteration", f"{statistics.median(per_it):.2f} ms (median of {args.repeats} runs of {k})"),
        ("  local (covariances + rotations)", f"{split['local']:.2f} ms"),
        ("  right-hand side", f"{split['rhs']:.2f} ms"),
        ("  solve", f"{split['solve']:.2f} ms"),
        ("energy", f"{best.energies[0]:.6g} -> {best.energies[-1]:.6g}"),
    ]
    width = max(len(name) for name, _ in rows)
    for name, value in rows:
        out(f"{name.ljust(width)}  {value}")
    return 0
