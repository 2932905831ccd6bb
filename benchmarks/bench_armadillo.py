"""ARAP on the armadillo against libigl: precompute, time per iteration, energies and agreement; the cost of painted
stiffness.

Scenario ("bend"): the lowest 10% of the vertices along y are fixed; the top 10% are rotated 45° about the z axis
through their centroid and shifted by 10% of the bounding-box diagonal along x. Both solvers start from the rest
pose and run the same number of iterations with the spokes energy and cotangent weights.

Run: ``python benchmarks/bench_armadillo.py [--mesh PATH] [--iterations 10] [--repeats 5] [--quick] [--json OUT]``
(``--quick``: a built-in sphere of 1,000 vertices, 2 iterations, one run: a check that it runs, not a measurement).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import arap
from arap.constraints.scenarios import bend
from arap.io import load_mesh
from arap.solve.solver import ArapSolver
from benchjson import add_json_option, figure, write_results

# The reference kernels are imported as benchmarks.reference_kernels, the name the tests import them by: their
# compiled code, cached by numba, names the module it was compiled in.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

DEFAULT_MESH = Path(__file__).resolve().parents[1].parent / "shared" / "meshes" / "armadillo.obj"


def run_arap(V: np.ndarray, F: np.ndarray, b: np.ndarray, bc: np.ndarray, iterations: int,
             repeats: int) -> dict[str, Any]:
    # Warm-up on the same problem so that JIT compilation is not timed.
    ArapSolver(V, F, b).solve(bc, max_iterations=1)
    t0 = time.perf_counter()
    solver = ArapSolver(V, F, b, energy="spokes", weights="cotangent")
    precompute = time.perf_counter() - t0
    per_iteration, runs, accelerated, lbfgs = [], [], [], []
    for _ in range(repeats):
        # The plain iteration, the same count as libigl's; then the same count with Anderson acceleration and with
        # L-BFGS (the default), whose extra cost per iteration is the difference (alternated so that load drifts hit
        # all alike).
        t = time.perf_counter()
        result = solver.solve(bc, initial=V, max_iterations=iterations, tolerance=0.0, acceleration="none")
        per_iteration.append((time.perf_counter() - t) / result.iterations)
        runs.append(result)
        t = time.perf_counter()
        fast = solver.solve(bc, initial=V, max_iterations=iterations, tolerance=0.0, acceleration="anderson")
        accelerated.append((time.perf_counter() - t) / fast.iterations)
        t = time.perf_counter()
        quasi = solver.solve(bc, initial=V, max_iterations=iterations, tolerance=0.0, acceleration="lbfgs")
        lbfgs.append((time.perf_counter() - t) / quasi.iterations)
    mid = runs[int(np.argsort(per_iteration)[len(runs) // 2])]
    split = {key: 1e3 * mid.timings[key] / mid.iterations for key in ("local", "rhs", "solve")}
    return {
        "precompute_ms": 1e3 * precompute,
        "factor_seconds": float(solver.factor_seconds),
        "ms_per_iteration": 1e3 * statistics.median(per_iteration),
        "ms_per_accelerated_iteration": 1e3 * statistics.median(accelerated),
        "ms_per_lbfgs_iteration": 1e3 * statistics.median(lbfgs),
        "split_ms": split,
        "backend": str(getattr(solver, "backend", "?")),
        "U": mid.vertices,
    }


def run_igl(V: np.ndarray, F: np.ndarray, b: np.ndarray, bc: np.ndarray, iterations: int,
            repeats: int) -> dict[str, Any] | None:
    try:
        import igl
    except ImportError:
        return None
    b32 = np.ascontiguousarray(b, dtype=np.int32)
    Vc = np.ascontiguousarray(V, dtype=np.float64)
    Fc = np.ascontiguousarray(F, dtype=np.int64)
    data = igl.ARAPData()
    data.energy = igl.ARAP_ENERGY_TYPE_SPOKES
    data.max_iter = iterations
    t0 = time.perf_counter()
    igl.arap_precomputation(Vc, Fc, 3, b32, data)
    precompute = time.perf_counter() - t0
    bcc = np.ascontiguousarray(bc, dtype=np.float64)
    times, U = [], Vc
    for _ in range(repeats):
        t = time.perf_counter()
        U = igl.arap_solve(bcc, data, Vc.copy())
        times.append((time.perf_counter() - t) / iterations)
    return {"precompute_ms": 1e3 * precompute, "ms_per_iteration": 1e3 * statistics.median(times), "U": U}


def backend_choices(V: np.ndarray, F: np.ndarray, b: np.ndarray, U: np.ndarray, repeats: int) -> list[str]:
    """Measure what the solver's design chooses between: sparse Cholesky backends and rotation kernels."""
    from benchmarks.reference_kernels import fit_rotations_scalar, fit_rotations_svd

    from arap.method.cells import build_cells
    from arap.method.local_step import covariances
    from arap.method.rotations import rotations_from_covariances
    from arap.sparse.linsolve import available_backends, factorize

    A = ArapSolver(V, F, b).reduced_matrix()
    B = np.random.default_rng(0).normal(size=(A.shape[0], 3))
    lines = [f"sparse Cholesky of the reduced matrix ({A.shape[0]:,} unknowns, 3 right-hand sides):"]
    for name in available_backends():
        t = time.perf_counter()
        factor = factorize(A, name)
        factor_ms = 1e3 * (time.perf_counter() - t)
        solves = []
        for _ in range(max(repeats, 5)):
            t = time.perf_counter()
            factor.solve(B)
            solves.append(1e3 * (time.perf_counter() - t))
        lines.append(f"  {name:<10} factor {factor_ms:8.1f} ms   solve {statistics.median(solves):6.2f} ms")
    S = covariances(build_cells(V, F), U)
    rotations_from_covariances(S[:10])
    lines.append(f"batched best-fit rotations of {len(S):,} cell covariances:")
    def scalar(S: np.ndarray) -> None:
        fit_rotations_scalar(S, np.empty_like(S))

    scalar(S[:10])
    for label, fn in (("numba blocks (SIMD)", rotations_from_covariances), ("numba cell by cell", scalar),
                      ("numpy SVD + fix", fit_rotations_svd)):
        times = []
        for _ in range(max(repeats, 5)):
            t = time.perf_counter()
            fn(S)
            times.append(1e3 * (time.perf_counter() - t))
        lines.append(f"  {label:<20} {statistics.median(times):7.2f} ms")
    return lines


