"""Tetrahedral meshes for the tests: a box of cubes, each split into six tetrahedra."""

from __future__ import annotations

import numpy as np

__all__ = ["tet_box"]

#: The six tetrahedra of a cube around its diagonal from corner 0 to corner 7 (corner ``i`` at the bits of ``i``:
#: x = bit 0, y = bit 1, z = bit 2), each positively oriented.
_CUBE_TETS = np.array([[0, 1, 3, 7], [0, 3, 2, 7], [0, 2, 6, 7], [0, 6, 4, 7], [0, 4, 5, 7], [0, 5, 1, 7]])


def tet_box(nx: int = 1, ny: int = 1, nz: int = 1, size: tuple[float, float, float] | None = None
            ) -> tuple[np.ndarray, np.ndarray]:
    """A box of ``nx × ny × nz`` cubes, each cut into 6 tetrahedra of positive volume (shared faces match).

    Parameters
    ----------
    size : (3,) floats or None
        The box's extent (default: one unit per cube), its corner at the origin.

    Returns
    -------
    V : ((nx + 1)(ny + 1)(nz + 1), 3) float64 array
    T : (6 nx ny nz, 4) int64 array
    """
    extent = np.array(size if size is not None else (nx, ny, nz), dtype=np.float64)
    i, j, k = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), np.arange(nz + 1), indexing="ij")
    V = np.column_stack([i.ravel() / nx, j.ravel() / ny, k.ravel() / nz]) * extent
    index = np.arange(len(V)).reshape(nx + 1, ny + 1, nz + 1)
    ci, cj, ck = (a.ravel() for a in np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"))
    corners = np.stack([index[ci + (c & 1), cj + ((c >> 1) & 1), ck + ((c >> 2) & 1)] for c in range(8)], axis=1)
    T = corners[:, _CUBE_TETS].reshape(-1, 4)
    return V, T.astype(np.int64)
