"""The mesh file's vertex numbering in the constraints documents the studio gives out.

Mesh repair may renumber a file's vertices when it is loaded (:func:`arap.meshes.repair.repair_mesh`: copies of one
vertex are welded, vertices used by no face dropped); the studio works on the repaired mesh. Its constraints documents
are read by ``arap deform`` on the same file, which takes indices as the file's and renumbers them itself
(:meth:`arap.constraints.Constraints.remapped`), so a document the studio gives out lists every vertex as all its file
copies: the fixed vertices, the handles (each copy with the vertex's target), the handle groups, the region of interest
and the painted stiffness. ``arap deform`` then merges the copies back, as they agree.

The other direction (a document read into the studio) happens in the client (``web/src/numbering.js``), which gets
the map with the mesh (the ``mesh`` frame's ``file_vertices``).
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from typing import Any

import numpy as np

from arap.server.mesh_model import MeshData
from arap.server.session_errors import ConstraintsRejected

__all__ = ["FileNumbering", "document_in_file_numbering", "message_in_file_numbering"]


class FileNumbering:
    """The file copies of each mesh vertex, from a repair's vertex map.

    Parameters
    ----------
    vertex_map : (n_file,) int array
        Mesh vertex of each file vertex, -1 for a dropped one (:attr:`MeshData.vertex_map`).
    n_vertices : int
        Vertices of the mesh.

    Examples
    --------
    >>> numbering = FileNumbering(np.array([-1, 0, 1, 0]), 2)
    >>> numbering.copies(np.array([0, 1])).tolist()
    [1, 3, 2]
    """

    def __init__(self, vertex_map: np.ndarray, n_vertices: int) -> None:
        vmap = np.asarray(vertex_map, dtype=np.int64)
        kept = np.flatnonzero(vmap >= 0)
        self.vertex_map = vmap
        self.n_vertices = int(n_vertices)
        self._copies = kept[np.argsort(vmap[kept], kind="stable")]
        self._starts = np.concatenate([[0], np.cumsum(np.bincount(vmap[kept], minlength=self.n_vertices))])

    @property
    def n_file(self) -> int:
        """Vertices of the file."""
        return len(self.vertex_map)

    def counts(self, idx: np.ndarray) -> np.ndarray:
        """How many file vertices each mesh vertex of ``idx`` is (1 unless repair welded copies of it)."""
        idx = np.asarray(idx, dtype=np.int64)
        counts: np.ndarray = self._starts[idx + 1] - self._starts[idx]
        return counts

    def copies(self, idx: np.ndarray) -> np.ndarray:
        """The file vertices of the mesh vertices ``idx``, in their order, each one's copies ascending.

        Parameters
        ----------
        idx : (k,) int array
            Mesh vertices.

        Returns
        -------
        (sum of :meth:`counts`,) int64 array
        """
        idx = np.asarray(idx, dtype=np.int64).reshape(-1)
        counts = self.counts(idx)
        total = int(counts.sum())
        # position of each output within its vertex's copies
        offset = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts)
        files: np.ndarray = self._copies[np.repeat(self._starts[idx], counts) + offset]
        return files

    def stiffness(self, raw: list[Any]) -> list[Any]:
        """Painted stiffness of a document in the file's numbering: ``[{"vertices", "value"}]`` groups list every
        copy; a list of one value per mesh vertex becomes one of the file's length (1 for dropped vertices)."""
        if raw and all(not isinstance(item, Mapping) for item in raw):
            values = list(raw)
            return [1.0 if i < 0 else values[i] for i in self.vertex_map.tolist()]
        return [{"vertices": self.copies(np.asarray(g["vertices"], dtype=np.int64)).tolist(), "value": g["value"]}
                for g in raw]


_VERTEX_MENTIONS = re.compile(r"(?P<lead>\bvertex |\bvertices |\(first: )(?P<idx>\[[0-9, ]*\]|[0-9]+)")
"""Where a constraint or solver message names mesh vertices: ``vertex 12``, ``vertices [3, 4]``, ``(first: 12)``
(a repeated index; "first: item k = i" names a position in a list, not a vertex, and is left alone)."""


