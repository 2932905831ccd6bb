"""The puppet warp of a 1000 × 1000 cut-out: time to mesh the picture, to set up and solve the warp, and to draw it,
at about 5,000 and 50,000 vertices; libigl's planar ARAP (elements energy) on the same mesh in the same run.

The picture: a figure (head, body, arms and legs) drawn with NumPy, opaque on a transparent background, with smooth
colour gradients. Five pins (head, hands, feet): one hand raised, one foot moved out, the others hold. arap places
each pin at its point in its triangle (a hard point handle) and solves until converged; libigl constrains vertices,
so its pins are the vertices nearest the pins, and it runs as many iterations as arap took (its ``max_iter``).
Printed: the times, arap's iterations, and the largest distance between the two results.

Run: ``python benchmarks/bench_puppet.py [--quick] [--json OUT]`` (``--quick``: a 300 × 300 picture at about 1,000 and
5,000 vertices).
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

import arap
from arap.puppet.imagemesh import default_spacing
from arap.puppet.warp import PuppetWarp
from benchjson import add_json_option, figure, write_results


def figure_picture(size: int) -> tuple[NDArray[np.uint8], NDArray[np.float64], NDArray[np.float64]]:
    """The cut-out, its pins and their targets (pixel coordinates, scaled with ``size``)."""
    s = size / 1000.0
    y, x = (np.mgrid[0:size, 0:size] + 0.5) / s
    inside = np.hypot(x - 500, y - 180) < 110                                   # head
    inside |= ((x - 500) / 170) ** 2 + ((y - 470) / 220) ** 2 < 1               # body
    inside |= (np.abs(y - 380) < 45) & (np.abs(x - 500) < 430)                  # arms
    inside |= (np.abs(x - 420) < 55) & (y > 550) & (y < 960)                    # legs
    inside |= (np.abs(x - 580) < 55) & (y > 550) & (y < 960)
    img = np.zeros((size, size, 4), dtype=np.uint8)
    img[:, :, 0] = np.rint(127.5 + 100 * np.sin(x / 61.0)).astype(np.uint8)
    img[:, :, 1] = np.rint(127.5 + 100 * np.cos(y / 47.0)).astype(np.uint8)
    img[:, :, 2] = np.rint(127.5 + 100 * np.sin((x + y) / 83.0)).astype(np.uint8)
    img[:, :, 3] = np.where(inside, 255, 0)
    pins = np.array([[500, 180], [100, 380], [900, 380], [420, 930], [580, 930]], dtype=np.float64)
    targets = pins.copy()
    targets[2] = [820, 120]   # the right hand raised
    targets[4] = [700, 880]   # the right foot out
    return img, pins * s, targets * s


def run_igl(V: NDArray[np.float64], F: NDArray[np.int64], pins: NDArray[np.float64],
            targets: NDArray[np.float64], iterations: int) -> dict[str, Any] | None:
    try:
        import igl
    except ImportError:
        return None
    b = np.array([int(np.argmin(np.hypot(*(V - p).T))) for p in pins], dtype=np.int64)
    t0 = time.perf_counter()
    d = igl.ARAPData()
    d.energy = igl.ARAP_ENERGY_TYPE_ELEMENTS
    d.max_iter = max(iterations, 1)
    igl.arap_precomputation(V, F, 2, b, d)
    setup = time.perf_counter() - t0
    t1 = time.perf_counter()
    U = np.asarray(igl.arap_solve(targets, d, V.copy()), dtype=np.float64)
    return {"setup": setup, "solve": time.perf_counter() - t1, "U": U}


def measure(img: NDArray[np.uint8], pins: NDArray[np.float64], targets: NDArray[np.float64],
            vertices: int) -> dict[str, Any]:
    area = float((img[:, :, 3] > 0).sum())
    spacing = float(np.sqrt(2.0 * area / (np.sqrt(3.0) * vertices)))  # a triangular lattice of that many points
    arap.image_mesh(img, spacing)  # a first run loads the modules
    t0 = time.perf_counter()
    mesh = arap.image_mesh(img, spacing)
    t_mesh = time.perf_counter() - t0
    t0 = time.perf_counter()
    puppet = PuppetWarp(img, pins, mesh=mesh)
    t_setup = time.perf_counter() - t0
    assert puppet._solver is not None
    t0 = time.perf_counter()
    result = puppet._solver.solve(mesh.vertices[puppet.held], point_targets=targets)
    t_solve = time.perf_counter() - t0
    U = np.asarray(result.vertices)
    t0 = time.perf_counter()
    puppet.render(U)
    t_draw = time.perf_counter() - t0
    row: dict[str, Any] = {"asked": vertices, "spacing": spacing, "vertices": len(mesh.vertices),
                           "triangles": len(mesh.triangles), "mesh_s": t_mesh, "setup_s": t_setup,
                           "solve_s": t_solve, "iterations": result.iterations, "converged": result.converged,
                           "draw_s": t_draw}
    peer = run_igl(mesh.vertices, mesh.triangles, pins, targets, result.iterations)
    if peer is not None:
        row.update(igl_setup_s=peer["setup"], igl_solve_s=peer["solve"],
                   igl_max_difference_px=float(np.abs(peer["U"] - U).max()))
    return row


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="a 300 x 300 picture at about 1,000 and 5,000 vertices")
    add_json_option(p, "bench_puppet")
    args = p.parse_args(argv)
    from arap.warmup import warm_up_kernels

    warm_up_kernels()
    size, counts = (300, (1000, 5000)) if args.quick else (1000, (5000, 50000))
    img, pins, targets = figure_picture(size)
    PuppetWarp(img, pins, spacing=default_spacing(size, size, 500))(targets)  # compiles the drawing kernel
    print(f"{size}x{size} cut-out ({int((img[:, :, 3] > 0).sum()):,} opaque pixels), 5 pins (2 moved)")
    print(f"{'vertices':>9} {'mesh s':>7} {'setup s':>8} {'solve s':>8} {'iter':>5} {'draw s':>7} "
          f"{'igl setup':>9} {'igl solve':>9} {'igl Δ px':>8}")
    rows, figures = [], []
    for count in counts:
        r = measure(img, pins, targets, count)
        rows.append(r)
        peer = (f"{r['igl_setup_s']:>9.3f} {r['igl_solve_s']:>9.3f} {r['igl_max_difference_px']:>8.2f}"
                if "igl_solve_s" in r else f"{'(libigl not installed)':>28}")
        print(f"{r['vertices']:>9,} {r['mesh_s']:>7.3f} {r['setup_s']:>8.3f} {r['solve_s']:>8.3f} "
              f"{r['iterations']:>5} {r['draw_s']:>7.3f} {peer}")
        n = f"{r['vertices'] / 1000:.0f}k vertices"
        figures.append(figure(f"puppet: mesh a {size}x{size} cut-out, {n}", r["mesh_s"], "s"))
        figures.append(figure(f"puppet: set up and solve, {n}", r["setup_s"] + r["solve_s"], "s",
                              "libigl arap (elements)", r.get("igl_setup_s", 0) + r.get("igl_solve_s", 0)
                              if "igl_solve_s" in r else None))
    if args.json is not None:
        write_results(args.json, "bench_puppet", figures, rows)


if __name__ == "__main__":
    main()
