"""Colouring the vertex graph for the sweeps of smooth-rotation ARAP (:mod:`arap.method.smooth`): no two neighbours
share a colour, so the cells of one colour can be updated at once, and within windows of :data:`WINDOW` positions the
vertices of one colour are consecutive."""

from __future__ import annotations

import numba as nb
import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

__all__ = ["WINDOW", "colour_order", "colour_vertices"]

WINDOW = 2048
"""Consecutive cells whose colours are swept before the next window's (so that a sweep stays in cache)."""


@nb.njit(cache=True, nogil=True)
def _greedy_colours(ptr, nbr):  # pragma: no cover - compiled
    n = ptr.shape[0] - 1
    colour = np.full(n, -1, np.int64)
    used = np.full(64, -1, np.int64)  # used[k] == i: colour k is taken by a neighbour of i
    for i in range(n):
        for k in range(ptr[i], ptr[i + 1]):
            c = colour[nbr[k]]
            if c >= 0:
                if c >= used.shape[0]:
                    grown = np.full(2 * c + 2, -1, np.int64)
                    grown[: used.shape[0]] = used
                    used = grown
                used[c] = i
        c = 0
        while c < used.shape[0] and used[c] == i:
            c += 1
        colour[i] = c
    return colour


def colour_vertices(ptr: NDArray[np.int64], nbr: NDArray[np.int32]) -> NDArray[np.int64]:
    """Greedy colouring of a graph in CSR form: no two neighbours share a colour.

    Parameters
    ----------
    ptr : (n+1,) int array
    nbr : (t,) int array
        Neighbours of ``i`` are ``nbr[ptr[i]:ptr[i+1]]``.

    Returns
    -------
    (n,) int64 array
        Colours ``0..k-1`` (k is at most the largest degree plus one; about 7 on triangle meshes).

    Example
    -------
    >>> ptr = np.array([0, 2, 4, 6]); nbr = np.array([1, 2, 0, 2, 0, 1])   # a triangle
    >>> colour_vertices(ptr, nbr).tolist()
    [0, 1, 2]
    """
    return _greedy_colours(np.ascontiguousarray(ptr, dtype=np.int64), np.ascontiguousarray(nbr, dtype=np.int64))


def colour_order(order: NDArray[np.int64], adjacency: sp.csr_matrix) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Refine a locality order for the coloured sweep: within each window of :data:`WINDOW` positions, the vertices
    of one colour become consecutive, so that each run of the sweep reads contiguous memory.

    Parameters
    ----------
    order : (n,) int array
        ``order[k]`` is the vertex at position ``k`` (e.g. :func:`arap.meshes.topology.locality_order`).
    adjacency : (n, n) sparse matrix
        Symmetric vertex adjacency.

    Returns
    -------
    order : (n,) int64 array
        The refined order.
    colour : (n,) int64 array
        A colouring of the vertices (indexed by vertex): no two neighbours share a colour.
    """
    n = len(order)
    A = sp.csr_matrix(adjacency)[order][:, order].tocsr()
    colour_at = colour_vertices(A.indptr.astype(np.int64), A.indices)
    positions = np.lexsort((colour_at, np.arange(n) // WINDOW))
    colour = np.empty(n, np.int64)
    colour[order] = colour_at
    return np.asarray(order, dtype=np.int64)[positions], colour
