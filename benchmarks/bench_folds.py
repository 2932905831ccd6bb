"""Which energy and weights fold meshes with obtuse triangles: folded face pairs after solving to convergence.

For every mesh (the shared scans and generated meshes with many negative cotangent weights) and every scenario
of ``benchmarks/scenarios.py`` (bend, twist, pull), each energy/weights variant is solved from the rest pose until
the relative energy change falls below ``--tolerance`` or ``--max-iterations`` is reached. Printed per run: folded
adjacent-face pairs (unit normals' dot < −0.5) of the result and of the rest shape, the largest change of a dihedral
angle, the variant's own energy and the paper's energy (spokes, cotangent weights) of the result. libigl's spokes ARAP
(cotangent weights, a fixed number of iterations: the same cap) runs in the same process as a peer on meshes up to
``--igl-max-vertices``.

Run: ``python benchmarks/bench_folds.py [--quick] [--max-iterations 500] [--json OUT]``
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arap.io import load_mesh
from arap.meshes.shapes import obtuse_cylinder, scan_blob
from arap.method.energy import arap_energy
from arap.method.weights import edge_weight_matrix
from arap.solve.solver import ArapSolver
from benchjson import add_json_option, figure, write_results
from folds import adjacent_face_pairs, folded_pairs, max_dihedral_change
from scenarios import make_scenario

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "meshes"
SCANS = ("decimated-knight.off", "camelhead.off", "armadillo.obj")
VARIANTS: tuple[tuple[str, str], ...] = (
    ("spokes", "cotangent"),
    ("spokes", "clamped"),
    ("spokes", "uniform"),
    ("spokes_and_rims", "cotangent"),
    ("spokes_and_rims", "clamped"),
)
FOLD_SCENARIOS = ("bend", "twist", "pull")
Mesh = tuple[str, NDArray[np.float64], NDArray[np.int64]]


def meshes(quick: bool) -> list[Mesh]:
    """The generated obtuse meshes, then the shared scans that exist (only the knight with ``quick``)."""
    out: list[Mesh] = []
    if quick:
        out.append(("obtuse cylinder 3k", *obtuse_cylinder(spacing=0.1)))
        out.append(("scan blob 1.5k", *scan_blob(n=1500)))
    else:
        out.append(("obtuse cylinder 12k", *obtuse_cylinder()))
        out.append(("scan blob 4k", *scan_blob()))
    for name in SCANS[:1] if quick else SCANS:
        path = SHARED / name
        if path.exists():
            V, F = load_mesh(path)
            out.append((path.stem, V, F))
        else:
            print(f"(skipping {path}: not found)", file=sys.stderr)
    return out


def negative_share(V: NDArray[np.float64], F: NDArray[np.int64]) -> float:
    import scipy.sparse as sp

    upper = sp.triu(edge_weight_matrix(V, F), k=1).tocsr()
    return float((upper.data < 0).mean())


def run_arap(V: NDArray[np.float64], F: NDArray[np.int64], constrained: NDArray[np.int64],
             targets: NDArray[np.float64], energy: str, weights: str, max_iterations: int,
             tolerance: float) -> dict[str, Any]:
    t0 = time.perf_counter()
    solver = ArapSolver(V, F, constrained, energy=energy, weights=weights)
    result = solver.solve(targets, initial=V, max_iterations=max_iterations, tolerance=tolerance)
    return {"U": result.vertices, "iterations": result.iterations, "converged": result.converged,
            "energy": result.energies[-1] if result.energies else float("nan"),
            "seconds": time.perf_counter() - t0}


def run_igl(V: NDArray[np.float64], F: NDArray[np.int64], constrained: NDArray[np.int64],
            targets: NDArray[np.float64], iterations: int) -> dict[str, Any] | None:
    try:
        import igl
    except ImportError:
        return None
    t0 = time.perf_counter()
    data = igl.ARAPData()
    data.energy = igl.ARAP_ENERGY_TYPE_SPOKES
    data.max_iter = iterations
    igl.arap_precomputation(V, F.astype(np.int64), 3, constrained.astype(np.int64), data)
    U = igl.arap_solve(targets, data, V.copy())
    return {"U": np.asarray(U, dtype=np.float64), "iterations": iterations, "converged": False,
            "energy": float("nan"), "seconds": time.perf_counter() - t0}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small meshes and 60 iterations (a CI-size check)")
    parser.add_argument("--max-iterations", type=int, default=None, help="cap per solve (default 500; quick 60)")
    parser.add_argument("--tolerance", type=float, default=1e-7, help="relative energy change to stop at")
    parser.add_argument("--scenarios", nargs="+", choices=FOLD_SCENARIOS, default=list(FOLD_SCENARIOS))
    parser.add_argument("--meshes", nargs="+", metavar="NAME", help="only meshes whose name contains one of these")
    parser.add_argument("--igl-max-vertices", type=int, default=15000,
                        help="run libigl only on meshes up to this size (default 15,000; 0: never)")
    add_json_option(parser, "bench_folds")
    args = parser.parse_args(argv)
    cap = args.max_iterations if args.max_iterations is not None else (60 if args.quick else 500)

    header = (f"{'mesh':<20} {'neg w':>6} {'scenario':<6} {'variant':<26} {'it':>4} {'folds':>6} {'rest':>5} "
              f"{'extra':>6} {'max Δθ°':>7} {'E own':>10} {'E spokes/cot':>12} {'s':>6}")
    print(f"solved from the rest pose until the relative energy change <= {args.tolerance:g}, at most {cap} "
          "iterations (libigl: exactly that many); folds = adjacent face pairs with normals' dot < -0.5")
    print(header)
    print("-" * len(header))
    rows: list[dict[str, Any]] = []
    for label, V, F in meshes(args.quick):
        if args.meshes and not any(part in label for part in args.meshes):
            continue
        adjacency = adjacent_face_pairs(F)
        rest_folds = folded_pairs(V, F, pairs=adjacency[0])
        share = negative_share(V, F)
        diag = float(np.linalg.norm(V.max(0) - V.min(0)))
        for scenario_name in args.scenarios:
            scenario = make_scenario(scenario_name, V)
            constrained = scenario.constrained
            targets = scenario.targets
            runs: list[tuple[str, dict[str, Any] | None]] = [
                (f"{energy}/{weights}", run_arap(V, F, constrained, targets, energy, weights, cap, args.tolerance))
                for energy, weights in VARIANTS
            ]
            if 0 < len(V) <= args.igl_max_vertices:
                runs.append(("libigl spokes/cotangent", run_igl(V, F, constrained, targets, cap)))
            for variant, run in runs:
                if run is None:
                    continue
                U = run["U"]
                folds = folded_pairs(U, F, pairs=adjacency[0])
                row = {
                    "mesh": label, "vertices": len(V), "negative_weight_share": share, "scenario": scenario_name,
                    "variant": variant, "iterations": run["iterations"], "converged": run["converged"],
                    "folds": folds, "rest_folds": rest_folds, "extra_folds": folds - rest_folds,
                    "max_dihedral_change_deg": float(np.degrees(max_dihedral_change(V, U, F))),
                    "energy": run["energy"], "paper_energy": arap_energy(V, F, U, "spokes", "cotangent"),
                    "seconds": run["seconds"], "diagonal": diag,
                }
                rows.append(row)
                it = f"{row['iterations']}{'' if row['converged'] or variant.startswith('libigl') else '+'}"
                print(f"{label:<20} {100 * share:>5.1f}% {scenario_name:<6} {variant:<26} {it:>4} {folds:>6} "
                      f"{rest_folds:>5} {folds - rest_folds:>+6} {row['max_dihedral_change_deg']:>7.1f} "
                      f"{row['energy']:>10.4g} {row['paper_energy']:>12.4g} {row['seconds']:>6.1f}", flush=True)
    print("it: iterations run ('+': stopped by the cap, not converged); E own: the variant's energy; "
          "E spokes/cot: the paper's energy of the result; s: seconds including precompute (machine under load)")
    if args.json:
        igl_rows = {(r["mesh"], r["scenario"]): r for r in rows if r["variant"].startswith("libigl")}
        figures = []
        for r in rows:
            if r["variant"].startswith("libigl"):
                continue
            peer = igl_rows.get((r["mesh"], r["scenario"]))
            figures.append(figure(f"folded pairs added, {r['mesh']}, {r['scenario']}, {r['variant']}",
                                  r["extra_folds"], "pairs", "libigl" if peer else None,
                                  peer["extra_folds"] if peer else None))
        write_results(args.json, "bench_folds", figures, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
