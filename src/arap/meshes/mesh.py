"""Triangle mesh validation.

:func:`check_mesh` is the strict gate every solver input goes through: it only converts types and raises
:class:`~arap.errors.MeshError` with a specific message. :func:`arap.meshes.repair.repair_mesh` fixes what can be fixed
(duplicate vertices, degenerate and duplicate faces, unreferenced vertices) and reports what it did. Mesh
description and diagnostics live in :mod:`arap.diagnose`.
"""

from __future__ import annotations

import logging
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from arap.errors import MeshError

__all__ = [
    "DEGENERATE_TOLERANCE",
    "MIN_RELATIVE_SIZE",
    "SIZE_RANGE",
    "WELD_TOLERANCE",
    "MeshLike",
    "bounding_box",
    "check_coordinates",
    "check_integer_indices",
    "check_mesh",
    "check_vertices_and_indices",
    "degenerate_faces",
    "mesh_arrays",
    "triangulate_polygons",
]

logger = logging.getLogger(__name__)

#: A face is degenerate when twice its area is at most this times the squared bounding-box diagonal.
DEGENERATE_TOLERANCE = 1e-12
#: Default distance, relative to the bounding-box diagonal, under which :func:`arap.meshes.repair.repair_mesh` welds
#: vertices.
WELD_TOLERANCE = 1e-9
#: Supported mesh sizes (the longest side of the bounding box). Outside this range squared lengths, areas and the
#: rotation fit's products of covariances leave the range of double precision (overflow or underflow).
SIZE_RANGE = (1e-12, 1e12)
#: Smallest size of a mesh relative to its largest coordinate: a tiny mesh far from the origin has too few
#: significant digits left for its shape.
MIN_RELATIVE_SIZE = 1e-10


# ---------------------------------------------------------------------------------------------- helpers
def _as_vertices(V: np.ndarray) -> np.ndarray:
    V = np.asarray(V)
    if V.dtype == object or not (np.issubdtype(V.dtype, np.floating) or np.issubdtype(V.dtype, np.integer)):
        raise MeshError(f"vertex coordinates must be real numbers, got dtype {V.dtype}")
    if V.ndim != 2 or V.shape[1] != 3:
        raise MeshError(f"vertices must have shape (n, 3), got {V.shape}")
    return np.ascontiguousarray(V, dtype=np.float64)


def check_integer_indices(A: np.ndarray, what: str) -> None:
    """Refuse indices that are not integers (floats holding whole numbers are taken); ``what`` names them."""
    if np.issubdtype(A.dtype, np.floating):
        if not np.all(np.isfinite(A)) or not np.array_equal(A, np.round(A)):
            raise MeshError(f"{what} indices must be integers")
    elif not np.issubdtype(A.dtype, np.integer) or A.dtype == np.bool_:
        raise MeshError(f"{what} indices must be integers, got dtype {A.dtype}")


def _as_faces(F: np.ndarray, allow_polygons: bool = False) -> np.ndarray:
    F = np.asarray(F)
    if F.size == 0 and F.ndim <= 2:
        return np.zeros((0, 3), dtype=np.int64)
    if F.ndim != 2:
        raise MeshError(f"faces must be a 2-d array of vertex indices, got shape {F.shape}")
    check_integer_indices(F, "face")
    if F.shape[1] != 3:
        if allow_polygons and F.shape[1] > 3:
            return triangulate_polygons(F.astype(np.int64))
        if F.shape[1] == 4:
            raise MeshError("faces have 4 vertices (quads); quads must be triangulated first "
                            "(arap.triangulate_polygons, or load the file with arap.load_mesh)")
        raise MeshError(f"faces must be triangles of shape (m, 3), got shape {F.shape}")
    return np.ascontiguousarray(F, dtype=np.int64)


def bounding_box(V: np.ndarray) -> np.ndarray:
    """Minimum and maximum corner of the points ``V`` (n, 3), shape (2, 3).

    Computed one column at a time: NumPy reduces along a 3-wide axis 0 an order of magnitude more slowly on large
    point sets.

    Example
    -------
    >>> bounding_box(np.array([[0.0, 2, 1], [1, -1, 3]])).tolist()
    [[0.0, -1.0, 1.0], [1.0, 2.0, 3.0]]
    """
    columns = range(V.shape[1])
    return np.array([[V[:, j].min() for j in columns], [V[:, j].max() for j in columns]], dtype=np.float64)


