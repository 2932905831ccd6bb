"""Structured element meshes: a rectangle of triangles in the plane (optionally with a round hole) and a box of
tetrahedra, for examples, tests and benchmarks of the element energy (:mod:`arap.method.elements`).

Both are consistently oriented (counter-clockwise triangles, positive tetrahedra) and their vertices are numbered
row by row, so constraints can be picked by position (``V[:, 0] < …``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from arap.errors import ArapError

__all__ = ["box_tetrahedra", "rectangle_triangles"]


def rectangle_triangles(nx: int, ny: int, size: tuple[float, float] = (2.0, 1.0),
                        hole: tuple[float, float, float] | None = None) -> tuple[NDArray[np.float64],
                                                                                NDArray[np.int64]]:
    """A planar rectangle of ``nx × ny`` squares, each cut into two triangles along alternating diagonals.

    Parameters
    ----------
    nx, ny : int
        Squares along x and y (≥ 1).
    size : (2,) floats
        Width and height.
    hole : (cx, cy, r) or None
        A round hole: triangles whose centroid lies within ``r`` of ``(cx, cy)`` are left out, and the vertices they
        leave unused are dropped.

    Returns
    -------
    V : (n, 2) float64 array
    F : (m, 3) int64 array
        Counter-clockwise triangles.

    Example
    -------
    >>> V, F = rectangle_triangles(4, 2)
    >>> V.shape, F.shape
    ((15, 2), (16, 3))
    """
    if nx < 1 or ny < 1:
        raise ArapError(f"a rectangle needs at least one square each way, got {nx} × {ny}")
    x, y = np.meshgrid(np.linspace(0.0, size[0], nx + 1), np.linspace(0.0, size[1], ny + 1), indexing="ij")
    V = np.column_stack([x.ravel(), y.ravel()])
    idx = np.arange((nx + 1) * (ny + 1)).reshape(nx + 1, ny + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    flip = ((np.arange(nx)[:, None] + np.arange(ny)[None, :]) % 2).astype(bool)
    first = np.where(flip[..., None], np.stack([a, b, d], -1), np.stack([a, b, c], -1)).reshape(-1, 3)
    second = np.where(flip[..., None], np.stack([b, c, d], -1), np.stack([a, c, d], -1)).reshape(-1, 3)
    F = np.concatenate([first, second])
    if hole is not None:
        cx, cy, r = hole
        centre = V[F].mean(axis=1)
        F = F[np.hypot(centre[:, 0] - cx, centre[:, 1] - cy) > r]
        used = np.zeros(len(V), dtype=bool)
        used[F.ravel()] = True
        new = np.cumsum(used) - 1
        V, F = V[used], new[F]
    return np.ascontiguousarray(V), np.ascontiguousarray(F, dtype=np.int64)


def box_tetrahedra(nx: int, ny: int, nz: int, size: tuple[float, float, float] | None = None
                   ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """A box of ``nx × ny × nz`` cubes, each cut into six tetrahedra around its main diagonal.

    Parameters
    ----------
    nx, ny, nz : int
        Cubes along each axis (≥ 1).
    size : (3,) floats or None
        The box's extent (None: unit cubes).

    Returns
    -------
    V : (n, 3) float64 array
    T : (6 nx ny nz, 4) int64 array
        Positively oriented tetrahedra; neighbouring cubes share their faces' diagonals, so the mesh is conforming.

    Example
    -------
    >>> V, T = box_tetrahedra(3, 1, 1)
    >>> V.shape, T.shape
    ((16, 3), (18, 4))
    """
    if min(nx, ny, nz) < 1:
        raise ArapError(f"a box needs at least one cube each way, got {nx} × {ny} × {nz}")
    extent = np.array([nx, ny, nz], dtype=np.float64) if size is None else np.asarray(size, dtype=np.float64)
    axes = [np.linspace(0.0, extent[k], count + 1) for k, count in enumerate((nx, ny, nz))]
    g = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    idx = np.arange(len(g)).reshape(nx + 1, ny + 1, nz + 1)
    offsets = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    corner = np.stack([idx[i:i + nx, j:j + ny, k:k + nz].ravel() for i, j, k in offsets], axis=1)
    ring = [(1, 2), (2, 3), (3, 7), (7, 4), (4, 5), (5, 1)]  # around the diagonal from corner 0 to corner 6
    T = np.concatenate([np.stack([corner[:, 0], corner[:, p], corner[:, q], corner[:, 6]], axis=1)
                        for p, q in ring])
    e1, e2, e3 = (g[T[:, i]] - g[T[:, 0]] for i in (1, 2, 3))
    negative = np.einsum("ij,ij->i", np.cross(e1, e2), e3) < 0
    T[negative] = T[negative][:, [0, 2, 1, 3]]
    return np.ascontiguousarray(g), np.ascontiguousarray(T, dtype=np.int64)
