"""The element energy (one rotation per triangle or tetrahedron) against libigl's elements solver, same run.

Scenarios: a planar 2:1 strip with a hole (about 7k vertices) and a planar rectangle of about 50k vertices, one end held
and the other turned 90° about its centre; a 30×6×6-cube bar of tetrahedra (six per cube) and a larger bar (over 100k
tetrahedra), one end held and the other twisted 120°; a tetrahedralized scan, the armadillo filled with about 120k
tetrahedra (:func:`fill_surface`, cached), feet held and head turned 90° about the vertical. libigl
(``ARAP_ENERGY_TYPE_ELEMENTS``, from the rest pose with the constrained vertices at their targets) runs
``--igl-iterations`` iterations (1,000 planar, 300 for tetrahedra by default); its energy is evaluated with our exact
energy. arap (the default solver: L-BFGS, until converged, from the same start) records the time of every iteration.
Printed per scenario: libigl's time (precompute and iterations), the time arap needs to reach libigl's energy and to
converge (set-up included in both), their ratios (target ≤ 1/20), the iterations arap takes to each (deterministic:
comparable across machines and loads, unlike the times), both final energies and arap's relative to libigl's (target ≤
0), and the inverted elements of each result (target: none where libigl has none; an element solve opens the elements it
turned over, see ``arap.method.unfold``).

Folds, measured (iterations and folds are deterministic for a given Cholesky back end; counted are every iteration the
callback saw, and the triangles turned over at the end). Without opening folds, the planar 50k rectangle ends with
two folded triangles, 8e-7 relatively above libigl's energy, where libigl keeps every triangle positive. Bounding
every step so that no element turns over instead would have cut the 103k-tetrahedron bar's steps 138 times (55
iterations becoming 200), though it ends with none inverted. Opening the folds once converged and resuming (the
previous method), then opening them once the energy settles (an iteration lowers it by at most 1e-6 of it) and giving
the opened run up as soon as it settles no lower or with more folds: strip with a hole 119 → 79 iterations (74
without opening), 3 → 1 folds (libigl 2; the energy alone would keep a minimum 7e-6 relatively lower with three);
planar 50k 153 → 87 iterations, no folds; tet bar 30×6×6 65 → 65, none. Rectangles turned 90° (not run here):
100×50 109 → 81 iterations, 2 folds; 80×40 94 (55 counted) → 65, 2 folds, no lower minimum found; 60×30 89 → 68, 1
fold. libigl ends with the same folds on the three rectangles: on the 100×50 it converges to the folded minimum the
solve reaches first (the same energy to 12 digits) with the same two triangles turned over, ten columns from the
turned end; opened (by 20 or by 100 smoothing sweeps), the solve turns those two over again, 3.5e-5 relatively lower.

Run: ``python benchmarks/bench_elements.py [--quick] [--json [OUT]]``
"""

from __future__ import annotations

import argparse
import hashlib
import time
from pathlib import Path
from typing import Any

import numpy as np

from arap import ArapSolver, arap_energy, load_mesh
from arap.io.atomic import atomic_output
from arap.meshes.domain import signed_measures
from arap.meshes.grids import box_tetrahedra, rectangle_triangles
from benchjson import add_json_option, figure, write_results
from scenarios import twist

SCAN = Path(__file__).resolve().parents[1].parent / "shared" / "meshes" / "armadillo.obj"
SCAN_TETRAHEDRA = {False: 120_000, True: 6_000}  # tetrahedra aimed at, full and --quick
SCAN_VERSION = 1  # part of the cache key: bump when scan_tetrahedra changes what it makes


def _rotation(angle: float, dim: int) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    if dim == 2:
        return np.array([[c, -s], [s, c]])
    return np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])


def _quality(V: np.ndarray, T: np.ndarray) -> np.ndarray:
    """6√2 volume / longest edge³ of each tetrahedron: 1 for a regular one, 0 for a flat one, negative inverted."""
    E = V[T]
    longest = np.max([np.linalg.norm(E[:, i] - E[:, j], axis=1) for i in range(4) for j in range(i + 1, 4)], axis=0)
    return np.sqrt(2.0) * signed_measures(V, T) / longest ** 3  # signed_measures: 6 × the volume