def _extent(V: np.ndarray) -> np.ndarray:
    """Bounding-box size of ``V`` (n, 3) (zeros for no point)."""
    if not len(V):
        return np.zeros(V.shape[1])
    box = bounding_box(V)
    return box[1] - box[0]


def _bbox_diagonal(V: np.ndarray) -> float:
    finite = V if np.isfinite(V).all() else V[np.all(np.isfinite(V), axis=1)]
    if not len(finite):
        return 0.0
    return float(np.linalg.norm(_extent(finite)))


def _double_areas(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Twice the area of every face, shape (m,)."""
    from arap.meshes._geometry import (
        double_areas,  # compiled: imported on first use, so that importing this stays light
    )

    return double_areas(V, F)


def coordinate_problem(V: np.ndarray) -> str | None:
    """What is wrong with the scale of finite coordinates (see :func:`check_coordinates`), or None."""
    if not len(V):
        return None
    small, large = SIZE_RANGE
    with np.errstate(over="ignore", invalid="ignore"):
        size = float(np.max(_extent(V)))
    reach = float(np.abs(V).max())
    where = f"coordinates range from {float(V.min()):.3g} to {float(V.max()):.3g}"
    supported = f"meshes from {small:g} to {large:g} across are supported"
    if not size <= large:
        across = f"{size:.3g}" if np.isfinite(size) else "more than 1.8e308"
        return (f"the coordinates are too large: the mesh is {across} across ({where}); {supported}, "
                "so scale it down")
    if size < small:
        return (f"the coordinates are too small: the mesh is only {size:.3g} across ({where}); {supported}, "
                "so scale it up")
    if size < MIN_RELATIVE_SIZE * reach:
        return (f"the mesh is too small for its distance from the origin: it is {size:.3g} across at coordinates "
                f"up to {reach:.3g}, which leaves too few significant digits for its shape (at least "
                f"{MIN_RELATIVE_SIZE:g} of the largest coordinate is needed); move it towards the origin")
    return None


def check_coordinates(V: np.ndarray) -> None:
    """Check that finite vertex positions have a scale the computations can represent.

    Parameters
    ----------
    V : (n, 3) float array
        Finite positions (of the vertices that faces use).

    Raises
    ------
    MeshError
        The mesh is larger or smaller than :data:`SIZE_RANGE` across, or smaller than :data:`MIN_RELATIVE_SIZE`
        times its largest coordinate; the message gives the range of the coordinates.
    """
    problem = coordinate_problem(V)
    if problem is not None:
        raise MeshError(problem)


def _repeated_vertex_faces(F: np.ndarray) -> np.ndarray:
    return (F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])


def triangulate_polygons(faces: np.ndarray | list[list[int]]) -> np.ndarray:
    """Fan-triangulate polygons: ``(a, b, c, d, …)`` becomes ``(a, b, c), (a, c, d), …``.

    Parameters
    ----------
    faces : (m, k) int array with k ≥ 3, or a list of index lists of any lengths ≥ 3

    Returns
    -------
    (t, 3) int64 array
        Triangles, polygon after polygon.
    """
    if isinstance(faces, np.ndarray) and faces.ndim == 2:
        P = faces.astype(np.int64)
        if P.shape[1] < 3:
            raise MeshError(f"polygons need at least 3 vertices, got shape {P.shape}")
        k = P.shape[1]
        tris = np.stack(
            [np.repeat(P[:, :1], k - 2, axis=1), P[:, 1:-1], P[:, 2:]], axis=2
        )
        return tris.reshape(-1, 3)
    out: list[list[int]] = []
    for poly in faces:
        p = [int(i) for i in poly]
        if len(p) < 3:
            raise MeshError(f"a polygon needs at least 3 vertices, got {p}")
        out.extend([p[0], p[i], p[i + 1]] for i in range(1, len(p) - 1))
    return np.asarray(out, dtype=np.int64).reshape(-1, 3)


def check_vertices_and_indices(V: np.ndarray, E: np.ndarray, what: str, one: str) -> None:
    """What every mesh check starts with: vertices and elements present, finite coordinates of a usable scale
    (:func:`check_coordinates`), element indices in range (``what``/``one``: the elements' name, plural and
    singular, for the messages).

    Raises
    ------
    MeshError
    """
    n, m = len(V), len(E)
    if n == 0 or m == 0:
        raise MeshError(f"the mesh is empty ({n} vertices, {m} {what})")
    if not np.isfinite(V).all():
        bad = np.flatnonzero(~np.all(np.isfinite(V), axis=1))
        raise MeshError(f"{len(bad)} vertices have NaN or infinite coordinates (first: vertex {bad[0]})")
    check_coordinates(V)
    if int(E.min()) < 0 or int(E.max()) >= n:
        bad = np.flatnonzero(np.any((E < 0) | (E >= n), axis=1))
        f0 = int(bad[0])
        raise MeshError(f"{len(bad)} {what} have vertex indices out of range [0, {n}) (first: {one} {f0} = "
                        f"{E[f0].tolist()})")


def degenerate_faces(V: np.ndarray, F: np.ndarray, tolerance: float = DEGENERATE_TOLERANCE) -> np.ndarray:
    """Mask of zero-area faces (a repeated vertex, or area below ``tolerance`` relative to the bounding box).

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array, indices in range
    tolerance : float
        Twice the face area must exceed ``tolerance · diag²``, with ``diag`` the bounding-box diagonal.

    Returns
    -------
    (m,) bool array
    """
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    used = np.zeros(len(V), dtype=bool)
    used[F.ravel()] = True
    diag = _bbox_diagonal(V[used] if len(F) else V)
    return _repeated_vertex_faces(F) | (_double_areas(V, F) <= tolerance * diag * diag)


# ---------------------------------------------------------------------------------------------- check
@runtime_checkable
class MeshLike(Protocol):
    """Any triangle mesh object with ``vertices`` (n, 3) and ``faces`` (m, 3), e.g. a ``trimesh.Trimesh``.

    Examples
    --------
    >>> import numpy as np, arap
    >>> class Mesh:
    ...     vertices = np.zeros((3, 3))
    ...     faces = np.array([[0, 1, 2]])
    >>> isinstance(Mesh(), arap.MeshLike), isinstance(np.zeros((3, 3)), arap.MeshLike)
    (True, False)
    """

    @property
    def vertices(self) -> Any: ...

    @property
    def faces(self) -> Any: ...


def is_mesh_like(obj: object) -> bool:
    """Whether ``obj`` is a mesh object (has ``vertices`` and ``faces``) rather than an array."""
    return not isinstance(obj, np.ndarray) and isinstance(obj, MeshLike)


def _type_names(obj: object) -> set[str]:
    """``module.Class`` names of an object's type and its bases (to recognise optional libraries' types without
    importing them)."""
    return {f"{cls.__module__.split('.')[0]}.{cls.__name__}" for cls in type(obj).__mro__}


_FOREIGN = "trimesh.Trimesh or trimesh.Scene, pyvista.PolyData, meshio.Mesh, arap.io.MeshAsset"


def _foreign_mesh(obj: object) -> tuple[np.ndarray, np.ndarray] | None:
    """The arrays of a mesh from another library that has no ``vertices``/``faces`` pair, or None for anything
    else. The libraries are optional: nothing is imported here."""
    names = _type_names(obj)
    mesh: Any = obj
    if "trimesh.Scene" in names:
        parts = [g for g in mesh.dump(concatenate=False) if hasattr(g, "faces") and len(g.faces)]
        if not parts:
            raise MeshError("the trimesh.Scene holds no triangle mesh")
        offsets = np.cumsum([0] + [len(g.vertices) for g in parts[:-1]])
        V = np.concatenate([np.asarray(g.vertices, dtype=np.float64) for g in parts])
        F = np.concatenate([np.asarray(g.faces, dtype=np.int64) + k for g, k in zip(parts, offsets, strict=True)])
        return V, F  # node transforms applied by dump, geometry in the scene's order
    if "pyvista.PolyData" in names:
        if not mesh.is_all_triangles:
            mesh = mesh.triangulate()
        faces = np.asarray(mesh.faces, dtype=np.int64)
        if faces.size == 0:
            raise MeshError("the pyvista.PolyData has no polygons (only points or lines?); a surface is needed")
        if faces.size % 4 or not np.all(faces.reshape(-1, 4)[:, 0] == 3):
            raise MeshError("the pyvista.PolyData's faces are not all triangles after triangulate()")
        return np.asarray(mesh.points), faces.reshape(-1, 4)[:, 1:]
    if any(name.startswith("pyvista.") for name in names):
        raise MeshError(f"a {type(obj).__name__} from pyvista is not a surface mesh: give a pyvista.PolyData "
                        "(for a volume grid, grid.extract_surface())")
    if "meshio.Mesh" in names:
        blocks = [np.asarray(block.data, dtype=np.int64) for block in mesh.cells if block.type == "triangle"]
        if not blocks:
            kinds = sorted({str(block.type) for block in mesh.cells})
            raise MeshError(f"the meshio.Mesh has no triangle cells (it has {', '.join(kinds) or 'no cells'}); "
                            "triangulate it first")
        V = np.asarray(mesh.points)
        if V.ndim == 2 and V.shape[1] == 2:
            raise MeshError("the meshio.Mesh has 2-d points; ARAP surface modeling needs 3-d coordinates")
        return V, np.concatenate(blocks)
    return None


def mesh_arrays(V: np.ndarray | MeshLike | Any, F: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The ``(V, F)`` arrays of a mesh given as arrays or as a mesh object.

    Parameters
    ----------
    V : (n, 3) float array or mesh object
        Vertex positions, or a mesh object: a ``trimesh.Trimesh``, a ``trimesh.Scene`` (its triangle meshes
        concatenated in the scene's order, node transforms applied), a ``pyvista.PolyData`` (triangulated first when
        it has other polygons), a ``meshio.Mesh`` (its ``"triangle"`` cells), an :class:`arap.io.MeshAsset` (file
        numbering; see its ``solve_mesh`` for the welded mesh), or anything with ``vertices`` and ``faces``. None of
        those libraries is needed unless its objects are passed.
    F : (m, 3) int array or None
        Triangles; None when ``V`` is a mesh object.

    Returns
    -------
    V : (n, 3) array
    F : (m, 3) array
        Not yet checked (see :func:`check_mesh`).

    Raises
    ------
    MeshError
        A mesh object together with ``F``, arrays without ``F``, an object of none of these kinds, or one without
        triangles.

    Example
    -------
    >>> import trimesh
    >>> V, F = mesh_arrays(trimesh.creation.box())
    >>> V.shape, F.shape
    ((8, 3), (12, 3))
    """
    foreign = _foreign_mesh(V) if not isinstance(V, np.ndarray) else None
    if foreign is not None or is_mesh_like(V):
        if F is not None:
            raise MeshError("give either a mesh object or the arrays V and F, not both")
        if foreign is not None:
            return foreign
        mesh: Any = V
        return np.asarray(mesh.vertices), np.asarray(mesh.faces)
    if F is None:
        if not isinstance(V, (np.ndarray, list, tuple)):
            raise MeshError(f"cannot take a mesh from a {type(V).__module__}.{type(V).__name__}: give the arrays V "
                            f"and F, or a mesh object ({_FOREIGN}, or anything with vertices and faces)")
        raise MeshError("F (the triangles) is missing: give V and F, or a mesh object with vertices and faces")
    return np.asarray(V), np.asarray(F)