def message_in_file_numbering(message: str, mesh: MeshData | None) -> str:
    """A message about the session's constraints that names vertices, with each named as the mesh file numbers it.

    The studio works on the repaired mesh, whose numbering may differ from the file's (see the module's notes);
    the user knows the file's. A vertex that repair welded from several file copies is named as its lowest copy.
    Unchanged when repair kept the numbering, and for indices beyond the mesh (out of range: the index as sent).

    Examples
    --------
    >>> V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    >>> mesh = MeshData.make("m", V, [[0, 1, 2]], ["1 unused vertex removed"], np.array([-1, 0, 1, 2]))
    >>> message_in_file_numbering("vertex 2 is in both fixed and handle group 0", mesh)
    'vertex 3 is in both fixed and handle group 0'
    >>> message_in_file_numbering("undetermined (e.g. vertices [0, 1])", mesh)
    'undetermined (e.g. vertices [1, 2])'
    """
    if mesh is None or mesh.vertex_map is None:
        return message
    numbering = FileNumbering(mesh.vertex_map, mesh.n_vertices)

    def file_index(i: int) -> int:
        if not 0 <= i < numbering.n_vertices:
            return i
        copies = numbering.copies(np.asarray([i], dtype=np.int64))
        return int(copies[0]) if len(copies) else i

    def renumber(match: re.Match[str]) -> str:
        idx = match["idx"]
        if idx.startswith("["):
            items = [int(x) for x in idx[1:-1].replace(",", " ").split()]
            idx = "[" + ", ".join(str(file_index(i)) for i in items) + "]"
        else:
            idx = str(file_index(int(idx)))
        return match["lead"] + idx

    return _VERTEX_MENTIONS.sub(renumber, message)


def _points_refused(mesh: MeshData) -> str:
    repairs = "; ".join(mesh.report)
    return (f"point handles cannot be saved in a constraints document for {mesh.name}: they refer to triangles of "
            f"the mesh as repaired when it was loaded ({repairs}), not to the file's, and arap deform refuses point "
            "handles on a mesh that repair changes; remove the point handles, or repair the mesh file first (arap "
            "info shows what repair changes)")


def document_in_file_numbering(document: dict[str, Any], mesh: MeshData) -> dict[str, Any]:
    """A constraints document of the studio (:meth:`arap.server.constraints.ConstraintSet.document`, in the
    numbering of the mesh the studio works on) in the numbering of the mesh file, as ``arap deform`` reads it.

    Parameters
    ----------
    document : dict
        ``fixed``, ``handles``, ``targets``, ``handle_groups``, optional ``roi``, ``stiffness``, ``points``,
        ``version``.
    mesh : MeshData
        The session's mesh.

    Returns
    -------
    dict
        ``document`` itself when repair kept the numbering; else a new document in which each vertex is listed as
        all its file copies (a handle's target repeated per copy, per-vertex stiffness of the file's length).

    Raises
    ------
    ConstraintsRejected
        For point handles on a mesh that repair changed (:attr:`MeshData.repaired`): they refer to the repaired
        triangles, and ``arap deform`` refuses them on such a mesh.

    Examples
    --------
    >>> V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    >>> mesh = MeshData.make("m", V, [[0, 1, 2]], ["1 unused vertex removed"], np.array([-1, 0, 1, 2]))
    >>> document_in_file_numbering({"fixed": [0], "handles": [2], "targets": [[0.0, 2, 0]],
    ...                             "handle_groups": [[2]]}, mesh)
    {'fixed': [1], 'handles': [3], 'targets': [[0.0, 2, 0]], 'handle_groups': [[3]]}
    """
    if document.get("points") and mesh.repaired:
        raise ConstraintsRejected(_points_refused(mesh))
    if mesh.vertex_map is None:
        return document
    numbering = FileNumbering(mesh.vertex_map, mesh.n_vertices)

    def listed(key: str) -> list[int]:
        files: list[int] = numbering.copies(np.asarray(document[key], dtype=np.int64)).tolist()
        return files

    out = dict(document)
    out["fixed"] = listed("fixed")
    handles = np.asarray(document["handles"], dtype=np.int64)
    out["handles"] = numbering.copies(handles).tolist()
    targets = document["targets"]
    out["targets"] = [t for t, c in zip(targets, numbering.counts(handles).tolist(), strict=True) for _ in range(c)]
    out["handle_groups"] = [numbering.copies(np.asarray(g, dtype=np.int64)).tolist()
                            for g in document["handle_groups"]]
    if document.get("roi") is not None:
        out["roi"] = listed("roi")
    if document.get("stiffness") is not None:
        out["stiffness"] = numbering.stiffness(document["stiffness"])
    return out