def _faces(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The four faces of each tetrahedron (sorted corners) as unique rows, and the index of each tet face in them."""
    faces = np.sort(T[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]].reshape(-1, 3), axis=1)
    unique, index = np.unique(faces, axis=0, return_inverse=True)
    return unique, index.ravel()


def _move(G: np.ndarray, T: np.ndarray, moving: np.ndarray, goal: np.ndarray, min_quality: float) -> np.ndarray:
    """``G`` with the vertices ``moving`` moved towards ``goal``, each a share of the way (1, halved up to ten
    times, else 0) that keeps every tetrahedron they are corners of at a quality of at least ``min_quality``."""
    where = np.full(len(G), -1, dtype=np.int64)
    where[moving] = np.arange(len(moving))
    near = np.flatnonzero((where[T] >= 0).any(axis=1))
    share = np.ones(len(moving))
    moved = G.copy()
    for attempt in range(12):
        if attempt == 11:
            share[share < 0.5 ** 10] = 0.0
        moved[moving] = G[moving] + share[:, None] * (goal - G[moving])
        bad = near[_quality(moved, T[near]) < min_quality]
        if not len(bad):
            return moved
        hit = where[T[bad]].ravel()
        share[np.unique(hit[hit >= 0])] *= 0.5
    return G  # not reached: with every share 0 the tetrahedra are those of G


def fill_surface(V: np.ndarray, F: np.ndarray, count: int, min_quality: float = 0.1,
                 rounds: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """About ``count`` well-shaped, positively oriented tetrahedra filling the closed surface ``V``, ``F``.

    A lattice of cubes cut into six tetrahedra each (:func:`box_tetrahedra`, quality 0.27), spaced for ``count``
    tetrahedra in the surface's volume, keeps the tetrahedra whose centroid is inside (libigl's fast winding number
    > ½) and, of them, the largest piece joined by faces. Then, ``rounds`` times, its boundary vertices move towards
    their closest points of the surface and its inner vertices towards the mean of their neighbours, each only as far
    as keeps every tetrahedron around it at a quality (6√2 volume / longest edge³, 1 for a regular tetrahedron) of at
    least ``min_quality``.
    """
    import igl
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    volume = abs(float(np.einsum("ij,ij->", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])))) / 6.0
    h = (6.0 * volume / count) ** (1.0 / 3.0)
    low = V.min(axis=0) - h
    cells = np.ceil((V.max(axis=0) + h - low) / h).astype(int)
    G, T = box_tetrahedra(*cells.tolist(), size=tuple(cells * h))
    G += low
    T = T[np.asarray(igl.fast_winding_number(V, F, G[T].mean(axis=1))) > 0.5]
    faces, index = _faces(T)
    tet = np.repeat(np.arange(len(T)), 4)
    order = np.argsort(index, kind="stable")
    pairs = np.flatnonzero(index[order][1:] == index[order][:-1])  # a face shared by two tetrahedra
    joined = sp.coo_matrix((np.ones(len(pairs)), (tet[order][pairs], tet[order][pairs + 1])), shape=(len(T),) * 2)
    _, labels = connected_components(joined, directed=False)
    T = T[labels == np.argmax(np.bincount(labels))]
    used = np.unique(T)
    renumber = np.full(len(G), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    G, T = G[used], renumber[T]
    faces, index = _faces(T)
    boundary = np.unique(faces[np.bincount(index, minlength=len(faces)) == 1])
    inner = np.setdiff1d(np.arange(len(G)), boundary)
    edges = T[:, [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]]].reshape(-1, 2)
    A = sp.coo_matrix((np.ones(2 * len(edges)), (edges.ravel(), edges[:, ::-1].ravel())), shape=(len(G),) * 2).tocsr()
    A.data[:] = 1.0  # each edge once, however many tetrahedra share it
    A = sp.diags(1.0 / np.asarray(A.sum(axis=1)).ravel()) @ A
    for _ in range(rounds):
        G = _move(G, T, boundary, np.asarray(igl.point_mesh_squared_distance(G[boundary], V, F)[2]), min_quality)
        G = _move(G, T, inner, (A @ G)[inner], min_quality)
    return np.ascontiguousarray(G), np.ascontiguousarray(T, dtype=np.int64)


def cache_folder() -> Path:
    """The benchmarks' folder in the user's cache folder (``~/.cache/arap/benchmarks`` on Linux)."""
    from numba.misc.appdirs import AppDirs  # what numba finds its own cache folder with (see arap.kernels.cache)

    return Path(AppDirs(appname="arap", appauthor=False).user_cache_dir) / "benchmarks"


def scan_tetrahedra(path: Path, count: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`fill_surface` of the scan ``path``, cached in :func:`cache_folder` by file content and ``count``."""
    key = hashlib.sha256(path.read_bytes() + f"|{count}|{SCAN_VERSION}".encode()).hexdigest()[:24]
    cached = cache_folder() / f"scan-{path.stem}-{key}.npz"
    if cached.exists():
        with np.load(cached) as saved:
            return saved["V"], saved["T"]
    t = time.perf_counter()
    V, F = load_mesh(path)
    V_tet, T = fill_surface(np.asarray(V, dtype=np.float64), np.asarray(F, dtype=np.int64), count)
    print(f"  filled {path.name} with {len(T)} tetrahedra in {time.perf_counter() - t:.1f} s (cached in {cached})")
    cached.parent.mkdir(parents=True, exist_ok=True)
    with atomic_output(cached) as out:
        np.savez(out, V=V_tet, T=T)
    return V_tet, T


