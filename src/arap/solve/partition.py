"""Which vertices a constraint set leaves free, and the checks of the arrays a solve is given.

A vertex is *constrained* when it is an anchor or a handle (its target is given), *held* when it stays at its rest
position without being constrained (outside the region of interest, or used by no face), and *free* otherwise: the
linear system has one row per free vertex. Every connected part of the free vertices must touch a constrained or
held vertex (or a point handle's triangle), or its position would be undetermined.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from arap.errors import ArapError, ConstraintError, UnconstrainedRegionError
from arap.meshes.mesh import MIN_RELATIVE_SIZE, SIZE_RANGE, bounding_box, coordinate_problem
from arap.meshes.topology import free_components
from arap.solve.indexing import find_unconstrained_part

__all__ = ["check_point_targets", "check_positions", "check_reach", "check_targets", "loose_parts",
           "partition_vertices"]


def partition_vertices(
    F: NDArray[np.integer], n: int, constrained: NDArray[np.integer], roi: NDArray[np.integer] | None,
    point_faces: NDArray[np.integer] | None, adjacency: sp.csr_matrix, loose: bool = False,
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64], list[NDArray[np.int64]]]:
    """The free, held and non-free (constrained or held) vertices of a constraint set, in increasing order, and the
    loose parts.

    Parameters
    ----------
    F : (m, 3) int array
    n : int
        Number of vertices.
    constrained : (k,) int array
        Anchors and handles.
    roi : (r,) int array or None
        Region of interest; None: the whole mesh.
    point_faces : (p,) int array or None
        Triangles holding point handles: their corners count as pinned.
    adjacency : (n, n) sparse matrix
        The mesh's vertex adjacency.
    loose : bool
        Connected parts of the free vertices that touch nothing that fixes them are held (and listed) rather than
        refused.

    Returns
    -------
    free, held, nonfree : int arrays
    loose : list of int arrays
        The vertices of each loose part (among ``held``); empty unless ``loose``.

    Raises
    ------
    UnconstrainedRegionError
        A connected part of the free vertices touches nothing that fixes it (unless ``loose``).

    Example
    -------
    >>> import numpy as np
    >>> from arap.meshes.topology import vertex_adjacency
    >>> F = np.array([[0, 1, 2], [0, 2, 3]])
    >>> free, held, nonfree, _ = partition_vertices(F, 5, np.array([0]), None, None, vertex_adjacency(F, 5))
    >>> free.tolist(), held.tolist(), nonfree.tolist()
    ([1, 2, 3], [4], [0, 4])
    """
    fixed_mask = np.zeros(n, dtype=bool)
    fixed_mask[constrained] = True
    referenced = np.zeros(n, dtype=bool)
    referenced[F.ravel()] = True
    held_mask = ~referenced & ~fixed_mask
    if roi is not None:
        in_roi = np.zeros(n, dtype=bool)
        in_roi[roi] = True
        held_mask |= ~in_roi & ~fixed_mask
    held = np.flatnonzero(held_mask)
    free = np.flatnonzero(~fixed_mask & ~held_mask)
    nonfree = np.flatnonzero(fixed_mask | held_mask)
    pinned = np.zeros(n, dtype=bool)  # a free part that holds a point handle's corner is pinned by it
    if point_faces is not None:
        pinned[F[point_faces].ravel()] = True
    if loose:
        pieces = loose_parts(free[~pinned[free]], adjacency)
        if pieces:
            held = np.union1d(held, np.concatenate(pieces))
            free = np.setdiff1d(free, held)
        return free, held, np.union1d(nonfree, held), pieces
    part = find_unconstrained_part(F, n, free[~pinned[free]], adjacency)
    if part is not None:
        sample, size, parts, in_all = part
        where = "" if roi is None else " (region of interest)"
        others = "" if parts == 1 else (f", and so {'are' if parts > 2 else 'is'} {parts - 1} more such "
                                        f"part{'s' if parts > 2 else ''} ({in_all - size} vertices)")
        raise UnconstrainedRegionError(
            f"a connected part of {size} free vertices{where} touches no constrained vertex, so its position is "
            f"undetermined (e.g. vertices {sample}){others}; add an anchor or handle "
            + ("there" if parts == 1 else "to each")
            + ("" if roi is None else " or shrink the region of interest"),
            vertices=sample, size=size,
        )
    return free, held, nonfree, []


def loose_parts(free: NDArray[np.int64], adjacency: sp.csr_matrix) -> list[NDArray[np.int64]]:
    """The connected parts of the ``free`` vertices that have no edge to another vertex, largest first.

    Example
    -------
    >>> from arap.meshes.topology import vertex_adjacency
    >>> A = vertex_adjacency(np.array([[0, 1, 2], [3, 4, 5]]), 6)
    >>> [p.tolist() for p in loose_parts(np.array([1, 2, 3, 4, 5]), A)]
    [[3, 4, 5]]
    """
    if not len(free):
        return []
    _, labels, pinned = free_components(adjacency, free)
    bad = np.flatnonzero(~pinned)
    parts = [free[labels == k] for k in bad]
    return sorted(parts, key=len, reverse=True)


def _floats(value: object, name: str, expected: str, error: type[ArapError]) -> NDArray[np.float64]:
    """``value`` as a float64 array (no copy when it is one); ``error`` naming ``name`` and the ``expected`` array
    when it holds anything but real numbers (strings, complex numbers, ragged lists, objects)."""
    try:
        raw = np.asarray(value)
    except ValueError:  # ragged nested lists
        raise error(f"{name} must be numbers: {expected}") from None
    if raw.dtype.kind == "c":
        raise error(f"{name} must be real numbers, got {raw.dtype}")
    if raw.dtype.kind not in "biuf" and raw.size:
        try:
            if raw.dtype.kind in "USV":
                raise TypeError
            return raw.astype(np.float64)
        except (TypeError, ValueError, OverflowError):
            raise error(f"{name} must be numbers: {expected}") from None
    return raw.astype(np.float64, copy=False)


def check_targets(targets: object, k: int, columns: int = 3) -> NDArray[np.float64]:
    """Targets of ``k`` constrained vertices as a (k, columns) float64 array; raises ConstraintError otherwise."""
    T = _floats(targets, "targets", f"({k}, {columns}) floats, one row per constrained vertex", ConstraintError)
    if T.shape != (k, columns):
        raise ConstraintError(f"targets must have shape ({k}, {columns}), one row per constrained vertex; "
                              f"got {T.shape}")
    if not np.all(np.isfinite(T)):
        bad = int(np.flatnonzero(~np.all(np.isfinite(T), axis=1))[0])
        raise ConstraintError(f"targets must be finite; row {bad} is {T[bad].tolist()}")
    return T


def check_point_targets(point_targets: object, p: int, columns: int = 3) -> NDArray[np.float64] | None:
    """Targets of ``p`` point constraints, shape (p, columns); required exactly when there are point constraints."""
    if point_targets is None:
        if p:
            raise ConstraintError(f"point_targets is missing: the solver has {p} point constraints")
        return None
    P = _floats(point_targets, "point_targets", f"({p}, {columns}) floats, one row per point constraint",
                ConstraintError)
    if P.shape != (p, columns):
        raise ConstraintError(f"point_targets must have shape ({p}, {columns}), got {P.shape}")
    if not np.isfinite(P).all():
        raise ConstraintError("point_targets must be finite")
    return P


def check_reach(bounds: NDArray[np.float64], X: NDArray[np.float64], what: str = "targets") -> None:
    """Refuse targets so far from the mesh that the two together have a scale the computations cannot represent
    (:func:`arap.meshes.mesh.coordinate_problem`: a target at 1e300 would give NaN energies and a mesh 1e300 across).

    Parameters
    ----------
    bounds : (2, 3) float array
        The mesh's bounding box: minimum and maximum corner.
    X : (k, 3) float array
        Finite targets.
    what : str
        What they are, for the message.

    Raises
    ------
    ConstraintError
        Naming the scale the targets give the problem (nothing is raised for a mesh that alone has a bad scale).
    """
    if not len(X):
        return
    # The usual case (a drag), with reductions over whole arrays (those along an axis of an (n, 3) array are much
    # slower, see arap.meshes.mesh.bounding_box, and this runs on every drag): the span over all axes bounds each
    # axis's, and the mesh's own size is at most the size with the targets.
    lo, hi = min(float(X.min()), float(bounds.min())), max(float(X.max()), float(bounds.max()))
    reach = max(-lo, hi)
    if hi - lo <= SIZE_RANGE[1] and float((bounds[1] - bounds[0]).max()) >= MIN_RELATIVE_SIZE * reach:
        return
    box = bounding_box(X)
    corners = np.stack([np.minimum(bounds[0], box[0]), np.maximum(bounds[1], box[1])])
    problem = coordinate_problem(corners)
    if problem is not None and coordinate_problem(bounds) is None:
        raise ConstraintError(f"the {what} lie too far from the mesh: with them, {problem}")


def check_positions(U: object, n: int, name: str, columns: int = 3) -> NDArray[np.float64]:
    """Positions of all ``n`` vertices as an (n, columns) float64 array; raises ArapError (naming ``name``)
    otherwise."""
    X = _floats(U, name, f"({n}, {columns}) floats, one row per vertex", ArapError)
    if X.shape != (n, columns):
        raise ArapError(f"{name} must have shape ({n}, {columns}), got {X.shape}")
    if not np.all(np.isfinite(X)):
        raise ArapError(f"{name} has non-finite coordinates")
    return X