def kernel_comparison(V: np.ndarray, F: np.ndarray, b: np.ndarray, bc: np.ndarray, repeats: int) -> list[str]:
    """Time the kernels of one iteration alone, cell-by-cell (before) against batched (after), interleaved.

    The state is the bend after 10 iterations; each repeat times every variant once in turn, so load from other
    processes falls on all of them alike, and medians are reported. "after" is what the solver runs (serial or
    parallel as the thread policy chooses); "before" is the cell-by-cell kernels on all of numba's threads.
    """
    import numba
    from benchmarks.reference_kernels import assemble_rhs_reference, local_step_reference

    from arap.kernels.parallel import policy
    from arap.method.local_step import (
        _local_parallel,
        _local_serial,
        _rhs_parallel,
        _rhs_serial,
        assemble_rhs,
        local_step,
    )

    solver = ArapSolver(V, F, b)
    solver.solve(bc, max_iterations=10)
    U, cells, gather, active = solver._state.last, solver.prepared.cells, solver.prepared.gather, solver.prepared.active
    const = solver.prepared.L_fn @ solver.prepared.fixed_positions(bc)
    R_prev = solver._state.local.R.copy()
    R, E, out = R_prev.copy(), np.zeros(len(U)), np.empty_like(const)
    threads = numba.config.NUMBA_NUM_THREADS
    local_args = (active, cells.ptr, cells.a, cells.b, cells.w, cells.we, cells.rest_sq, U, R, E)
    rhs_args = (gather.ptr, gather.cell, gather.g, R, const, out)

    def with_threads(n: int, fn: Any) -> Any:
        def run() -> None:
            numba.set_num_threads(n)
            fn()
        return run

    variants: dict[str, dict[str, Any]] = {
        f"before ({threads} threads)": {
            "local": with_threads(threads, lambda: local_step_reference(cells, active, U, R, E)),
            "rhs": with_threads(threads, lambda: assemble_rhs_reference(gather, R, const, out))},
        "before (1 thread)": {
            "local": with_threads(1, lambda: local_step_reference(cells, active, U, R, E)),
            "rhs": with_threads(1, lambda: assemble_rhs_reference(gather, R, const, out))},
        "after (policy)": {"local": lambda: local_step(cells, active, U, R, E),
                           "rhs": lambda: assemble_rhs(gather, R, const, out)},
        "after (serial)": {"local": lambda: _local_serial(*local_args), "rhs": lambda: _rhs_serial(*rhs_args)},
        f"after ({threads} threads)": {"local": with_threads(threads, lambda: _local_parallel(*local_args)),
                                       "rhs": with_threads(threads, lambda: _rhs_parallel(*rhs_args))},
    }
    times: dict[tuple[str, str], list[float]] = {}
    solves: list[float] = []
    B = np.random.default_rng(0).normal(size=const.shape)
    for rep in range(max(repeats, 5) * 4 + 1):
        for name, kernels in variants.items():
            for kind, fn in kernels.items():
                R[...] = R_prev  # every local step starts from the same previous rotations
                t = time.perf_counter()
                fn()
                if rep:  # the first round compiles or loads the kernels
                    times.setdefault((name, kind), []).append(1e3 * (time.perf_counter() - t))
        t = time.perf_counter()
        solver.factor.solve(B)
        solves.append(1e3 * (time.perf_counter() - t))
    numba.set_num_threads(threads)
    solve = statistics.median(solves[1:])
    lines = [f"kernels of one iteration alone ({len(active):,} cells, {len(gather.cell):,} right-hand-side terms; "
             f"median ms of {len(solves) - 1} interleaved repeats; solve {solve:.2f} ms):",
             f"  {'':<22} {'local':>7} {'rhs':>7} {'(local+rhs+solve)/solve':>24}"]
    for name in variants:
        loc = statistics.median(times[(name, "local")])
        rhs = statistics.median(times[(name, "rhs")])
        lines.append(f"  {name:<22} {loc:7.2f} {rhs:7.2f} {(loc + rhs + solve) / solve:24.2f}")
    choices = ", ".join(f"{k[0]}: {'parallel' if v.prefers_parallel() else 'serial'}"
                        for k, v in policy._times.items())
    lines.append(f"  thread policy now prefers: {choices or 'serial (below the parallel work size)'}")
    return lines