def scenario(name: str, quick: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """Mesh, constrained vertices, targets and libigl's default iteration count of a scenario."""
    if name == "strip with a hole":
        V, T = rectangle_triangles(40 if quick else 120, 20 if quick else 60, hole=(1.0, 0.5, 0.25))
        angle, iterations = np.pi / 2, 1000
    elif name == "planar 50k":
        V, T = rectangle_triangles(60 if quick else 316, 30 if quick else 158)
        angle, iterations = np.pi / 2, 1000
    elif name == "tet bar 30x6x6":
        V, T = box_tetrahedra(15, 3, 3) if quick else box_tetrahedra(30, 6, 6)
        angle, iterations = 2 * np.pi / 3, 300
    elif name == "tet bar 100k":
        V, T = box_tetrahedra(20, 4, 4) if quick else box_tetrahedra(60, 12, 24)
        angle, iterations = 2 * np.pi / 3, 300
    else:  # "tet scan": the armadillo filled with tetrahedra, feet held, head turned 90° about the vertical
        V, T = scan_tetrahedra(SCAN, SCAN_TETRAHEDRA[quick])
        turned = twist(V, axis=1, share=0.1, angle=np.pi / 2)
        return V, T, turned.constrained, turned.targets, 300
    x = V[:, 0]
    left = np.flatnonzero(x <= x.min() + 1e-9)
    right = np.flatnonzero(x >= x.max() - 1e-9)
    c = V[right].mean(axis=0)
    targets = np.concatenate([V[left], (V[right] - c) @ _rotation(angle, V.shape[1]).T + c])
    return V, T, np.concatenate([left, right]), targets, iterations


def run_igl(V: np.ndarray, T: np.ndarray, b: np.ndarray, bc: np.ndarray, iterations: int) -> dict[str, Any]:
    import igl

    data = igl.ARAPData()
    data.energy = igl.ARAP_ENERGY_TYPE_ELEMENTS
    data.max_iter = iterations
    t = time.perf_counter()
    igl.arap_precomputation(V, T, V.shape[1], b.astype(np.int64), data)
    t_pre = time.perf_counter() - t
    start = V.copy()
    start[b] = bc
    t = time.perf_counter()
    U = np.asarray(igl.arap_solve(bc, data, start))
    return {"precompute_s": t_pre, "solve_s": time.perf_counter() - t, "U": U}


def run_ours(V: np.ndarray, T: np.ndarray, b: np.ndarray, bc: np.ndarray) -> dict[str, Any]:
    t0 = time.perf_counter()
    solver = ArapSolver(V, T, b)
    setup = time.perf_counter() - t0
    times: list[float] = []
    energies: list[float] = []

    def record(iteration: int, energy: float) -> bool:
        times.append(time.perf_counter() - t0)
        energies.append(energy)
        return True

    result = solver.solve(bc, initial="rest", callback=record)
    total = time.perf_counter() - t0
    return {"setup_s": setup, "total_s": total, "times": times, "energies": energies, "U": result.vertices,
            "iterations": result.iterations, "converged": result.converged}


def inverted(V: np.ndarray, T: np.ndarray, U: np.ndarray) -> int:
    lift = (lambda X: np.column_stack([X, np.zeros(len(X))])) if V.shape[1] == 2 else (lambda X: X)
    rest = np.sign(signed_measures(lift(V), T))
    return int(np.count_nonzero(np.sign(signed_measures(lift(U), T)) != rest))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small meshes, for a smoke run")
    parser.add_argument("--igl-iterations", type=int, default=None, help="libigl's iterations (default per scenario)")
    parser.add_argument("--scenarios", nargs="*", default=["strip with a hole", "planar 50k", "tet bar 30x6x6",
                                                            "tet bar 100k", "tet scan"])
    add_json_option(parser, "bench_elements")
    args = parser.parse_args()
    # warm-up: compile the kernels on a tiny problem of each kind
    for name in ("strip with a hole", "tet bar 30x6x6"):
        V, T, b, bc, _ = scenario(name, True)
        ArapSolver(V, T, b).solve(bc, max_iterations=3)
    figures, data = [], {}
    for name in args.scenarios:
        if name == "tet scan" and not SCAN.exists():
            print(f"{name}: skipped, the scan {SCAN} is not there")
            continue
        V, T, b, bc, default_iterations = scenario(name, args.quick)
        iterations = args.igl_iterations or default_iterations
        igl_run = run_igl(V, T, b, bc, iterations)
        ours = run_ours(V, T, b, bc)
        e_igl = arap_energy(V, T, igl_run["U"])
        e_ours = arap_energy(V, T, ours["U"])
        t_igl = igl_run["precompute_s"] + igl_run["solve_s"]
        reached = [k for k, e in enumerate(ours["energies"]) if e <= e_igl]
        t_reach = ours["times"][reached[0]] if reached else float("nan")
        k_reach = reached[0] + 1 if reached else None
        row = {"vertices": len(V), "elements": len(T), "igl_iterations": iterations, "igl_s": t_igl,
               "igl_precompute_s": igl_run["precompute_s"], "igl_energy": e_igl, "arap_energy": e_ours,
               "arap_setup_s": ours["setup_s"], "arap_reach_s": t_reach, "arap_converged_s": ours["total_s"],
               "arap_iterations": ours["iterations"], "arap_converged": ours["converged"],
               "arap_reach_iterations": k_reach, "arap_energy_relative": (e_ours - e_igl) / abs(e_igl),
               "inverted_igl": inverted(V, T, igl_run["U"]), "inverted_arap": inverted(V, T, ours["U"])}
        data[name] = row
        print(f"{name}: {len(V)} vertices, {len(T)} elements")
        print(f"  libigl {iterations} iterations: {t_igl:.2f} s (precompute {igl_run['precompute_s']:.2f} s), "
              f"energy {e_igl:.12g}, inverted {row['inverted_igl']}")
        print(f"  arap: libigl's energy after {k_reach} iterations, {t_reach:.3f} s ({t_igl / t_reach:.1f}× faster), "
              f"converged ({ours['iterations']} iterations) after {ours['total_s']:.3f} s "
              f"({t_igl / ours['total_s']:.1f}× faster), energy {e_ours:.12g} ({row['arap_energy_relative']:+.2e} "
              f"relative to libigl's), inverted {row['inverted_arap']}")
        figures.append(figure(f"elements, {name}: time to libigl's {iterations}-iteration energy", t_reach, "s",
                              "libigl", t_igl))
        figures.append(figure(f"elements, {name}: converged energy", e_ours, "energy", "libigl", e_igl))
        figures.append(figure(f"elements, {name}: inverted elements", row["inverted_arap"], "elements", "libigl",
                              row["inverted_igl"]))
    if args.json:
        write_results(args.json, "bench_elements", figures, data)


if __name__ == "__main__":
    main()
