"""Combinatorial structure of a triangle mesh: edges, boundary, adjacency and connected components."""

from __future__ import annotations

import numba as nb
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components as _cc
from scipy.sparse.csgraph import reverse_cuthill_mckee


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


def non_manifold_vertices(F: np.ndarray, n: int) -> np.ndarray:
    """Vertices where separate sheets of faces meet at a point (a bow-tie), shape (k,), increasing.

    A vertex's faces are linked when they share an edge at it; on a manifold they form one fan (a disc, or a half disc
    at a boundary), at a bow-tie two or more.

    Example
    -------
    >>> non_manifold_vertices(np.array([[0, 1, 2], [0, 3, 4]]), 5).tolist()
    [0]
    """
    F = np.asarray(F, dtype=np.int64)
    if not len(F):
        return np.zeros(0, dtype=np.int64)
    # Each corner (v; a, b) of a face joins v's wedges towards a and towards b: nodes are the (v, neighbour) pairs.
    v = F.ravel()
    a = np.roll(F, -1, axis=1).ravel()
    b = np.roll(F, 1, axis=1).ravel()
    keys = np.concatenate([v * n + a, v * n + b])
    nodes, inverse = np.unique(keys, return_inverse=True)
    k = len(v)
    graph = sp.coo_matrix((np.ones(k), (inverse[:k], inverse[k:])), shape=(len(nodes), len(nodes)))
    _, labels = _cc(graph, directed=False)
    owner = nodes // n
    fans = np.unique(np.stack([owner, labels], axis=1), axis=0)[:, 0]
    counts = np.bincount(fans, minlength=n)
    return np.flatnonzero(counts > 1)


def boundary_edges(F: np.ndarray) -> np.ndarray:
    """Edges used by exactly one face, shape (b, 2)."""
    edges, counts = edge_face_counts(F)
    return edges[counts == 1]


def vertex_adjacency(F: np.ndarray, n: int) -> sp.csr_matrix:
    """Symmetric 0/1 vertex adjacency matrix (no self loops), shape (n, n)."""
    ptr, idx = _face_adjacency(np.ascontiguousarray(F, dtype=np.int64), int(n))
    if len(idx) < np.iinfo(np.int32).max:
        ptr = ptr.astype(np.int32)
    M = sp.csr_matrix((np.ones(len(idx), dtype=np.int8), idx, ptr), shape=(n, n))
    M.has_sorted_indices = True
    return M


@nb.njit(cache=True, nogil=True)
def _face_adjacency(F, n):  # pragma: no cover - compiled
    # Every corner lists its two face neighbours; a stamp per vertex drops repeats, a short sort orders each row.
    count = np.zeros(n + 1, np.int64)
    for f in range(F.shape[0]):
        for k in range(3):
            count[F[f, k] + 1] += 2
    for i in range(n):
        count[i + 1] += count[i]
    fill = count[:-1].copy()
    idx = np.empty(count[n], np.int32)
    for f in range(F.shape[0]):
        for k in range(3):
            v = F[f, k]
            p = fill[v]
            idx[p] = F[f, (k + 1) % 3]
            idx[p + 1] = F[f, (k + 2) % 3]
            fill[v] = p + 2
    stamp = np.full(n, -1, np.int64)
    ptr = np.zeros(n + 1, np.int64)
    out = 0
    for r in range(n):
        start = out
        for p in range(count[r], count[r + 1]):
            c = idx[p]
            if stamp[c] != r:
                stamp[c] = r
                q = out - 1
                while q >= start and idx[q] > c:
                    idx[q + 1] = idx[q]
                    q -= 1
                idx[q + 1] = c
                out += 1
        ptr[r + 1] = out
    return ptr, idx[:out].copy()


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


def free_components(adjacency: sp.csr_matrix, free: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
    """Connected components of the graph of the ``free`` vertices, and which of them touch another vertex.

    Parameters
    ----------
    adjacency : (n, n) scipy.sparse.csr_matrix
        Symmetric vertex adjacency (:func:`vertex_adjacency`).
    free : (f,) int array
        Distinct vertex indices.

    Returns
    -------
    count : int
        Number of components.
    labels : (f,) int64 array
        Component of ``free[i]``; components are numbered in the order of their first member in ``free`` (as
        ``scipy.sparse.csgraph.connected_components`` numbers those of ``adjacency[free][:, free]``).
    pinned : (count,) bool array
        Whether a vertex of the component has a neighbour outside ``free``.
    """
    return _free_components(adjacency.indptr, adjacency.indices, np.asarray(free, dtype=np.int64),
                            adjacency.shape[0])


@nb.njit(cache=True, nogil=True)
def _free_components(indptr, indices, free, n):  # pragma: no cover - compiled
    position = np.full(n, -1, np.int64)
    for i in range(free.shape[0]):
        position[free[i]] = i
    labels = np.full(free.shape[0], -1, np.int64)
    pinned = np.zeros(free.shape[0], np.bool_)
    queue = np.empty(free.shape[0], np.int64)
    count = 0
    for start in range(free.shape[0]):
        if labels[start] != -1:
            continue
        labels[start] = count
        head = 0
        tail = 1
        queue[0] = start
        while head < tail:
            v = free[queue[head]]
            head += 1
            for p in range(indptr[v], indptr[v + 1]):
                j = position[indices[p]]
                if j < 0:
                    pinned[count] = True
                elif labels[j] == -1:
                    labels[j] = count
                    queue[tail] = j
                    tail += 1
        count += 1
    return count, labels, pinned[:count].copy()
