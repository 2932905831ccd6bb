"""Validation of vertex index sets and detection of free regions that no constraint pins down."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numba as nb
import numpy as np
import scipy.sparse as sp

from arap.errors import ConstraintError
from arap.meshes.mesh import bounding_box
from arap.meshes.topology import free_components, vertex_adjacency


def _show(value: Any) -> str:
    """A value for a message, at most 40 characters (a 400-digit integer must not flood it)."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def check_index_array(indices: Any, n: int, name: str, *, allow_empty: bool = True) -> np.ndarray:
    """Validate a list of vertex indices: the one check every caller (library, command line, studio) uses.

    Parameters
    ----------
    indices : sequence of int (list, tuple, range) or (k,) integer array
        Python ``int`` or NumPy integers. Floats (even ``1.0``), booleans, strings and nested lists are refused,
        whatever their value; an empty list or array of any dtype is the empty set.
    n : int
        Number of vertices.
    name : str
        What the indices are, for messages (``"fixed"``, ``"handle group 2"``).
    allow_empty : bool
        When False, an empty list is refused.

    Returns
    -------
    (k,) int64 array

    Raises
    ------
    ConstraintError
        Not a flat list of integers, out of range ``[0, n)``, repeated, or empty when not allowed.
    """
    if isinstance(indices, np.ndarray):
        if indices.ndim != 1 and indices.size:
            raise ConstraintError(f"{name} must be a flat list of vertex indices, got an array of shape "
                                  f"{indices.shape}")
        if indices.size and indices.dtype.kind not in "iu":
            raise ConstraintError(f"{name} must be a flat list of integer vertex indices, got an array of "
                                  f"{indices.dtype}")
        items: Any = indices.reshape(-1)
    elif isinstance(indices, Sequence) and not isinstance(indices, str | bytes | bytearray):
        items = indices
        if set(map(type, items)) - {int}:  # the common all-int list skips this per-item loop
            for pos, item in enumerate(items):
                if isinstance(item, bool | np.bool_) or not isinstance(item, int | np.integer):
                    raise ConstraintError(f"{name} must be a flat list of integer vertex indices; item {pos} is "
                                          f"{_show(item)}")
    else:
        raise ConstraintError(f"{name} must be a list of vertex indices, got {type(indices).__name__}")
    if not len(items):
        if not allow_empty:
            raise ConstraintError(f"{name} is empty" + ("; leave it out (None, null) to use the whole mesh"
                                                         if name == "roi" else ""))
        return np.zeros(0, dtype=np.int64)
    if not isinstance(items, np.ndarray) and not (0 <= min(items) and max(items) < n):
        # Compared as Python integers: a 400-digit index must be refused, not overflow int64.
        out = [pos for pos, i in enumerate(items) if not 0 <= i < n]
        raise ConstraintError(f"{name} has {len(out)} indices out of range [0, {n}) "
                              f"(first: item {out[0]} = {_show(int(items[out[0]]))})")
    if isinstance(items, np.ndarray):
        bad = (items < 0) | (items >= n)  # in the array's own dtype: uint64 beyond int64 must not wrap
        if bad.any():
            first = int(np.flatnonzero(bad)[0])
            raise ConstraintError(f"{name} has {int(bad.sum())} indices out of range [0, {n}) "
                                  f"(first: item {first} = {int(items[first])})")
    arr = np.asarray(items, dtype=np.int64)
    uniq, counts = np.unique(arr, return_counts=True)
    if np.any(counts > 1):
        dup = uniq[counts > 1]
        raise ConstraintError(f"{name} lists {len(dup)} vertices more than once (first: {int(dup[0])})")
    return arr


