"""A mesh the studio has loaded (:class:`MeshData`: read-only arrays, its name, the repairs made and the file's
vertex numbering) and its export as a mesh file.

Kept apart from :mod:`arap.server.meshdata`, which loads meshes and frames them for the wire, so that a session
(:mod:`arap.server.session`), which holds a mesh but knows nothing of the protocol, needs only this.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from arap.io import formats, save_mesh_bytes

__all__ = ["EXPORT_MIME", "MeshData", "export_mesh"]

EXPORT_MIME = {name: formats.get(name).mime for name in formats.export_names() if formats.get(name).kind == "surface"}
"""Media type of each mesh export format (from :mod:`arap.io.formats`)."""


@dataclass(frozen=True, eq=False)
class MeshData:
    """A loaded mesh (arrays are read-only and may be shared between sessions).

    Attributes
    ----------
    name : str
        Display name.
    V : (n, 3) float64 array
    F : (m, 3) int64 array
        The triangles drawn (and picked): the surface, or the boundary of a solid.
    report : list of str
        Repairs made while loading, one line each.
    vertex_map : (n_file,) int64 array or None
        When repair renumbered the file's vertices (welded or dropped some): the index in :attr:`V` of each vertex
        of the file, -1 for one dropped (:attr:`arap.meshes.repair.RepairResult.vertex_map`). None when the numbering is
        the file's (clean files, built-in models, arrays). Constraints documents use the file's numbering
        (:mod:`arap.server.numbering`).
    elements : (t, 4) int64 array or None
        The tetrahedra of a solid, which the solver deforms (``F`` is then their boundary); None for a surface.
    face_owner : (m,) int64 array or None
        For a solid: the tetrahedron behind each boundary triangle.
    picture : (h, w, 3|4) uint8 array or None
        For a picture opened for the puppet warp (:mod:`arap.server.pictures`): its pixels; the mesh then lies in
        ``z = 0`` at ``(x, h − y)`` pixels and bends in its plane.
    builtin : bool
        The mesh is the built-in model named :attr:`name` (:func:`arap.server.meshdata.load_builtin`), not a file,
        upload, picture or arrays that happen to share a built-in's name.
    """

    name: str
    V: np.ndarray
    F: np.ndarray
    report: list[str] = field(default_factory=list)
    vertex_map: np.ndarray | None = None
    elements: np.ndarray | None = None
    face_owner: np.ndarray | None = None
    picture: np.ndarray | None = None
    builtin: bool = False

    @classmethod
    def solid(cls, name: str, V: np.ndarray, T: np.ndarray, report: list[str] | None = None) -> MeshData:
        """A tetrahedral solid, drawn by its boundary (checked: :func:`arap.check_domain`)."""
        from arap.meshes.domain import boundary_faces_and_owners, check_domain

        domain = check_domain(V, T)
        boundary, owner = boundary_faces_and_owners(domain.elements, domain.V)
        note = (f"a solid of {len(domain.elements):,} tetrahedra, drawn by its {len(boundary):,} boundary triangles; "
                "the solver deforms the tetrahedra")
        mesh = cls.make(name, domain.V, boundary, [*(report or []), note])
        elements = np.array(domain.elements, dtype=np.int64)
        elements.setflags(write=False)
        owner.setflags(write=False)
        return cls(mesh.name, mesh.V, mesh.F, mesh.report, None, elements, owner)

    @property
    def repaired(self) -> bool:
        """Loading named changes to the file (its ``report``: repairs, a solid's boundary), so that point handles of
        a document, which name triangles, do not carry over between it and the file. A picture's mesh is no file's:
        its pins name its own triangles, and its report only describes it."""
        return bool(self.report) and self.picture is None

    @property
    def solve_elements(self) -> np.ndarray:
        """What the solver deforms: the tetrahedra of a solid, else the triangles."""
        return self.F if self.elements is None else self.elements

    @classmethod
    def make(cls, name: str, V: np.ndarray, F: np.ndarray, report: list[str] | None = None,
             vertex_map: np.ndarray | None = None) -> MeshData:
        """Freeze copies of the arrays into a :class:`MeshData` (an identity ``vertex_map`` becomes None)."""
        V = np.array(V, dtype=np.float64)
        F = np.array(F, dtype=np.int64)
        V.setflags(write=False)
        F.setflags(write=False)
        vmap = None
        if vertex_map is not None and not np.array_equal(vertex_map, np.arange(len(V))):
            vmap = np.array(vertex_map, dtype=np.int64)
            if vmap.ndim != 1 or vmap.max(initial=-1) >= len(V) or vmap.min(initial=0) < -1 or \
                    not np.isin(np.arange(len(V)), vmap).all():
                raise ValueError("vertex_map must map the file's vertices onto every mesh vertex (-1: dropped)")
            vmap.setflags(write=False)
        return cls(name, V, F, list(report or []), vmap)

    @property
    def n_file_vertices(self) -> int:
        """Vertices of the mesh file (:attr:`n_vertices` when repair kept the numbering)."""
        return self.n_vertices if self.vertex_map is None else len(self.vertex_map)

    @property
    def n_vertices(self) -> int:
        """Number of vertices."""
        return len(self.V)

    @property
    def n_faces(self) -> int:
        """Number of triangles."""
        return len(self.F)


def export_mesh(name: str, U: np.ndarray, F: np.ndarray, fmt: str) -> tuple[str, str, bytes]:
    """Encode the deformed mesh as a file.

    Returns
    -------
    filename : str
    mime : str
    data : bytes
    """
    return f"{name}-deformed.{fmt}", EXPORT_MIME[fmt], save_mesh_bytes(U, F, fmt)
