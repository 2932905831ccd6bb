"""Combinatorial structure of a triangle mesh: edges, boundary, adjacency and connected components."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components as _cc
from scipy.sparse.csgraph import reverse_cuthill_mckee

from arap._csr import csr_from_face_edges


def directed_half_edges(F: np.ndarray) -> np.ndarray:
    """Half-edges of every face, in face order.

    Parameters
    ----------
    F : (m, 3) int array
        Triangle indices.

    Returns
    -------
    (3m, 2) int64 array
        Rows ``(F[f, k], F[f, (k+1) % 3])`` for k = 0, 1, 2, face after face.
    """
    F = np.asarray(F, dtype=np.int64)
    return np.stack([F, np.roll(F, -1, axis=1)], axis=2).reshape(-1, 2)


def unique_edges(F: np.ndarray) -> np.ndarray:
    """Undirected edges of the mesh, each once, as sorted pairs.

    Parameters
    ----------
    F : (m, 3) int array

    Returns
    -------
    (e, 2) int64 array
        Edges ``(i, j)`` with ``i < j``, sorted lexicographically.
    """
    return edge_face_counts(F)[0]


def edge_face_counts(F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Undirected edges with the number of faces using each.

    Returns
    -------
    edges : (e, 2) int64 array
    counts : (e,) int64 array
        1 for boundary edges, 2 for interior manifold edges, more for non-manifold edges.
    """
    he = np.sort(directed_half_edges(F), axis=1)
    if not len(he):
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0, dtype=np.int64)
    # One int64 key per edge sorts far faster than rows of a 2-D array.
    base = int(he.max()) + 1
    keys, counts = np.unique(he[:, 0] * base + he[:, 1], return_counts=True)
    return np.stack([keys // base, keys % base], axis=1), counts


def boundary_edges(F: np.ndarray) -> np.ndarray:
    """Edges used by exactly one face, shape (b, 2)."""
    edges, counts = edge_face_counts(F)
    return edges[counts == 1]


def vertex_adjacency(F: np.ndarray, n: int) -> sp.csr_matrix:
    """Symmetric 0/1 vertex adjacency matrix (no self loops), shape (n, n)."""
    A = csr_from_face_edges(np.asarray(F, dtype=np.int64), n)
    M = sp.csr_matrix((np.ones(A.nnz, dtype=np.int8), A.indices, A.indptr), shape=(n, n))
    M.has_sorted_indices = True
    return M


def connected_components(F: np.ndarray, n: int) -> tuple[int, np.ndarray]:
    """Connected components of the vertex graph.

    Returns
    -------
    count : int
        Number of components (isolated vertices count as components of their own).
    labels : (n,) int array
        Component label of every vertex.
    """
    count, labels = _cc(vertex_adjacency(F, n), directed=False)
    return int(count), labels


def locality_order(F: np.ndarray, n: int, adjacency: sp.csr_matrix | None = None) -> np.ndarray:
    """A vertex order in which mesh neighbours have nearby indices (reverse Cuthill-McKee).

    Returns
    -------
    (n,) int64 array
        ``order[k]`` is the original index of the vertex placed at position ``k``.
    """
    A = vertex_adjacency(F, n) if adjacency is None else adjacency
    return np.asarray(reverse_cuthill_mckee(A, symmetric_mode=True), dtype=np.int64)
