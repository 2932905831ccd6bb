"""What the solver deforms: a triangle surface in space, a triangle mesh in the plane or a tetrahedral solid.

:func:`check_domain` is the gate every solver input goes through. It tells the three kinds apart by the arrays'
shapes, checks each strictly (one :class:`~arap.errors.MeshError` per defect, naming the first bad element) and
returns a :class:`Domain`: the positions the solver works in (always three columns; a planar mesh lies in ``z = 0``)
and how to give results back in the caller's coordinates.

- **surface**: ``V`` (n, 3), ``F`` (m, 3) triangles: :func:`arap.meshes.mesh.check_mesh`, unchanged.
- **planar**: ``V`` (n, 2) with triangles, or ``V`` (n, 3) with one constant coordinate and ``energy="elements"``.
  Rotations are 2×2 (about the plane's normal), so a triangle cannot flip over: a reflection is never a rotation
  in the plane, while in space it is a half turn.
- **solid**: ``V`` (n, 3), ``T`` (m, 4) tetrahedra (libigl's ``arap_precomputation`` with ``dim = 3`` on a
  tetrahedral mesh).

Elements whose orientation disagrees with the others (a triangle folded over in the plane, an inverted
tetrahedron) and elements of zero area or volume are refused: their cotangent weights describe no rest shape.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from arap.errors import ArapError, MeshError
from arap.meshes.mesh import (
    DEGENERATE_TOLERANCE,
    bounding_box,
    check_integer_indices,
    check_mesh,
    check_vertices_and_indices,
    is_mesh_like,
    mesh_arrays,
)
from arap.options import DEFAULT_ELEMENT_ENERGY, DEFAULT_ENERGY, EnergyType

__all__ = ["PLANAR_TOLERANCE", "Domain", "DomainKind", "boundary_faces", "boundary_faces_and_owners", "check_domain",
           "default_energy", "element_mesh_arrays",
           "signed_measures", "tetrahedron_faces"]

DomainKind = Literal["surface", "planar", "solid"]

PLANAR_TOLERANCE = 1e-12
"""A coordinate is constant (the mesh is planar) when its spread is at most this times the bounding-box diagonal."""


@dataclass(frozen=True, eq=False)
class Domain:
    """A checked mesh in the solver's coordinates.

    Attributes
    ----------
    V : (n, 3) float64 array
        Positions the solver works in: the caller's for surfaces and solids; for planar meshes the two in-plane
        coordinates and a zero.
    elements : (m, 3) or (m, 4) int64 array
        Triangles or tetrahedra, as given.
    kind : {"surface", "planar", "solid"}
    columns : int
        Coordinates per vertex in the caller's arrays (2 or 3).
    axes : (3,) int array
        The caller's coordinate behind each of the solver's (for planar (n, 3) input: the two in-plane ones, then the
        constant one); ``[0, 1, 2]`` otherwise.
    offset : float
        The constant coordinate of planar (n, 3) input (0 otherwise).
    """

    V: NDArray[np.float64]
    elements: NDArray[np.int64]
    kind: DomainKind
    columns: int
    axes: NDArray[np.int64]
    offset: float

    @property
    def planar(self) -> bool:
        return self.kind == "planar"

    @property
    def graph_faces(self) -> NDArray[np.int64]:
        """Triangles spanning the mesh's edge graph: the elements, or the four faces of every tetrahedron."""
        return tetrahedron_faces(self.elements) if self.kind == "solid" else self.elements

    def lift(self, X: NDArray[np.float64], what: str, error: type[ArapError] = MeshError) -> NDArray[np.float64]:
        """The caller's checked points ``X`` (k, columns) in the solver's coordinates (k, 3).

        Raises
        ------
        ArapError
            ``error``, for points of planar input in space that leave the mesh's plane.
        """
        A = X
        if self.kind != "planar":
            return A
        out = np.zeros((len(A), 3))
        out[:, :2] = A[:, self.axes[:2]]
        if self.columns == 3:
            off = A[:, self.axes[2]] - self.offset
            scale = max(float(np.abs(self.V).max(initial=0.0)), abs(self.offset), 1.0)
            if len(off) and np.abs(off[np.isfinite(off)]).max(initial=0.0) > 1e-9 * scale:
                axis = "xyz"[int(self.axes[2])]
                raise error(f"{what} leave the plane {axis} = {self.offset:g} of the planar mesh; a planar "
                                "mesh deforms in its plane (for a surface in space use a surface energy)")
            out[:, 2] = np.where(np.isfinite(off), 0.0, off)  # keeps NaN/inf for the callers' own checks
        return out

    def drop(self, X: NDArray[np.float64]) -> NDArray[np.float64]:
        """The solver's points ``X`` (k, 3) in the caller's coordinates (k, columns): a new array."""
        if self.kind != "planar":
            return X
        out = np.empty((len(X), self.columns))
        if self.columns == 2:
            out[:] = X[:, :2]
        else:
            out[:, self.axes] = X
            out[:, self.axes[2]] = self.offset
        return out


