"""Textured GLB in and out: arap.load_asset + save_asset against trimesh's own load + export, in the same run.

The model is a ~1M-vertex textured surface written by trimesh itself (a wavy sphere-like grid with a UV seam,
per-vertex normals and an embedded PNG texture), so that both readers see a file from the same common exporter.

Timed, best of ``--repeats``:

- ``arap load``: ``load_asset`` (JSON, accessors, scene transforms, UVs);
- ``arap solve mesh``: ``asset.solve_mesh()`` (welding the seam copies), shown apart: it is what a solve adds;
- ``arap save``: ``save_asset`` with new positions (positions and bounds rewritten, normals recomputed per normal
  group, everything else copied);
- ``trimesh load``: ``trimesh.load`` with its defaults (which merges vertices) and with ``process=False``;
- ``trimesh export``: ``scene.export(file_type="glb")``.

Run: ``python benchmarks/bench_assets.py [--vertices 1000000] [--repeats 3] [--quick]`` (``--quick``: 2,000 vertices,
one run: a check that it runs, not a measurement)
"""

from __future__ import annotations

import argparse
import io
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import trimesh
from PIL import Image

from arap.io import load_asset, save_asset
from benchjson import add_json_option, figure, write_results


def textured_surface(vertices: int) -> trimesh.Trimesh:
    """A closed-in-longitude grid of about ``vertices`` vertices: the seam column is duplicated (its UVs differ)."""
    rows = max(3, int(np.sqrt(vertices / 2)))
    cols = max(4, vertices // rows)
    u = np.linspace(0.0, 1.0, cols)  # u = 0 and u = 1 coincide in space: a UV seam
    v = np.linspace(0.05, 0.95, rows)
    U, W = np.meshgrid(u, v)
    theta, phi = 2 * np.pi * U, np.pi * W
    radius = 1.0 + 0.05 * np.sin(8 * theta) * np.sin(6 * phi)
    V = np.stack([radius * np.sin(phi) * np.cos(theta), radius * np.sin(phi) * np.sin(theta), radius * np.cos(phi)],
                 axis=-1).reshape(-1, 3)
    V[(np.arange(rows)[:, None] * cols + cols - 1).ravel()] = V[(np.arange(rows)[:, None] * cols).ravel()]
    i, j = np.meshgrid(np.arange(rows - 1), np.arange(cols - 1), indexing="ij")
    a = (i * cols + j).ravel()
    F = np.concatenate([np.stack([a, a + 1, a + cols + 1], axis=1), np.stack([a, a + cols + 1, a + cols], axis=1)])
    image = Image.fromarray(np.random.default_rng(0).integers(0, 256, (256, 256, 3), dtype=np.uint8))
    uv = np.stack([U.ravel(), W.ravel()], axis=1)
    mesh = trimesh.Trimesh(V, F, visual=trimesh.visual.TextureVisuals(uv=uv, image=image), process=False)
    mesh.vertex_normals  # noqa: B018 - computed so that the exporter writes them
    return mesh


def best(fn: Callable[[], Any], repeats: int) -> tuple[float, Any]:
    times, out = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vertices", type=int, default=1_000_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="2,000 vertices, one run")
    add_json_option(parser, "bench_assets")
    args = parser.parse_args(argv)
    if args.quick:
        args.vertices, args.repeats = 2000, 1
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        path = folder / "model.glb"
        path.write_bytes(textured_surface(args.vertices).export(file_type="glb"))
        size = path.stat().st_size

        t_load, asset = best(lambda: load_asset(path), args.repeats)
        t_weld, solve = best(lambda: (setattr(asset, "_solve", None), asset.solve_mesh())[1], args.repeats)
        moved = solve.V * 1.01 + 0.01 * np.sin(solve.V[:, [1, 2, 0]] * 5)
        t_save, _ = best(lambda: save_asset(folder / "out.glb", asset, moved), args.repeats)
        t_tm_load, scene = best(lambda: trimesh.load(path), args.repeats)
        t_tm_raw, _ = best(lambda: trimesh.load(path, process=False), args.repeats)
        t_tm_export, _ = best(lambda: scene.export(file_type="glb"), args.repeats)
        out = load_asset(folder / "out.glb")
        assert np.array_equal(out.uvs, asset.uvs) and out.textures == asset.textures

    image = next(iter(asset.textures.values()))
    Image.open(io.BytesIO(image)).verify()
    print(f"model: {len(asset.vertices):,} vertices ({len(solve.V):,} once the seam is welded), "
          f"{len(asset.faces):,} triangles, {size / 1e6:.1f} MB GLB with a {len(image) / 1e3:.0f} kB texture")
    print(f"{'step':<34}{'seconds':>10}")
    rows = [("arap load_asset", t_load), ("arap solve_mesh (weld seams)", t_weld), ("arap save_asset (new positions)",
                                                                                    t_save),
            ("trimesh.load (defaults)", t_tm_load), ("trimesh.load (process=False)", t_tm_raw),
            ("trimesh export glb", t_tm_export)]
    for name, t in rows:
        print(f"{name:<34}{t:>10.3f}")
    ours = t_load + t_save
    theirs = t_tm_load + t_tm_export
    print(f"\nload + save: arap {ours:.3f} s, trimesh {theirs:.3f} s (defaults): ratio {ours / theirs:.2f}x; "
          f"against trimesh with process=False: {ours / (t_tm_raw + t_tm_export):.2f}x")
    print(f"with the weld a solve needs: {(ours + t_weld) / theirs:.2f}x")
    if args.json:
        write_results(args.json, "bench_assets", [
            figure(f"GLB load + save, {len(asset.vertices):,} vertices", ours, "s", "trimesh (defaults)", theirs),
            figure("GLB load + save", ours, "s", "trimesh (process=False)", t_tm_raw + t_tm_export),
            figure("GLB load + weld + save", ours + t_weld, "s", "trimesh (defaults)", theirs),
        ], {"vertices": len(asset.vertices), "welded_vertices": len(solve.V), "triangles": len(asset.faces),
            "glb_bytes": size, "seconds": dict(rows)})


if __name__ == "__main__":
    main()