def fixed_cost(V: np.ndarray, F: np.ndarray, b: np.ndarray, bc: np.ndarray, repeats: int) -> str:
    """Per-call fixed cost: a warm 1-iteration solve minus the kernels of its iteration."""
    solver = ArapSolver(V, F, b)
    solver.solve(bc, max_iterations=3)
    totals, kernels = [], []
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    moving = np.any(bc != V[b], axis=1)
    for k in range(max(repeats, 5) * 4):
        # As in a drag: the moving targets shift a little on every call.
        step = bc.copy()
        step[moving] += 1e-3 * diag * (k + 1)
        result = solver.solve(step, max_iterations=1)
        totals.append(1e3 * result.timings["total"])
        kernels.append(1e3 * sum(result.timings[k] for k in ("local", "rhs", "solve", "acceleration")))
    total, kern = statistics.median(totals), statistics.median(kernels)
    return (f"warm 1-iteration solve: {total:.2f} ms, of which fixed per-call work {total - kern:.2f} ms "
            f"({100 * (total - kern) / total:.0f}%)")


def painted_cost(V: np.ndarray, F: np.ndarray, b: np.ndarray, bc: np.ndarray, iterations: int,
                 repeats: int) -> str:
    """Per-iteration cost with painted stiffness (the default energy, the plain iteration): none, 100 and rigid on
    the band of vertices between 45% and 65% of the height, alternated run by run."""
    y = V[:, 1]
    lo, hi = np.quantile(y, [0.45, 0.65])
    band = np.flatnonzero((y > lo) & (y < hi))
    cases = {"none": None, "100": 100.0, "rigid": np.inf}
    solvers = {}
    for name, value in cases.items():
        stiffness = None
        if value is not None:
            stiffness = np.ones(len(V))
            stiffness[band] = value
        solvers[name] = ArapSolver(V, F, b, stiffness=stiffness)
        solvers[name].solve(bc, max_iterations=2)
    times: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(repeats):
        for name, solver in solvers.items():
            t = time.perf_counter()
            result = solver.solve(bc, initial=V, max_iterations=iterations, tolerance=0.0, acceleration="none")
            times[name].append(1e3 * (time.perf_counter() - t) / result.iterations)
    parts = ", ".join(f"{name} {statistics.median(t):.2f} ms" for name, t in times.items())
    return f"per iteration with painted stiffness on {len(band):,} vertices (default energy, plain): {parts}"


