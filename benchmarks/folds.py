"""Folds of a deformed surface: adjacent faces turned against each other, and dihedral-angle changes.

A pair of faces sharing an edge is *folded* when their unit normals point in nearly opposite directions
(``n₁ · n₂ < −0.5``, a dihedral turn of more than 120°). Real scans have some at rest (thin parts, noise), so a
deformation is judged by the folded pairs it adds to its rest shape's.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from arap.meshes.topology import directed_half_edges

__all__ = [
    "FOLD_THRESHOLD", "adjacent_face_pairs", "dihedral_turns", "folded_pairs", "max_dihedral_change", "unit_normals",
]

FOLD_THRESHOLD = -0.5
"""Two adjacent faces are folded when the dot product of their unit normals is below this."""


def adjacent_face_pairs(F: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Pairs of faces sharing an edge, one row per manifold interior edge.

    Parameters
    ----------
    F : (m, 3) int array

    Returns
    -------
    pairs : (p, 2) int64 array
        Face indices ``(f, g)``, ``f < g``. Boundary edges (one face) and non-manifold edges (more than two) are
        left out.
    edges : (p, 2) int64 array
        The shared edge ``(a, b)``, directed as in face ``f`` (``b`` follows ``a`` counter-clockwise).
    """
    F = np.asarray(F, dtype=np.int64)
    if not len(F):
        return np.zeros((0, 2), dtype=np.int64), np.zeros((0, 2), dtype=np.int64)
    directed = directed_half_edges(F)
    he = np.sort(directed, axis=1)
    base = int(he.max()) + 1
    order = np.argsort(he[:, 0] * base + he[:, 1], kind="stable")
    key = (he[:, 0] * base + he[:, 1])[order]
    _, start, count = np.unique(key, return_index=True, return_counts=True)
    first = order[start[count == 2]]
    second = order[start[count == 2] + 1]
    return np.stack([first // 3, second // 3], axis=1), directed[first]


def unit_normals(V: NDArray[np.float64], F: NDArray[np.int64]) -> NDArray[np.float64]:
    """Unit normal of every face (counter-clockwise orientation), shape (m, 3); zero for zero-area faces."""
    P = np.asarray(V, dtype=np.float64)[np.asarray(F, dtype=np.int64)]
    N = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    length = np.linalg.norm(N, axis=1, keepdims=True)
    return np.divide(N, length, out=np.zeros_like(N), where=length > 0)


def _pair_dots(V: NDArray[np.float64], F: NDArray[np.int64], pairs: NDArray[np.int64] | None) -> NDArray[np.float64]:
    pairs = adjacent_face_pairs(F)[0] if pairs is None else pairs
    N = unit_normals(V, F)
    return np.einsum("ij,ij->i", N[pairs[:, 0]], N[pairs[:, 1]])


def folded_pairs(V: NDArray[np.float64], F: NDArray[np.int64], threshold: float = FOLD_THRESHOLD,
                 pairs: NDArray[np.int64] | None = None) -> int:
    """Number of adjacent face pairs whose unit normals' dot product is below ``threshold``.

    Parameters
    ----------
    V : (n, 3) float array
        Positions (rest or deformed).
    F : (m, 3) int array
    threshold : float
        −0.5 by default: the faces turn by more than 120° against each other.
    pairs : (p, 2) int array or None
        :func:`adjacent_face_pairs` of ``F``, when already computed.

    Returns
    -------
    int
    """
    return int((_pair_dots(V, F, pairs) < threshold).sum())


def dihedral_turns(V: NDArray[np.float64], F: NDArray[np.int64],
                   adjacency: tuple[NDArray[np.int64], NDArray[np.int64]] | None = None) -> NDArray[np.float64]:
    """Signed angle between the normals of every adjacent face pair, in radians.

    0 is flat, positive a convex edge (like a cube's), negative a concave one; ±π is folded flat onto itself.
    Assumes consistently oriented faces.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    adjacency : (pairs, edges) or None
        :func:`adjacent_face_pairs` of ``F``, when already computed.

    Returns
    -------
    (p,) float64 array
        In the order of the pairs.
    """
    V = np.asarray(V, dtype=np.float64)
    pairs, edges = adjacent_face_pairs(F) if adjacency is None else adjacency
    N = unit_normals(V, F)
    nf, ng = N[pairs[:, 0]], N[pairs[:, 1]]
    e = V[edges[:, 1]] - V[edges[:, 0]]
    length = np.linalg.norm(e, axis=1)
    sine = np.einsum("ij,ij->i", np.cross(nf, ng), e) / np.where(length > 0, length, 1.0)
    return np.arctan2(sine, np.einsum("ij,ij->i", nf, ng))


def max_dihedral_change(V: NDArray[np.float64], U: NDArray[np.float64], F: NDArray[np.int64]) -> float:
    """Largest change of a signed dihedral angle from ``V`` to ``U`` (radians, 0 to π), wrapped around ±π.

    Parameters
    ----------
    V : (n, 3) float array
        Rest positions.
    U : (n, 3) float array
        Deformed positions.
    F : (m, 3) int array

    Returns
    -------
    float
        0 for a mesh without interior edges.
    """
    adjacency = adjacent_face_pairs(F)
    if not len(adjacency[0]):
        return 0.0
    d = dihedral_turns(U, F, adjacency) - dihedral_turns(V, F, adjacency)
    return float(np.abs((d + np.pi) % (2 * np.pi) - np.pi).max())
