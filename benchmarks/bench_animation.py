"""Keyframe animation: frames solved per second for a 2 s, 30 fps animation, and the first frame against the
others (each frame starts from the previous one; the first from the rest pose).

The animation (default mesh: the armadillo): the lowest 10% of the vertices along y held, the highest 10% a handle
group that turns 60° about a horizontal axis through its centroid over the first second and back over the next,
given as three ``transforms`` keyframes (so the handles turn about their pivot by slerp). For comparison, the same
frames are solved each from a cold start (``initial="auto"``), as a loop of ``arap deform`` calls would.

Run: ``python benchmarks/bench_animation.py [--mesh PATH] [--fps 30] [--seconds 2] [--json OUT]``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np

import arap
from arap.animation import frame_times, iter_frames, load_keyframes
from benchjson import add_json_option, figure, write_results

DEFAULT_MESH = Path(__file__).resolve().parents[2] / "shared" / "meshes" / "armadillo.obj"


def keyframes(V: np.ndarray, seconds: float) -> dict[str, Any]:
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


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--mesh", type=Path, default=DEFAULT_MESH)
    p.add_argument("--fps", type=float, default=30.0)
    p.add_argument("--seconds", type=float, default=2.0)
    add_json_option(p, "bench_animation")
    args = p.parse_args(argv)
    from arap.method.jit import warm_up_kernels

    warm_up_kernels()
    V, F = arap.load_mesh(args.mesh)
    keys = load_keyframes(keyframes(V, args.seconds), V)
    times = frame_times(keys, args.fps)
    c = keys.constraints
    t0 = time.perf_counter()
    solver = arap.ArapSolver(V, F, c.constrained)
    setup = time.perf_counter() - t0
    warm: list[tuple[float, int]] = []
    t0 = time.perf_counter()
    for _, result in iter_frames(solver, keys, V, times):
        warm.append((result.timings["total"], result.iterations))
    warm_total = time.perf_counter() - t0
    cold: list[tuple[float, int]] = []
    t0 = time.perf_counter()
    for t in times:
        targets = np.concatenate([V[c.fixed], keys.handle_targets(float(t))])
        result = solver.solve(targets, initial="auto")
        cold.append((result.timings["total"], result.iterations))
    cold_total = time.perf_counter() - t0
    w = np.array(warm)
    k = np.array(cold)
    figures = {"mesh": args.mesh.name, "vertices": len(V), "frames": len(times), "fps": args.fps,
               "setup_seconds": setup,
               "warm": {"seconds": warm_total, "frames_per_second": len(times) / warm_total,
                        "first_frame_ms": 1e3 * w[0, 0], "other_frames_ms": 1e3 * w[1:, 0].mean(),
                        "first_frame_iterations": int(w[0, 1]), "other_frames_iterations": float(w[1:, 1].mean())},
               "cold": {"seconds": cold_total, "frames_per_second": len(times) / cold_total,
                        "frame_ms": 1e3 * k[:, 0].mean(), "iterations": float(k[:, 1].mean())}}
    print(f"{args.mesh.name}: {len(V):,} vertices, {len(times)} frames ({args.seconds:g} s at {args.fps:g} fps), "
          f"set-up {setup:.2f} s")
    print(f"  each frame from the previous: {warm_total:.2f} s, {len(times) / warm_total:.1f} frames/s; first frame "
          f"{1e3 * w[0, 0]:.0f} ms ({int(w[0, 1])} iterations), the others {1e3 * w[1:, 0].mean():.0f} ms "
          f"({w[1:, 1].mean():.0f} iterations) on average")
    print(f"  each frame from a cold start:  {cold_total:.2f} s, {len(times) / cold_total:.1f} frames/s; "
          f"{1e3 * k[:, 0].mean():.0f} ms ({k[:, 1].mean():.0f} iterations) on average")
    if args.json:
        write_results(args.json, "bench_animation", [
            figure(f"frames per second, {args.mesh.name}, each frame from the previous", len(times) / warm_total,
                   "frames/s", "each frame from a cold start", len(times) / cold_total, better="higher"),
            figure(f"ms per frame, {args.mesh.name}, each frame from the previous", 1e3 * w[1:, 0].mean(), "ms",
                   "each frame from a cold start", 1e3 * k[:, 0].mean()),
        ], figures)


if __name__ == "__main__":
    main()
