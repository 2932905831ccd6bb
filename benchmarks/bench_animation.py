"""Keyframe animation: frames solved per second by default (the frames between keyframes to
``arap.animation.FRAME_TOLERANCE``) against ``exact`` (every frame to convergence, as ``arap animate --exact``), in
the same run, and how far the default's frames are from the exact ones, as a fraction of the bounding-box diagonal.

The animation: the lowest 10% of the vertices (along y) held, the highest 10% a handle group that turns 60° about a
horizontal axis through its centroid over the first half and back over the second, given as three ``transforms``
keyframes (so the handles turn about their pivot by slerp); every frame starts from the previous one. Meshes: the
built-in cactus, and the armadillo (``../shared/meshes/armadillo.obj``) when it is there, or those given with
``--mesh``. Each mode gets a solver of its own; the factorisation is not counted.

Run: ``python benchmarks/bench_animation.py [--mesh M ...] [--fps 30] [--seconds 2] [--quick] [--json OUT]``
(``--quick``: the cactus alone, 1 s at 10 fps: a check that it runs, not a measurement).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np

import arap
from arap.animation import FRAME_TOLERANCE, animate
from arap.meshes.shapes import BUILTIN_MESHES
from benchjson import add_json_option, figure, write_results

DEFAULT_MESH = Path(__file__).resolve().parents[2] / "shared" / "meshes" / "armadillo.obj"
BUILTIN = "cactus"


def keyframes(V: np.ndarray, seconds: float) -> dict[str, Any]:
    """The turn and back: three ``transforms`` keyframes at 0, ``seconds / 2`` and ``seconds``."""
    y = V[:, 1]
    fixed = np.flatnonzero(y <= np.quantile(y, 0.1))
    top = np.flatnonzero(y >= np.quantile(y, 0.9))
    pivot = V[top].mean(axis=0)
    a = np.radians(60.0)
    R = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]])
    turned = np.eye(4)
    turned[:3, :3] = R
    turned[:3, 3] = pivot - R @ pivot
    return {"fixed": fixed.tolist(), "handles": top.tolist(),
            "keyframes": [{"time": 0.0, "transforms": [np.eye(4).tolist()]},
                          {"time": seconds / 2, "transforms": [turned.tolist()]},
                          {"time": seconds, "transforms": [np.eye(4).tolist()]}]}


def load(spec: str) -> tuple[str, np.ndarray, np.ndarray]:
    if spec in BUILTIN_MESHES:
        V, F = arap.builtin_mesh(spec)
        return spec, V, F
    V, F = arap.load_mesh(spec)
    return Path(spec).name, V, F


def measure(spec: str, fps: float, seconds: float) -> dict[str, Any]:
    """Both modes on one mesh: frames per second, iterations, and the default's distance from the exact frames."""
    name, V, F = load(spec)
    diag = float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))
    doc = keyframes(V, seconds)
    runs = {}
    for mode in ("exact", "default"):
        t0 = time.perf_counter()
        anim = animate(V, F, doc, fps=fps, exact=mode == "exact")
        wall = time.perf_counter() - t0 - anim.setup_seconds
        runs[mode] = anim, wall
    (exact, exact_wall), (fast, fast_wall) = runs["exact"], runs["default"]
    between = ~fast.at_key if fast.at_key is not None else np.ones(len(fast.times), dtype=bool)
    distance = np.linalg.norm(fast.vertices - exact.vertices, axis=2).max(axis=1) / diag
    frames = len(fast.times)
    return {
        "mesh": name, "vertices": len(V), "frames": frames, "fps": fps, "seconds": seconds,
        "frame_tolerance": FRAME_TOLERANCE,
        "exact": {"seconds": exact_wall, "frames_per_second": frames / exact_wall,
                  "iterations_between_keys": float(exact.iterations[between].mean()) if between.any() else 0.0,
                  "iterations": int(exact.iterations.sum())},
        "default": {"seconds": fast_wall, "frames_per_second": frames / fast_wall,
                    "iterations_between_keys": float(fast.iterations[between].mean()) if between.any() else 0.0,
                    "iterations": int(fast.iterations.sum())},
        "largest_distance_diagonals": float(distance.max()),
        "mean_largest_distance_diagonals": float(distance[between].mean()) if between.any() else 0.0,
    }


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--mesh", action="append", default=None,
                   help=f"a mesh file or built-in name (repeatable; default: {BUILTIN} and the armadillo when present)")
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--seconds", type=float, default=2.0)
    p.add_argument("--quick", action="store_true", help=f"{BUILTIN} alone, 1 s at 10 fps")
    add_json_option(p, "bench_animation")
    args = p.parse_args(argv)
    from arap.warmup import warm_up_kernels

    warm_up_kernels()
    if args.quick:
        meshes, args.fps, args.seconds = [BUILTIN], 10.0, 1.0
    else:
        meshes = args.mesh or [BUILTIN, *([str(DEFAULT_MESH)] if DEFAULT_MESH.exists() else [])]
    results = []
    figures = []
    for spec in meshes:
        r = measure(spec, args.fps, args.seconds)
        results.append(r)
        e, d = r["exact"], r["default"]
        print(f"{r['mesh']}: {r['vertices']:,} vertices, {r['frames']} frames ({args.seconds:g} s at {args.fps:g} fps)")
        print(f"  every frame to convergence (--exact): {e['seconds']:.2f} s, {e['frames_per_second']:.2f} frames/s, "
              f"{e['iterations_between_keys']:.0f} iterations a frame between keys")
        print(f"  default (between keys to {FRAME_TOLERANCE:g}):    {d['seconds']:.2f} s, "
              f"{d['frames_per_second']:.2f} frames/s, {d['iterations_between_keys']:.0f} iterations a frame between "
              f"keys: {d['frames_per_second'] / e['frames_per_second']:.2f}× the frames/s")
        print(f"  default's frames from the exact ones: at most {r['largest_distance_diagonals']:.2e} of the diagonal "
              f"(largest vertex distance; {r['mean_largest_distance_diagonals']:.2e} on average between keys)")
        figures += [
            figure(f"frames per second, {r['mesh']}, default (between keys to {FRAME_TOLERANCE:g})",
                   d["frames_per_second"], "frames/s", "every frame to convergence (--exact)", e["frames_per_second"],
                   better="higher"),
            figure(f"largest distance of the default's frames from converged ones, {r['mesh']}",
                   r["largest_distance_diagonals"], "diagonals"),
        ]
    if args.json:
        write_results(args.json, "bench_animation", figures, {"meshes": results, "quick": args.quick})


if __name__ == "__main__":
    main()
