"""Time to a converged shape against libigl: our default solver against 1,000 libigl iterations, same run.

For each scenario libigl (spokes energy, cotangent weights, from the rest pose) runs ``--igl-iterations`` iterations;
its energy ``E_igl`` is evaluated with our exact (double-precision) energy. Our default solver (same energy and weights;
L-BFGS, start chosen by energy, until converged), and Anderson acceleration for comparison, run with a callback that
records the time and energy of every iteration. Printed per scenario: libigl's time, the iterations and time we need to
reach ``E_igl``, their ratio (target ≤ 1/20), and both final energies relative to the gap ``G = E(first iteration) −
min(E_igl, E_ours)``. With obtuse triangles the energy has several local minima, so a run can settle in a different one;
the table says so rather than hiding it.

The rigid rows move 40 scattered vertices by one rigid motion rotated 170° and report the distance of each
result from that motion, in bounding-box diagonals.

Run: ``python benchmarks/bench_convergence.py [--igl-iterations 1000] [--quick] [--json OUT]`` (``--quick``: the
cactus and the knight, 20 libigl iterations: a check that it runs, not a measurement).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np

from arap import ArapSolver, arap_energy
from arap.io import load_mesh
from arap.meshes._geometry import best_rigid_transform
from arap.meshes.shapes import builtin_mesh
from arap.options import ACCELERATIONS, Acceleration
from benchjson import add_json_option, figure, write_results
from scenarios import make_scenario

MESHES = Path(__file__).resolve().parents[1].parent / "shared" / "meshes"
SCENARIOS = [("armadillo.obj", "bend"), ("armadillo.obj", "twist"), ("camelhead.off", "bend"),
             ("decimated-knight.off", "bend"), ("cactus", "bend")]
RIGID = ["cactus", "decimated-knight.off"]


def load(name: str) -> tuple[np.ndarray, np.ndarray]:
    if "." in name:
        return load_mesh(MESHES / name)
    return builtin_mesh(name)


def run_igl(V: np.ndarray, F: np.ndarray, b: np.ndarray, bc: np.ndarray, iterations: int) -> dict[str, Any]:
    import igl

    data = igl.ARAPData()
    data.energy = igl.ARAP_ENERGY_TYPE_SPOKES
    data.max_iter = iterations
    t = time.perf_counter()
    igl.arap_precomputation(V, F, 3, b.astype(np.int64), data)
    t_pre = time.perf_counter() - t
    t = time.perf_counter()
    U = np.asarray(igl.arap_solve(bc, data, V.copy()))
    return {"precompute_s": t_pre, "solve_s": time.perf_counter() - t, "U": U}


def run_ours(V: np.ndarray, F: np.ndarray, b: np.ndarray, bc: np.ndarray,
             acceleration: Acceleration = "lbfgs") -> dict[str, Any]:
    t = time.perf_counter()
    solver = ArapSolver(V, F, b, energy="spokes", weights="cotangent")
    t_pre = time.perf_counter() - t
    trace: list[tuple[float, float]] = []
    t0 = time.perf_counter()

    def record(iteration: int, energy: float) -> None:
        trace.append((time.perf_counter() - t0, energy))

    result = solver.solve(bc, callback=record, acceleration=acceleration)
    return {"precompute_s": t_pre, "solve_s": time.perf_counter() - t0, "trace": trace, "result": result}


def scenario_rows(mesh: str, name: str, igl_iterations: int, accelerations: list[str]) -> list[dict[str, Any]]:
    V, F = load(mesh)
    s = make_scenario(name, V)
    igl_run = run_igl(V, F, s.constrained, s.targets, igl_iterations)
    e_igl = arap_energy(V, F, igl_run["U"], "spokes")
    return [ours_row(V, F, mesh, name, s.constrained, s.targets, igl_run, e_igl, a) for a in accelerations]


def ours_row(V: np.ndarray, F: np.ndarray, mesh: str, name: str, b: np.ndarray, bc: np.ndarray,
             igl_run: dict[str, Any], e_igl: float, acceleration: Any) -> dict[str, Any]:
    ours = run_ours(V, F, b, bc, acceleration)
    times, energies = zip(*ours["trace"], strict=True)
    e_ours = energies[-1]
    reached = next((k for k, e in enumerate(energies) if e <= e_igl), None)
    gap = energies[0] - min(e_igl, e_ours)
    row = {
        "scenario": f"{Path(mesh).stem} {name}", "vertices": len(V), "acceleration": acceleration,
        "igl_s": igl_run["solve_s"], "igl_energy": e_igl,
        "ours_iterations": ours["result"].iterations, "ours_s": ours["solve_s"], "ours_energy": e_ours,
        "converged": ours["result"].converged,
        "reach_iterations": None if reached is None else reached + 1,
        "reach_s": None if reached is None else times[reached],
        "gap": gap,
    }
    row["ratio"] = None if reached is None else row["reach_s"] / row["igl_s"]
    return row


def rigid_row(mesh: str, igl_iterations: int) -> dict[str, Any]:
    V, F = load(mesh)
    s = make_scenario("rigid", V)
    diag = float(np.linalg.norm(V.max(0) - V.min(0)))
    # The whole rest pose moved by the same motion: recover it from the constrained targets.
    R, t = best_rigid_transform(V[s.constrained], s.targets)
    moved = V @ R.T + t
    igl_run = run_igl(V, F, s.constrained, s.targets, igl_iterations)
    ours = run_ours(V, F, s.constrained, s.targets)
    return {"scenario": f"{Path(mesh).stem} rigid 170°", "vertices": len(V),
            "igl_off": float(np.abs(igl_run["U"] - moved).max() / diag), "igl_s": igl_run["solve_s"],
            "ours_off": float(np.abs(ours["result"].vertices - moved).max() / diag),
            "ours_iterations": ours["result"].iterations, "ours_s": ours["solve_s"]}


def fmt(x: float | None, spec: str) -> str:
    return "—" if x is None else format(x, spec)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--igl-iterations", type=int, default=1000)
    p.add_argument("--quick", action="store_true",
                   help="the cactus and the knight only, 20 libigl iterations (a check that it runs)")
    add_json_option(p, "bench_convergence")
    p.add_argument("--accelerations", nargs="+", choices=ACCELERATIONS, default=["lbfgs", "anderson"],
                   help="our solvers to time against the same libigl run (default: lbfgs anderson)")
    args = p.parse_args(argv)
    try:
        import igl  # noqa: F401
    except ImportError:
        raise SystemExit("libigl is not installed (pip install libigl): it is the peer measured here") from None
    iterations = 20 if args.quick else args.igl_iterations
    scenarios = [sc for sc in SCENARIOS if not args.quick or sc[0] in RIGID]
    # Compile the kernels before timing.
    V, F = builtin_mesh("bar")
    ArapSolver(V, F, [0, 1, 2]).solve(V[[0, 1, 2]] + 0.1, max_iterations=3)

    rows = [row for mesh, name in scenarios for row in scenario_rows(mesh, name, iterations, args.accelerations)]
    print(f"\nTime to libigl's energy after {iterations} iterations (spokes, cotangent weights; seconds)")
    print(f"{'scenario':<22}{'ours':>9}{'n':>7}{'libigl':>9}{'ours: it':>10}{'time':>8}{'ratio':>8}"
          f"{'(E_igl−E*)/G':>14}{'(E_ours−E*)/G':>15}{'ours total':>12}{'it':>6}")
    for r in rows:
        best = min(r["igl_energy"], r["ours_energy"])
        print(f"{r['scenario']:<22}{r['acceleration']:>9}{r['vertices']:>7}{r['igl_s']:>9.2f}"
              f"{fmt(r['reach_iterations'], 'd'):>10}"
              f"{fmt(r['reach_s'], '.3f'):>8}{fmt(r['ratio'], '.3f'):>8}"
              f"{(r['igl_energy'] - best) / r['gap']:>14.2e}{(r['ours_energy'] - best) / r['gap']:>15.2e}"
              f"{r['ours_s']:>12.3f}{r['ours_iterations']:>6}")
    rigid_rows = [rigid_row(mesh, iterations) for mesh in RIGID]
    print(f"\nAll constraints moved by one rigid motion (170°): distance from it, in diagonals "
          f"(libigl after {iterations} iterations)")
    print(f"{'scenario':<26}{'libigl off':>12}{'libigl s':>10}{'ours off':>12}{'ours it':>9}{'ours s':>9}")
    for r in rigid_rows:
        print(f"{r['scenario']:<26}{r['igl_off']:>12.2e}{r['igl_s']:>10.2f}{r['ours_off']:>12.2e}"
              f"{r['ours_iterations']:>9}{r['ours_s']:>9.3f}")
    if args.json is not None:
        figures = [figure(f"time to libigl's energy, {r['scenario']}, {r['acceleration']}", r["reach_s"], "s",
                          f"libigl, {iterations} iterations", r["igl_s"]) for r in rows if r["reach_s"] is not None]
        figures += [figure(f"distance from the rigid motion, {r['scenario']}", r["ours_off"], "diagonals",
                           f"libigl, {iterations} iterations", r["igl_off"]) for r in rigid_rows]
        write_results(args.json, "bench_convergence", figures, {"scenarios": rows, "rigid": rigid_rows})


if __name__ == "__main__":
    main()
