"""Loose parts that follow: a connected part of the mesh that no constraint reaches moves with the rigid motion of
the constrained surface around it.

A model made of several pieces (the wheels of a car, the buttons of a coat, a separate eye) has pieces that no
anchor or handle touches; their position is undetermined by the energy. Held in place they get left behind when the
body moves; here each such part takes the rigid motion (weighted Procrustes, :func:`arap.meshes._geometry.
best_rigid_transform`) that best maps the rest positions of its *anchors* onto their current positions: for every
vertex of the part, the nearest vertex of the rest of the mesh at rest. A wheel thus turns and moves with the wheel
arch around it, not with the car's far end. The part's own cells stay rigid, so its energy stays zero.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from arap.meshes._geometry import best_rigid_transform

__all__ = ["FollowingParts"]


class FollowingParts:
    """Where the loose parts go for a pose of the rest of the mesh.

    Parameters
    ----------
    rest : (n, 3) float array
        Rest positions (the solver's internal numbering and origin).
    parts : list of int arrays
        The vertices of each loose part (internal numbering).
    others : (k,) int array
        The vertices the parts may follow (those the solve places; internal numbering).

    Example
    -------
    >>> rest = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0.1, 0.1, 0.5]])
    >>> follow = FollowingParts(rest, [np.array([3])], np.array([0, 1, 2]))
    >>> U = rest + [2.0, 0, 0]
    >>> follow.place(U)[3].tolist()
    [2.1, 0.1, 0.5]
    """

    def __init__(self, rest: NDArray[np.float64], parts: list[NDArray[np.int64]], others: NDArray[np.int64]) -> None:
        self._rest = rest
        self._parts: list[tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]] = []
        if not len(others):
            return
        tree = cKDTree(rest[others])
        for part in parts:
            _, nearest = tree.query(rest[part], k=1)
            anchors, counts = np.unique(others[np.asarray(nearest, dtype=np.int64)], return_counts=True)
            self._parts.append((part, anchors, counts.astype(np.float64)))

    def __len__(self) -> int:
        return len(self._parts)

    def place(self, U: NDArray[np.float64]) -> NDArray[np.float64]:
        """``U`` with every loose part moved by the rigid motion of its anchors from rest to ``U``: a new array."""
        out = U.copy()
        for part, anchors, weights in self._parts:
            R, t = best_rigid_transform(self._rest[anchors], U[anchors], weights)
            out[part] = self._rest[part] @ R.T + t
        return out