def tetrahedron_faces(T: NDArray[np.integer]) -> NDArray[np.int64]:
    """The four triangles of every tetrahedron, shape (4m, 3) (shared faces repeated).

    Example
    -------
    >>> tetrahedron_faces(np.array([[0, 1, 2, 3]])).tolist()
    [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]]
    """
    T = np.asarray(T, dtype=np.int64)
    return np.concatenate([T[:, [1, 2, 3]], T[:, [0, 3, 2]], T[:, [0, 1, 3]], T[:, [0, 2, 1]]]).reshape(4, -1, 3) \
        .transpose(1, 0, 2).reshape(-1, 3)


def boundary_faces(T: NDArray[np.integer], V: NDArray[np.floating] | None = None) -> NDArray[np.int64]:
    """The boundary triangles of a tetrahedral mesh (see :func:`boundary_faces_and_owners`).

    Example
    -------
    >>> boundary_faces(np.array([[0, 1, 2, 3], [1, 2, 3, 4]])).shape
    (6, 3)
    """
    return boundary_faces_and_owners(T, V)[0]


def boundary_faces_and_owners(T: NDArray[np.integer], V: NDArray[np.floating] | None = None
                              ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The boundary triangles of a tetrahedral mesh: the faces that belong to one tetrahedron only, turned outwards.

    Parameters
    ----------
    T : (m, 4) int array
    V : (n, 3) float array or None
        Positions, to turn the faces of negatively oriented tetrahedra outwards too (None: the tetrahedra are taken
        as positively oriented).

    Returns
    -------
    faces : (k, 3) int64 array
        In the order of the tetrahedra.
    owners : (k,) int64 array
        The tetrahedron of each face.

    Example
    -------
    >>> faces, owners = boundary_faces_and_owners(np.array([[0, 1, 2, 3], [1, 2, 3, 4]]))
    >>> owners.tolist()
    [0, 0, 0, 1, 1, 1]
    """
    T64: NDArray[np.int64] = np.asarray(T, dtype=np.int64)
    T = T64
    if V is not None:
        negative = signed_measures(np.asarray(V, dtype=np.float64), T64) < 0
        if negative.any():
            T = T.copy()
            T[negative] = T[negative][:, [0, 2, 1, 3]]
    faces = tetrahedron_faces(T)
    key = np.sort(faces, axis=1)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    once = np.flatnonzero(counts[inverse.ravel()] == 1)
    return np.ascontiguousarray(faces[once]), once // 4


def element_mesh_arrays(V: Any, F: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """The ``(V, elements)`` arrays of a mesh given as arrays or as an object.

    Beyond :func:`arap.meshes.mesh.mesh_arrays`' surface objects: a ``meshio.Mesh`` with ``tetra`` cells (or
    ``triangle`` cells, planar when its points have two coordinates or a constant third) and a
    ``pyvista.UnstructuredGrid`` of tetrahedra.

    Raises
    ------
    MeshError
        Mixed element types, or an object holding neither triangles nor tetrahedra.
    """
    names = {f"{cls.__module__.split('.')[0]}.{cls.__name__}" for cls in type(V).__mro__}
    if F is None and "meshio.Mesh" in names:
        kinds = sorted({str(block.type) for block in V.cells})
        solid = [k for k in kinds if k.startswith("tetra")]
        if solid:
            # Boundary triangles, lines and points beside the tetrahedra (as gmsh writes them) are left aside.
            if any(k not in ("tetra", "triangle", "line", "vertex") for k in kinds):
                raise MeshError(f"the meshio.Mesh mixes element types ({', '.join(kinds)}); ARAP solids take linear "
                                "tetrahedra only ('tetra' cells)")
            T = np.concatenate([np.asarray(b.data, dtype=np.int64) for b in V.cells if b.type == "tetra"])
            return np.asarray(V.points), T
        if any(k not in ("triangle", "line", "vertex") for k in kinds):
            raise MeshError(f"the meshio.Mesh has cells of types {', '.join(kinds)}; ARAP takes triangles or linear "
                            "tetrahedra ('tetra'): triangulate other cells first")
        blocks = [np.asarray(b.data, dtype=np.int64) for b in V.cells if b.type == "triangle"]
        if not blocks:
            raise MeshError(f"the meshio.Mesh has no triangle or tetra cells (it has {', '.join(kinds) or 'none'})")
        return np.asarray(V.points), np.concatenate(blocks)
    if F is None and "pyvista.UnstructuredGrid" in names:
        grid: Any = V
        celltypes = np.asarray(grid.celltypes)
        tetra = 10  # VTK_TETRA
        if len(celltypes) == 0 or not np.all(celltypes == tetra):
            raise MeshError("the pyvista.UnstructuredGrid must hold linear tetrahedra only (VTK_TETRA); "
                            f"it has cell types {sorted(set(celltypes.tolist()))}")
        cells = np.asarray(grid.cells, dtype=np.int64).reshape(-1, 5)
        return np.asarray(grid.points), cells[:, 1:]
    if F is not None and not is_mesh_like(V):
        return np.asarray(V), np.asarray(F)
    return mesh_arrays(V, F)


def _as_elements(F: object) -> NDArray[np.int64]:
    A = np.asarray(F)
    if A.ndim != 2 or A.shape[1] not in (3, 4):
        raise MeshError(f"elements must be triangles (m, 3) or tetrahedra (m, 4), got shape {A.shape}")
    check_integer_indices(A, "element")
    return np.ascontiguousarray(A, dtype=np.int64)


def _check_elements(V: NDArray[np.float64], T: NDArray[np.int64], what: str) -> None:
    """Indices in range, no repeated vertex, no zero measure, one orientation (signed measures of one sign)."""
    m = len(T)
    check_vertices_and_indices(V, T, what, "tetrahedron" if T.shape[1] == 4 else "triangle")
    S = np.sort(T, axis=1)
    repeated = np.any(S[:, 1:] == S[:, :-1], axis=1)
    if repeated.any():
        bad = np.flatnonzero(repeated)
        raise MeshError(f"{len(bad)} {what} repeat a vertex (first: {bad[0]} = {T[bad[0]].tolist()})")
    box = bounding_box(V)
    diag = float(np.linalg.norm(box[1] - box[0]))
    signed = signed_measures(V, T)
    dim = T.shape[1] - 1
    flat = np.abs(signed) <= DEGENERATE_TOLERANCE * diag ** dim
    if flat.any():
        bad = np.flatnonzero(flat)
        word = "area" if dim == 2 else "volume"
        raise MeshError(f"{len(bad)} {what} have zero {word} (first: {bad[0]} = {T[bad[0]].tolist()})")
    positive = signed > 0
    minority = positive if positive.sum() * 2 < m else ~positive
    if minority.any():
        bad = np.flatnonzero(minority)
        kind = "folded over (oriented against the others)" if dim == 2 else "inverted (oriented against the others)"
        raise MeshError(f"{len(bad)} {what} are {kind} (first: {bad[0]} = {T[bad[0]].tolist()}); a rest shape needs "
                        "every element the same way round")


def signed_measures(V: NDArray[np.float64], T: NDArray[np.int64]) -> NDArray[np.float64]:
    """Signed areas of triangles in the plane ``z = 0`` (m, 3), or signed volumes of tetrahedra (m, 4), times 2 or 6.

    Example
    -------
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> signed_measures(V, np.array([[0, 1, 2, 3], [0, 2, 1, 3]])).tolist()
    [1.0, -1.0]
    """
    e1 = V[T[:, 1]] - V[T[:, 0]]
    e2 = V[T[:, 2]] - V[T[:, 0]]
    if T.shape[1] == 3:
        return e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    e3 = V[T[:, 3]] - V[T[:, 0]]
    return np.einsum("ij,ij->i", np.cross(e1, e2), e3)


def _plane_axis(V: NDArray[np.float64]) -> int | None:
    """The coordinate that is constant over ``V`` (the last one if several), or None."""
    spread = np.ptp(V, axis=0)
    diag = float(np.linalg.norm(spread))
    flat = np.flatnonzero(spread <= PLANAR_TOLERANCE * max(diag, 1e-300))
    return int(flat[-1]) if len(flat) and diag > 0 else None


def default_energy(V: NDArray[np.floating], T: NDArray[np.integer],
                   targets: NDArray[np.floating] | None = None) -> EnergyType:
    """The energy a mesh file is deformed with when none is given (``arap deform``, ``arap animate``, ``arap batch``).

    ``elements`` for tetrahedra, and for triangles in a plane of constant coordinate (a picture's mesh saved by the
    studio, in ``z = 0``) that all turn the same way in it and that the ``targets`` keep in it: such a mesh is
    deformed in its plane, as the studio deforms it. The surface energy :data:`~arap.options.DEFAULT_ENERGY`
    otherwise: for a surface in space, and for a flat sheet that the targets bend out of its plane (or whose
    triangles are folded over), which only a surface energy can deform. (:class:`arap.ArapSolver` itself takes
    ``elements`` only for triangles given with two coordinates and for tetrahedra.)

    Parameters
    ----------
    V : (n, 2) or (n, 3) float array
    T : (m, 3) or (m, 4) int array
    targets : (k, 3) float array or None
        Every position the constraints ask for (their handles', fixed vertices' and point handles' targets).

    Example
    -------
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]]); T = np.array([[0, 1, 2]])
    >>> default_energy(V, T), default_energy(V, T, np.array([[1., 0, 0.5]]))
    ('elements', 'spokes_and_rims')
    """
    P: NDArray[np.float64] = np.asarray(V, dtype=np.float64)
    T = np.asarray(T)
    if T.ndim == 2 and T.shape[1] == 4:
        return DEFAULT_ELEMENT_ENERGY
    if P.ndim != 2 or P.shape[1] != 3 or not len(P) or not np.isfinite(P).all():
        return DEFAULT_ELEMENT_ENERGY if P.ndim == 2 and P.shape[1] == 2 else DEFAULT_ENERGY
    axis = _plane_axis(P)
    if axis is None:
        return DEFAULT_ENERGY
    if targets is not None and len(targets):
        off = np.asarray(targets, dtype=np.float64)[:, axis] - P[0, axis]
        scale = max(float(np.abs(P).max()), 1.0)  # as Domain.lift measures a target's distance from the plane
        if np.abs(off[np.isfinite(off)]).max(initial=0.0) > 1e-9 * scale:
            return DEFAULT_ENERGY
    if len(T) and T.ndim == 2 and T.shape[1] == 3 and T.min() >= 0 and T.max() < len(P):
        signed = signed_measures(P[:, [a for a in range(3) if a != axis] + [axis]], T.astype(np.int64))
        if (signed > 0).any() and (signed < 0).any():
            return DEFAULT_ENERGY
    return DEFAULT_ELEMENT_ENERGY


def check_domain(V: Any, F: Any = None, elements: bool = False) -> Domain:
    """Check a mesh and tell its kind (see the module's description).

    Parameters
    ----------
    V : (n, 2) or (n, 3) real array, or a mesh object
        Positions, or a mesh object (see :func:`element_mesh_arrays`; then leave out ``F``).
    F : (m, 3) or (m, 4) integer array or None
        Triangles or tetrahedra.
    elements : bool
        The element energy is asked for: a (n, 3) triangle mesh with a constant coordinate is then planar.

    Returns
    -------
    Domain

    Raises
    ------
    MeshError
        As :func:`arap.meshes.mesh.check_mesh`, and for elements: out-of-range or repeated indices, zero area or
        volume, elements oriented against the others; tetrahedra with 2-d points.

    Example
    -------
    >>> V = np.array([[0., 0], [1, 0], [0, 1]]); F = np.array([[0, 1, 2]])
    >>> d = check_domain(V, F)
    >>> d.kind, d.V.shape, d.drop(d.V).shape
    ('planar', (3, 3), (3, 2))
    """
    V, F = element_mesh_arrays(V, F)
    V = np.asarray(V)
    if V.dtype == object or not (np.issubdtype(V.dtype, np.floating) or np.issubdtype(V.dtype, np.integer)):
        raise MeshError(f"vertex coordinates must be real numbers, got dtype {V.dtype}")
    if V.ndim != 2 or V.shape[1] not in (2, 3):
        raise MeshError(f"vertices must have shape (n, 3), or (n, 2) for a planar mesh, got {V.shape}")
    T = _as_elements(F) if np.asarray(F).size else np.zeros((0, 3), dtype=np.int64)
    V = np.ascontiguousarray(V, dtype=np.float64)
    identity = np.arange(3)
    if T.shape[1] == 4:
        if V.shape[1] != 3:
            raise MeshError(f"tetrahedra need 3-d vertices, got shape {V.shape}")
        _check_elements(V, T, "tetrahedra")
        return Domain(V=V, elements=T, kind="solid", columns=3, axes=identity, offset=0.0)
    if V.shape[1] == 2:
        lifted = np.zeros((len(V), 3))
        lifted[:, :2] = V
        _check_elements(lifted, T, "triangles")
        return Domain(V=lifted, elements=T, kind="planar", columns=2, axes=identity, offset=0.0)
    axis = _plane_axis(V) if elements and len(V) and np.isfinite(V).all() else None
    if axis is None:
        V, T = check_mesh(V, T)
        return Domain(V=V, elements=T, kind="surface", columns=3, axes=identity, offset=0.0)
    axes = np.array([a for a in range(3) if a != axis] + [axis], dtype=np.int64)
    offset = float(V[0, axis])
    lifted = np.zeros((len(V), 3))
    lifted[:, :2] = V[:, axes[:2]]
    _check_elements(lifted, T, "triangles")
    return Domain(V=lifted, elements=T, kind="planar", columns=3, axes=axes, offset=offset)
