"""Validation of vertex index sets and detection of free regions that no constraint pins down."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from arap.errors import ConstraintError
from arap.topology import vertex_adjacency


def check_index_array(indices: np.ndarray | list[int], n: int, name: str) -> np.ndarray:
    """Validate a list of vertex indices.

    Parameters
    ----------
    indices : array-like of int
    n : int
        Number of vertices.
    name : str
        What the indices are, for messages.

    Returns
    -------
    (k,) int64 array

    Raises
    ------
    ConstraintError
        Not a flat list of integers, out of range, or repeated.
    """
    arr = np.asarray(indices)
    if arr.size == 0:
        return np.zeros(0, dtype=np.int64)
    if arr.ndim != 1:
        raise ConstraintError(f"{name} must be a flat list of vertex indices, got an array of shape {arr.shape}")
    if arr.dtype.kind == "f":
        if not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr)):
            raise ConstraintError(f"{name} must hold integer vertex indices")
    elif arr.dtype.kind not in "iu":
        raise ConstraintError(f"{name} must hold integer vertex indices, got {arr.dtype}")
    arr = arr.astype(np.int64)
    bad = (arr < 0) | (arr >= n)
    if np.any(bad):
        first = int(arr[np.flatnonzero(bad)[0]])
        raise ConstraintError(
            f"{name}: {int(bad.sum())} indices out of range 0..{n - 1} (the mesh has {n} vertices), e.g. {first}"
        )
    uniq, counts = np.unique(arr, return_counts=True)
    if np.any(counts > 1):
        dup = uniq[counts > 1]
        raise ConstraintError(f"{name}: {len(dup)} vertices listed more than once, e.g. {int(dup[0])}")
    return arr


def find_unconstrained_part(F: np.ndarray, n: int, free: np.ndarray,
                            adjacency: sp.csr_matrix | None = None) -> tuple[list[int], int] | None:
    """Find a connected part of the free vertices with no edge to a non-free vertex.

    Such a part has no constraint, so the global step's matrix is singular there.

    Parameters
    ----------
    F : (m, 3) int array
    n : int
    free : (f,) int array
        Free vertices.
    adjacency : (n, n) sparse matrix or None
        The mesh's vertex adjacency, if already computed.

    Returns
    -------
    (sample, size) or None
        Up to five vertex indices of the largest offending part and its size; None if every part is pinned.
    """
    if not len(free):
        return None
    A = vertex_adjacency(F, n) if adjacency is None else adjacency
    is_free = np.zeros(n, dtype=bool)
    is_free[free] = True
    A_ff = A[free][:, free]
    count, labels = connected_components(A_ff, directed=False)
    # A part is pinned if one of its vertices has a non-free neighbour.
    pinned_vertex = np.asarray(A[free].astype(np.int64) @ (~is_free).astype(np.int64)).ravel() > 0
    pinned = np.zeros(count, dtype=bool)
    pinned[labels[pinned_vertex]] = True
    if pinned.all():
        return None
    sizes = np.bincount(labels, minlength=count)
    bad = np.flatnonzero(~pinned)
    worst = bad[np.argmax(sizes[bad])]
    members = free[labels == worst]
    return [int(v) for v in members[:5]], int(sizes[worst])