def table(rows: list[tuple[str, str, str]]) -> str:
    widths = [max(len(r[i]) for r in rows) for i in range(3)]
    lines = []
    for k, r in enumerate(rows):
        lines.append("  ".join(cell.ljust(widths[i]) if i == 0 else cell.rjust(widths[i]) for i, cell in enumerate(r)))
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--mesh", type=Path, default=DEFAULT_MESH, help=f"mesh file (default: {DEFAULT_MESH})")
    parser.add_argument("--iterations", type=int, default=10, help="iterations per run (default: 10)")
    parser.add_argument("--repeats", type=int, default=5, help="runs; medians are reported (default: 5)")
    add_json_option(parser, "bench_armadillo")
    parser.add_argument("--plot", type=Path, help="bar chart of the times (PNG; needs matplotlib)")
    parser.add_argument("--quick", action="store_true",
                        help="a built-in sphere of 1,000 vertices, 2 iterations, one run")
    args = parser.parse_args(argv)
    if args.quick:
        args.mesh, args.iterations, args.repeats = Path("sphere:1000"), 2, 1
        V, F = arap.builtin_mesh("sphere:1000")
    elif not args.mesh.exists():
        print(f"mesh {args.mesh} not found (use --mesh)", file=sys.stderr)
        return 2
    else:
        V, F = load_mesh(args.mesh)
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    scenario = bend(V, axis=1, angle=np.radians(45.0), shift=0.1)
    fixed, handles = scenario.fixed, scenario.handles
    b, bc = scenario.constrained, scenario.targets
    print(f"{args.mesh.name}: {len(V):,} vertices, {len(F):,} faces; {len(fixed):,} fixed, {len(handles):,} "
          f"handles; {args.iterations} iterations, median of {args.repeats} runs\n")

    ours = run_arap(V, F, b, bc, args.iterations, args.repeats)
    igl_res = run_igl(V, F, b, bc, args.iterations, args.repeats)
    e_ours = arap.arap_energy(V, F, ours["U"], "spokes", "cotangent")
    split = ours["split_ms"]
    rows = [("", "arap", "libigl 2.6.3" if igl_res else "libigl (not installed)")]
    rows.append(("precompute (ms)", f"{ours['precompute_ms']:.1f}",
                 f"{igl_res['precompute_ms']:.1f}" if igl_res else "-"))
    rows.append(("per iteration (ms)", f"{ours['ms_per_iteration']:.2f}",
                 f"{igl_res['ms_per_iteration']:.2f}" if igl_res else "-"))
    rows.append(("  local: covariances + rotations", f"{split['local']:.2f}", ""))
    rows.append(("  right-hand side", f"{split['rhs']:.2f}", ""))
    rows.append(("  solve", f"{split['solve']:.2f}", ""))
    rows.append(("per iteration, Anderson (ms)", f"{ours['ms_per_accelerated_iteration']:.2f}", ""))
    rows.append(("Anderson overhead per iteration",
                 f"{ours['ms_per_accelerated_iteration'] / ours['ms_per_iteration'] - 1:+.0%}", ""))
    rows.append(("per iteration, L-BFGS (default, ms)", f"{ours['ms_per_lbfgs_iteration']:.2f}", ""))
    rows.append(("L-BFGS overhead per iteration",
                 f"{ours['ms_per_lbfgs_iteration'] / ours['ms_per_iteration'] - 1:+.0%}", ""))
    rows.append(("iteration / solve", f"{ours['ms_per_iteration'] / max(split['solve'], 1e-9):.2f}", ""))
    rows.append(("final energy", f"{e_ours:.6g}", ""))
    figures: dict[str, Any] = {
        "mesh": str(args.mesh), "vertices": len(V), "faces": len(F), "fixed": len(fixed), "handles": len(handles),
        "iterations": args.iterations, "repeats": args.repeats, "backend": ours["backend"],
        "arap": {k: v for k, v in ours.items() if k != "U"} | {"energy": e_ours},
    }
    if igl_res:
        e_igl = arap.arap_energy(V, F, igl_res["U"], "spokes", "cotangent")
        rows[-1] = ("final energy", f"{e_ours:.6g}", f"{e_igl:.6g}")
        dist = float(np.linalg.norm(ours["U"] - igl_res["U"], axis=1).max()) / diag
        figures["libigl"] = {k: v for k, v in igl_res.items() if k != "U"} | {"energy": e_igl}
        figures["max_distance_over_diagonal"] = dist
        figures["speedup_iteration"] = igl_res["ms_per_iteration"] / ours["ms_per_iteration"]
        figures["speedup_precompute"] = igl_res["precompute_ms"] / ours["precompute_ms"]
    print(table(rows))
    print(f"\nlinear solver: {ours['backend']}")
    if igl_res:
        print(f"libigl / arap: {figures['speedup_iteration']:.2f}x per iteration, "
              f"{figures['speedup_precompute']:.2f}x precompute")
        print(f"max vertex distance between the results: {figures['max_distance_over_diagonal']:.2e} of the diagonal")
    print()
    print("\n".join(kernel_comparison(V, F, b, bc, args.repeats)))
    print(fixed_cost(V, F, b, bc, args.repeats))
    print(painted_cost(V, F, b, bc, args.iterations, args.repeats))
    print()
    print("\n".join(backend_choices(V, F, b, ours["U"], args.repeats)))
    if args.json:
        peer = "libigl" if igl_res else None
        write_results(args.json, "bench_armadillo", [
            figure(f"precompute, {args.mesh.name}", ours["precompute_ms"], "ms", peer,
                   igl_res["precompute_ms"] if igl_res else None),
            figure(f"time per iteration, {args.mesh.name}", ours["ms_per_iteration"], "ms", peer,
                   igl_res["ms_per_iteration"] if igl_res else None),
            figure("time per iteration, L-BFGS (default)", ours["ms_per_lbfgs_iteration"], "ms",
                   "plain iteration", ours["ms_per_iteration"]),
            figure("time per iteration, Anderson", ours["ms_per_accelerated_iteration"], "ms",
                   "plain iteration", ours["ms_per_iteration"]),
        ], figures)
    if args.plot:
        plot(figures, args.plot)
    return 0


def plot(figures: dict[str, Any], path: Path) -> None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed; no plot", file=sys.stderr)
        return
    names = ["arap"] + (["libigl"] if "libigl" in figures else [])
    fig, axes = plt.subplots(1, 2, figsize=(8, 3))
    axes[0].bar(names, [figures[n]["precompute_ms"] for n in names])
    axes[0].set_ylabel("precompute (ms)")
    axes[1].bar(names, [figures[n]["ms_per_iteration"] for n in names])
    axes[1].set_ylabel("ms per iteration")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


if __name__ == "__main__":
    sys.exit(main())
