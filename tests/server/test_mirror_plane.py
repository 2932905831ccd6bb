"""The studio's mirror-plane finder (``web/src/symmetry.js``, run by Node): on generated shapes with one mirror
plane, turned and moved, it finds that plane and pairs each vertex with its mirror image, exact or with scan-like
noise; and its work (the distances its nearest-point queries compute) stays within a bound in n log n."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from arap.meshes.shapes import sphere

pytestmark = [pytest.mark.timeout(300),
              pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")]

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = """
import { readFileSync } from 'node:fs';
import { detectSymmetry } from %s;
const mesh = JSON.parse(readFileSync(0, 'utf8'));
const found = detectSymmetry(new Float32Array(mesh.V), new Uint32Array(mesh.F), 'auto');
console.log(JSON.stringify({ plane: found.plane, matched: found.matched, work: found.work,
  mirrorOf: found.mirrorOf ? Array.from(found.mirrorOf) : null }));
"""

WORK_PER_VERTEX_LOG = 40
"""Bound of the work of pairing every vertex: distances computed per vertex and per log2 of the vertex count."""
SAMPLE_WORK = 10_000_000
"""Bound of the work of choosing the plane (candidate planes scored and refined on a sample of the vertices, the same
size whatever the mesh's). The finder computes 7.6, 9.5 and 13.8 million distances in all on the exact shapes of
4k, 16k and 36k vertices (17 million on the 43k-vertex armadillo); the grid hashes it used before computed 75, 70 and
82 million (126 million)."""


def _shape(frequency: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A lumpy closed shape mirror-symmetric about the plane x = 0 only; its vertices, triangles and each vertex's
    mirror image."""
    V, F = sphere(frequency=frequency)
    x, y, z = V.T
    W = np.column_stack([1.3 * x, 0.8 * y + 0.25 * z**2 + 0.1 * x**2, 0.55 * z + 0.2 * y + 0.15 * y**2])
    mirrored = W * [-1.0, 1.0, 1.0]
    distance, partner = cKDTree(W).query(mirrored)
    assert distance.max() < 1e-9  # the sphere's vertices mirror each other across x = 0
    return W, F, partner


def _detect(V: np.ndarray, F: np.ndarray, tmp_path: Path) -> dict[str, Any]:
    module = tmp_path / "detect.mjs"
    module.write_text(SCRIPT % json.dumps((ROOT / "web" / "src" / "symmetry.js").as_uri()))
    done = subprocess.run(["node", str(module)], input=json.dumps({"V": V.ravel().tolist(), "F": F.ravel().tolist()}),
                          capture_output=True, text=True, timeout=240, check=False)
    assert done.returncode == 0, done.stderr
    result: dict[str, Any] = json.loads(done.stdout)
    return result


@pytest.mark.parametrize(("frequency", "noise"), [(20, 0.0), (40, 0.0), (40, 0.002)])
def test_the_mirror_plane_of_a_turned_shape_is_found_and_its_vertices_paired(frequency: int, noise: float,
                                                                             tmp_path: Path) -> None:
    W, F, partner = _shape(frequency)
    rng = np.random.default_rng(frequency)
    turn = Rotation.random(random_state=frequency)
    diag = float(np.linalg.norm(W.max(axis=0) - W.min(axis=0)))
    shift = np.array([3.0, -1.0, 0.5])
    V = turn.apply(W + noise * diag * rng.standard_normal(W.shape)) + shift
    found = _detect(V, F, tmp_path)
    assert found["plane"] is not None, found["matched"]
    normal = np.asarray(found["plane"]["normal"])
    expected = turn.apply([1.0, 0.0, 0.0])
    assert abs(normal @ expected) > math.cos(math.radians(0.5 if noise else 0.2)), (normal, expected)
    # the plane passes through the turned and moved origin of the shape
    assert abs((np.asarray(found["plane"]["point"]) - shift) @ expected) < 1e-3 * diag
    mirror_of = np.asarray(found["mirrorOf"])
    assert found["matched"] > (0.97 if noise else 0.999)
    assert np.mean(mirror_of == partner) > (0.5 if noise else 0.999)
    paired = mirror_of >= 0  # a partner other than the exact image is a neighbour of it, where the noise moved it
    assert np.linalg.norm(V[mirror_of[paired]] - V[partner[paired]], axis=1).max() < 0.05 * diag

    n = len(V)
    assert found["work"] <= SAMPLE_WORK + WORK_PER_VERTEX_LOG * n * math.log2(n), found["work"]
