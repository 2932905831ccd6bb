"""Geodesic (icosahedral) spheres of any size: the benchmark meshes from 12 vertices to 20 million.

Each face of an icosahedron is split into ``k²`` triangles (``k`` the frequency) and the points are projected on the
sphere, so the triangles are nearly equilateral at every size.
"""

from __future__ import annotations

import numpy as np

from arap.errors import OptionError

__all__ = ["MAX_SPHERE_VERTICES", "sphere", "sphere_frequency_for"]

MAX_SPHERE_VERTICES = 20_000_000
"""Largest sphere :func:`sphere` builds (about 4 GB of arrays and more to solve on it)."""

_PHI = (1.0 + 5.0 ** 0.5) / 2.0
_ICO_V = np.array([
    [-1, _PHI, 0], [1, _PHI, 0], [-1, -_PHI, 0], [1, -_PHI, 0],
    [0, -1, _PHI], [0, 1, _PHI], [0, -1, -_PHI], [0, 1, -_PHI],
    [_PHI, 0, -1], [_PHI, 0, 1], [-_PHI, 0, -1], [-_PHI, 0, 1],
])
_ICO_F = np.array([
    [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6],
    [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10],
    [8, 6, 7], [9, 8, 1],
])


def sphere_frequency_for(n_vertices: int) -> int:
    """Geodesic frequency whose sphere has about ``n_vertices`` vertices (``10 k² + 2``)."""
    return max(1, round(((max(n_vertices, 12) - 2) / 10.0) ** 0.5))


def sphere(subdivisions: int = 4, *, frequency: int | None = None, radius: float = 1.0
           ) -> tuple[np.ndarray, np.ndarray]:
    """Geodesic (icosahedral) sphere: each icosahedron face split into ``k²`` triangles, projected on the sphere.

    Parameters
    ----------
    subdivisions : int
        ``k = 2**subdivisions``, giving the vertex count of the classic icosphere: 10 · 4^s + 2 (s = 5: 10,242;
        s = 7: 163,842; s = 8: 655,362).
    frequency : int or None
        Use this ``k`` instead (any size: ``10 k² + 2`` vertices; k = 316 gives 998,562).
    radius : float

    Returns
    -------
    V : (10 k² + 2, 3) float64 array
    F : (20 k², 3) int64 array
        Counter-clockwise seen from outside.

    Raises
    ------
    OptionError
        ``k < 1``, or more than :data:`MAX_SPHERE_VERTICES` vertices.

    Examples
    --------
    >>> import arap
    >>> V, F = arap.sphere(1)                                  # an icosahedron subdivided once
    >>> V.shape, F.shape
    ((42, 3), (80, 3))
    """
    k = int(frequency) if frequency is not None else 2 ** int(subdivisions)
    if k < 1:
        raise OptionError(f"sphere frequency must be >= 1, got {k}")
    if 10 * k * k + 2 > MAX_SPHERE_VERTICES:
        raise OptionError(f"a sphere of frequency {k} would have {10 * k * k + 2:,} vertices, more than "
                          f"{MAX_SPHERE_VERTICES:,}")
    edges = {tuple(sorted((int(f[i]), int(f[(i + 1) % 3])))) for f in _ICO_F for i in range(3)}
    edge_index = {e: i for i, e in enumerate(sorted(edges))}
    n_edge_pts = k - 1
    n_inner = (k - 1) * (k - 2) // 2
    base_inner = 12 + len(edge_index) * n_edge_pts
    n_total = base_inner + 20 * n_inner
    V = np.zeros((n_total, 3))
    V[:12] = _ICO_V

    i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
    valid = i + j <= k
    i, j = i[valid], j[valid]
    w = np.stack([k - i - j, i, j], axis=1)  # weights on the corners (A, B, C)
    local = -np.ones((k + 1, k + 1), dtype=np.int64)
    tri_up = np.stack([np.stack([i, j], 1), np.stack([i + 1, j], 1), np.stack([i, j + 1], 1)], 1)
    up = (i + j) < k
    down = (i + j) < k - 1
    tri_dn = np.stack([np.stack([i + 1, j], 1), np.stack([i + 1, j + 1], 1), np.stack([i, j + 1], 1)], 1)
    faces: list[np.ndarray] = []
    for f, corners in enumerate(_ICO_F):
        ids = np.empty(len(i), dtype=np.int64)
        nonzero = (w > 0).sum(axis=1)
        corner = nonzero == 1
        ids[corner] = corners[np.argmax(w[corner], axis=1)]
        on_edge = nonzero == 2
        if on_edge.any():
            we = w[on_edge]
            pair = np.sort(np.where(we > 0, corners[None, :], -1), axis=1)[:, 1:]  # the two corners used
            e = np.array([edge_index[(int(p), int(q))] for p, q in pair])
            w_hi = np.where(corners[None, :] == pair[:, 1:2], we, 0).sum(axis=1)
            ids[on_edge] = 12 + e * n_edge_pts + (w_hi - 1)
        inner = nonzero == 3
        ids[inner] = base_inner + f * n_inner + np.arange(int(inner.sum()))
        V[ids] = (w @ _ICO_V[corners]) / k
        local[i, j] = ids
        faces.append(local[tri_up[up, :, 0], tri_up[up, :, 1]])
        faces.append(local[tri_dn[down, :, 0], tri_dn[down, :, 1]])
    V *= radius / np.linalg.norm(V, axis=1, keepdims=True)
    return V, np.concatenate(faces)