def find_unconstrained_part(F: np.ndarray, n: int, free: np.ndarray,
                            adjacency: sp.csr_matrix | None = None) -> tuple[list[int], int, int, int] | None:
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
    (sample, size, parts, vertices) or None
        Up to five vertex indices of the largest offending part and its size, the number of offending parts and
        their vertices in all; None if every part is pinned.
    """
    if not len(free):
        return None
    A = vertex_adjacency(F, n) if adjacency is None else adjacency
    # A part is pinned if one of its vertices has a non-free neighbour.
    count, labels, pinned = free_components(A, free)
    if pinned.all():
        return None
    sizes = np.bincount(labels, minlength=count)
    bad = np.flatnonzero(~pinned)
    worst = bad[np.argmax(sizes[bad])]
    members = free[labels == worst]
    return [int(v) for v in members[:5]], int(sizes[worst]), len(bad), int(sizes[bad].sum())


@nb.njit(cache=True, nogil=True)
def _rows_of(X: np.ndarray, index: np.ndarray, offset: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    out = np.empty((index.shape[0], 3))
    o0, o1, o2 = offset[0], offset[1], offset[2]
    for i in range(index.shape[0]):
        j = index[i]
        out[i, 0] = X[j, 0] + o0
        out[i, 1] = X[j, 1] + o1
        out[i, 2] = X[j, 2] + o2
    return out


_NO_OFFSET = np.zeros(3)


def rows_of(X: np.ndarray, index: np.ndarray, offset: np.ndarray | None = None) -> np.ndarray:
    """``X[index] + offset`` for an (n, 3) float64 array and a valid index array, as a new array (compiled: about
    twice as fast as ``np.take`` on the rows of a large mesh, which the solver pays on every call).

    Parameters
    ----------
    X : (n, 3) float64 array
    index : (k,) int array
        Row indices in ``0..n-1`` (not checked).
    offset : (3,) float64 array or None
        Added to every row (in the same pass); None: nothing.

    Returns
    -------
    (k, 3) float64 array

    Example
    -------
    >>> rows_of(np.arange(9.0).reshape(3, 3), np.array([2, 0])).tolist()
    [[6.0, 7.0, 8.0], [0.0, 1.0, 2.0]]
    >>> rows_of(np.arange(9.0).reshape(3, 3), np.array([1]), np.array([10.0, 0.0, 0.0])).tolist()
    [[13.0, 4.0, 5.0]]
    """
    return _rows_of(X, index, _NO_OFFSET if offset is None else np.asarray(offset, dtype=np.float64))


@nb.njit(cache=True, nogil=True)
def _with_rows(X: np.ndarray, index: np.ndarray, values: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    out = X.copy()
    for k in range(index.shape[0]):
        j = index[k]
        out[j, 0] = values[k, 0]
        out[j, 1] = values[k, 1]
        out[j, 2] = values[k, 2]
    return out


def with_rows(X: np.ndarray, index: np.ndarray, values: np.ndarray) -> np.ndarray:
    """A copy of the (m, 3) float64 array ``X`` with rows ``index`` set to ``values`` (k, 3), compiled (the solver
    places the targets among the fixed positions on every call).

    Example
    -------
    >>> with_rows(np.zeros((3, 3)), np.array([1]), np.ones((1, 3))).tolist()
    [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.0, 0.0, 0.0]]
    """
    return _with_rows(X, index, values)


@nb.njit(cache=True, nogil=True)
def assign_rows(dst: np.ndarray, src: np.ndarray) -> bool:  # pragma: no cover - compiled
    """``dst[:] = src`` for two (m, 3) float64 arrays; returns whether ``dst`` held ``src`` already (one pass).

    Example
    -------
    >>> a = np.zeros((2, 3)); assign_rows(a, np.ones((2, 3))), assign_rows(a, np.ones((2, 3)))
    (False, True)
    """
    same = True
    for i in range(dst.shape[0]):
        for j in range(3):
            if dst[i, j] != src[i, j]:
                same = False
                dst[i, j] = src[i, j]
    return same

FAR = 1e3
"""A mesh whose bounding-box centre lies farther than this many diagonals from the origin along an axis is held
relative to that centre (along that axis) inside the solver."""


def internal_origin(V: np.ndarray, diagonal: float) -> np.ndarray:
    """The origin the solver holds positions relative to, shape (3,).

    Far from the origin (surveyed scans in map coordinates) absolute coordinates keep too few bits of the shape for
    a tolerance of 1e-9 of its size: a sphere of radius 1 at 1e7 never converged. Along an axis where the centre of
    the bounding box is more than :data:`FAR` diagonals away, the origin is that centre, and every coordinate along it
    lies within a factor 2 of it, so the shift is exact (Sterbenz's lemma); elsewhere it is 0 and nothing changes.

    Example
    -------
    >>> internal_origin(np.array([[1e7, 0.0, 0.0], [1e7 + 1.0, 1.0, 1.0]]), np.sqrt(3.0)).tolist()
    [10000000.5, 0.0, 0.0]
    """
    if not len(V):
        return np.zeros(3)
    box = bounding_box(V)
    centre = 0.5 * (box[0] + box[1])
    return np.where(np.abs(centre) > FAR * diagonal, centre, 0.0)