def check_mesh(V: np.ndarray, F: np.ndarray) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Validate a triangle mesh strictly and return it with canonical types.

    Runs in O(n + m) with vectorised NumPy, so it is cheap next to any solve.

    Parameters
    ----------
    V : (n, 3) real array
        Vertex positions.
    F : (m, 3) integer array
        Triangles as vertex indices (0-based).

    Returns
    -------
    V : (n, 3) float64 C-contiguous array
    F : (m, 3) int64 C-contiguous array

    Raises
    ------
    MeshError
        Wrong shapes or dtypes (quads and other polygons must be triangulated), an empty mesh, non-finite
        coordinates, coordinates of an unsupported scale (:func:`check_coordinates`), face indices out of range,
        faces repeating a vertex, zero-area faces.

    Examples
    --------
    >>> import numpy as np, arap
    >>> V, F = arap.check_mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    >>> V.dtype, F.dtype, F.shape
    (dtype('float64'), dtype('int64'), (1, 3))
    """
    V = _as_vertices(V)
    F = _as_faces(F)
    check_vertices_and_indices(V, F, "faces", "face")
    rep = _repeated_vertex_faces(F)
    if rep.any():
        bad = np.flatnonzero(rep)
        f0 = int(bad[0])
        raise MeshError(
            f"{len(bad)} faces repeat a vertex (first: face {f0} = {F[f0].tolist()}); "
            "arap.repair_mesh removes them"
        )
    box = bounding_box(V)
    diag = float(np.linalg.norm(box[1] - box[0]))
    degenerate = _double_areas(V, F) <= DEGENERATE_TOLERANCE * diag * diag
    if degenerate.any():
        bad = np.flatnonzero(degenerate)
        f0 = int(bad[0])
        raise MeshError(
            f"{len(bad)} faces have zero area (first: face {f0} = {F[f0].tolist()}); "
            "arap.repair_mesh removes degenerate faces"
        )
    return V, F
