"""Validation of vertex index sets and detection of free regions that no constraint pins down."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from arap.errors import ConstraintError
from arap.topology import vertex_adjacency


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
                            adjacency: sp.csr_matrix | None = None,
                            pinned_free: np.ndarray | None = None) -> tuple[list[int], int] | None:
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
    pinned_free : (q,) int array or None
        Free vertices that pin their part by themselves (those a point constraint holds).

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
    if pinned_free is not None and len(pinned_free):
        slot = np.full(n, -1)
        slot[free] = np.arange(len(free))
        held = slot[pinned_free]
        pinned_vertex[held[held >= 0]] = True
    pinned = np.zeros(count, dtype=bool)
    pinned[labels[pinned_vertex]] = True
    if pinned.all():
        return None
    sizes = np.bincount(labels, minlength=count)
    bad = np.flatnonzero(~pinned)
    worst = bad[np.argmax(sizes[bad])]
    members = free[labels == worst]
    return [int(v) for v in members[:5]], int(sizes[worst])


BARYCENTRIC_TOLERANCE = 1e-6
"""How far barycentric coordinates may stray below 0 or their sum from 1 (rounding in a client's raycast)."""


def check_point_constraints(
    faces: Any, barycentric: Any, weights: Any, n_faces: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate point constraints (a point inside a face, given by barycentric coordinates): the one check that the
    library, the command line and the studio use.

    Parameters
    ----------
    faces : (p,) sequence of int
        Face of each point.
    barycentric : (p, 3) array-like of float
        Barycentric coordinates of each point in its face (in the order of the face's vertices): finite, each at
        least ``-BARYCENTRIC_TOLERANCE`` and summing to 1 within ``BARYCENTRIC_TOLERANCE``.
    weights : (p,) array-like of float or None
        ``inf`` for a hard constraint (met exactly), a positive finite weight for a soft one (a penalty
        ``w ‖p − t‖²``). None: all hard.
    n_faces : int
        Number of faces of the mesh.

    Returns
    -------
    faces : (p,) int64 array
    barycentric : (p, 3) float64 array
        Clipped at 0 and normalised to sum exactly to 1.
    weights : (p,) float64 array

    Raises
    ------
    ConstraintError
        A face index out of range or not an integer, barycentric coordinates of the wrong shape, not finite,
        negative or not summing to 1, or a weight that is not positive (NaN included).
    """
    if isinstance(faces, np.ndarray) and faces.size and faces.dtype.kind not in "iu":
        raise ConstraintError(f"point faces must be integer face indices, got an array of {faces.dtype}")
    if not isinstance(faces, np.ndarray):
        if not isinstance(faces, Sequence) or isinstance(faces, str | bytes | bytearray):
            raise ConstraintError(f"point faces must be a list of face indices, got {type(faces).__name__}")
        for pos, item in enumerate(faces):
            if isinstance(item, bool | np.bool_) or not isinstance(item, int | np.integer):
                raise ConstraintError(f"point faces must be integer face indices; item {pos} is {_show(item)}")
            if not 0 <= item < n_faces:
                raise ConstraintError(f"point {pos}: face {_show(item)} is out of range [0, {n_faces})")
    f = np.asarray(faces).reshape(-1)
    bad = np.flatnonzero((f < 0) | (f >= n_faces))
    if len(bad):
        raise ConstraintError(f"point {int(bad[0])}: face {int(f[bad[0]])} is out of range [0, {n_faces})")
    p = len(f)
    try:
        b = np.array(barycentric, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ConstraintError(f"point barycentric coordinates must be numbers ({exc})") from exc
    if b.shape != (p, 3) and not (p == 0 and b.size == 0):
        raise ConstraintError(f"point barycentric coordinates must have shape ({p}, 3), got {b.shape}")
    b = b.reshape(p, 3)
    if not np.all(np.isfinite(b)):
        bad_row = int(np.flatnonzero(~np.all(np.isfinite(b), axis=1))[0])
        raise ConstraintError(f"point {bad_row}: barycentric coordinates must be finite, got {b[bad_row].tolist()}")
    low = np.flatnonzero(np.any(b < -BARYCENTRIC_TOLERANCE, axis=1))
    if len(low):
        raise ConstraintError(f"point {int(low[0])}: barycentric coordinates must be >= 0 (the point lies in its "
                              f"face), got {b[low[0]].tolist()}")
    off = np.flatnonzero(np.abs(b.sum(axis=1) - 1.0) > BARYCENTRIC_TOLERANCE)
    if len(off):
        raise ConstraintError(f"point {int(off[0])}: barycentric coordinates must sum to 1, got "
                              f"{b[off[0]].tolist()} (sum {float(b[off[0]].sum())})")
    b = np.clip(b, 0.0, None)
    b /= b.sum(axis=1, keepdims=True)
    if weights is None:
        w = np.full(p, np.inf)
    else:
        try:
            w = np.array(weights, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError) as exc:
            raise ConstraintError(f"point weights must be numbers ({exc})") from exc
        if w.shape != (p,):
            raise ConstraintError(f"point weights must have shape ({p},), one per point, got {w.shape}")
        bad = np.flatnonzero(~(w > 0))
        if len(bad):
            raise ConstraintError(f"point {int(bad[0])}: weight must be > 0 (inf: hard), got {w[bad[0]]}")
    return f.astype(np.int64), b, w
