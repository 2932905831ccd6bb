"""Mesh repair: fix what makes a mesh unusable for ARAP (polygons, duplicate vertices, degenerate and duplicate
faces, unused vertices), report what was done, and carry results back to the input's numbering."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from arap.errors import MeshError
from arap.meshes._weld import _unique_face_mask, _weld_groups
from arap.meshes.mesh import (
    WELD_TOLERANCE,
    _as_faces,
    _as_vertices,
    _bbox_diagonal,
    _repeated_vertex_faces,
    check_coordinates,
    degenerate_faces,
    triangulate_polygons,
)

__all__ = ["RepairResult", "repair_mesh"]

logger = logging.getLogger(__name__)


@dataclass
class RepairResult:
    """Outcome of :func:`repair_mesh`.

    Attributes
    ----------
    V : (n', 3) float64 array
        Repaired vertices, in the order of their first occurrence in the input.
    F : (m', 3) int64 array
        Repaired triangles.
    vertex_map : (n,) int64 array
        New index of every input vertex (welded vertices share one), or -1 for dropped vertices.
    report : list of str
        One human-readable line per repair made; empty when the mesh was already clean.
    counts : dict of str to int
        ``welded_vertices``, ``triangulated_polygons``, ``repeated_vertex_faces``, ``degenerate_faces``,
        ``duplicate_faces``, ``unreferenced_vertices``.
    input_V, input_F : (n, 3) float64 and (m0, 3) int64 arrays, or None
        The input's vertices and triangles (polygons fan-triangulated, nothing dropped), kept when the repair changed
        the vertex numbering (for :meth:`in_input_order`); else None.

    Examples
    --------
    >>> import numpy as np, arap
    >>> V, F = arap.sphere(1)
    >>> result = arap.repair_mesh(np.vstack([V, V[:1]]), F)   # one more vertex, used by no face
    >>> result.report, int(result.vertex_map[-1]), len(result.V)
    (['dropped 1 vertices used by no face'], -1, 42)
    """

    V: np.ndarray
    F: np.ndarray
    vertex_map: np.ndarray
    report: list[str] = field(default_factory=list)
    counts: dict[str, int] = field(default_factory=dict)
    input_V: np.ndarray | None = None
    input_F: np.ndarray | None = None

    @classmethod
    def identity(cls, V: np.ndarray, F: np.ndarray | None = None) -> RepairResult:
        """The result of no repair: ``V`` and ``F`` as they are (``F`` None: no triangles), every vertex kept."""
        faces = np.zeros((0, 3), dtype=np.int64) if F is None else F
        return cls(V=V, F=faces, vertex_map=np.arange(len(V), dtype=np.int64))

    @property
    def renumbers(self) -> bool:
        """True if the repaired vertices are not the input's in the same order (welded or dropped vertices)."""
        return not np.array_equal(self.vertex_map, np.arange(len(self.vertex_map)))

    def in_input_order(self, U: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Positions of the repaired vertices carried back to the input's vertices, with the input's triangles.

        Each input vertex takes the position of the repaired vertex it became (a welded copy keeps its small offset
        from the vertex it was welded to). A vertex used only by dropped faces (a zero-area sliver, a face repeating
        a vertex) follows the kept vertices of such a face (on their segment where it lay on it, else at its offset
        from one of them), so the written faces make no spike back to the rest pose; a vertex no face uses keeps its
        input position. So a deformed mesh can be written with the vertex order and count of the file it came from.

        Parameters
        ----------
        U : (n', 3) float array
            Positions of the repaired vertices (e.g. a deformation of :attr:`V`).

        Returns
        -------
        (V, F) or None
            (n, 3) positions and the input's (m0, 3) triangles; ``(U, F)`` when the repair kept the numbering. None
            when a dropped vertex has non-finite coordinates (it cannot be written).

        Example
        -------
        >>> r = repair_mesh(np.array([[9.0, 9, 9], [0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[1, 2, 3]]))
        >>> V, F = r.in_input_order(r.V + 1.0)
        >>> V.tolist(), F.tolist()
        ([[9.0, 9.0, 9.0], [1.0, 1.0, 1.0], [2.0, 1.0, 1.0], [1.0, 2.0, 1.0]], [[1, 2, 3]])
        """
        if self.input_V is None or self.input_F is None:
            return U, self.F
        kept = self.vertex_map >= 0
        if not np.isfinite(self.input_V[~kept]).all():
            return None
        out = self.input_V.copy()
        to = self.vertex_map[kept]
        out[kept] = U[to] + (self.input_V[kept] - self.V[to])
        _follow_kept_corners(out, self.input_V, self.input_F, kept)
        return out, self.input_F

    @property
    def changed(self) -> bool:
        """True if anything was repaired."""
        return any(self.counts.values())


def _follow_kept_corners(out: np.ndarray, V: np.ndarray, F: np.ndarray, kept: np.ndarray) -> None:
    """Move (in ``out``) the dropped vertices of faces that also have kept vertices with those: a vertex between
    two kept corners ``a``, ``b`` of a face keeps its parameter ``t`` along ``a → b`` (and its small offset from that
    line), one beside a single kept corner its offset from it. ``V`` are the rest positions, ``out`` the positions
    of the kept vertices already carried over."""
    K = kept[F]
    rows = np.flatnonzero(~K.all(axis=1) & K.any(axis=1))
    if not len(rows):
        return
    G, K = F[rows], K[rows]
    n_kept = K.sum(axis=1)
    for count in (1, 2):  # a face with two kept corners places its vertex last, so it wins over one with one
        for c in range(3):
            sel = ~K[:, c] & (n_kept == count)
            if not sel.any():
                continue
            p, o1, o2 = G[sel, c], G[sel, (c + 1) % 3], G[sel, (c + 2) % 3]
            if count == 1:
                a = np.where(K[sel, (c + 1) % 3], o1, o2)
                out[p] = out[a] + (V[p] - V[a])
                continue
            d = V[o2] - V[o1]
            dd = np.einsum("ij,ij->i", d, d)
            t = np.divide(np.einsum("ij,ij->i", V[p] - V[o1], d), dd, out=np.zeros(len(p)), where=dd > 0)[:, None]
            out[p] = out[o1] + t * (out[o2] - out[o1]) + (V[p] - (V[o1] + t * d))


def repair_mesh(
    V: np.ndarray, polygons: np.ndarray | list[list[int]], *, weld_tolerance: float = WELD_TOLERANCE
) -> RepairResult:
    """Fix the defects that make a mesh unusable for ARAP, keeping everything else as it is.

    In order: polygons are fan-triangulated, vertices closer than ``weld_tolerance · diag`` are welded
    (the first occurrence is kept, so a clean mesh keeps its indices), faces repeating a vertex, zero-area
    faces and duplicate faces (same three vertices, either orientation; the first is kept) are dropped, and
    vertices used by no face are dropped. The result passes :func:`check_mesh`.

    Parameters
    ----------
    V : (n, 3) float array
    polygons : (m, 3) int array of triangles, (m, k) int array of polygons, or a list of polygons
    weld_tolerance : float
        Welding distance relative to the bounding-box diagonal of the referenced vertices; 0 welds exact
        duplicates only.

    Returns
    -------
    RepairResult

    Raises
    ------
    MeshError
        Faces use non-finite vertices or out-of-range indices, the coordinates have an unsupported scale
        (:func:`check_coordinates`), or no valid face remains.

    Examples
    --------
    A quad and a vertex no face uses:

    >>> import numpy as np, arap
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [9, 9, 9]], dtype=float)
    >>> repaired = arap.repair_mesh(V, [[0, 1, 2, 3]])
    >>> repaired.F.shape, len(repaired.V), repaired.counts["triangulated_polygons"]
    ((2, 3), 4, 1)
    """
    V = _as_vertices(V)
    n_polygons = len(polygons)
    if isinstance(polygons, np.ndarray):
        F = _as_faces(polygons, allow_polygons=True)
    else:
        F = triangulate_polygons(polygons) if n_polygons else np.zeros((0, 3), dtype=np.int64)
    n = len(V)
    F_input = F
    counts = {
        "triangulated_polygons": int(len(F) - n_polygons),
        "welded_vertices": 0,
        "repeated_vertex_faces": 0,
        "degenerate_faces": 0,
        "duplicate_faces": 0,
        "unreferenced_vertices": 0,
    }
    report: list[str] = []
    if len(F) and (F.min() < 0 or F.max() >= n):
        bad = np.flatnonzero(np.any((F < 0) | (F >= n), axis=1))
        raise MeshError(f"{len(bad)} faces have vertex indices out of range [0, {n}) (first: face {bad[0]}); "
                        "this cannot be repaired")
    finite = np.all(np.isfinite(V), axis=1) if not np.isfinite(V).all() else None
    used_bad = ~finite[F].all(axis=1) if finite is not None and len(F) else np.zeros(0, dtype=bool)
    if finite is not None and used_bad.any():
        bad_v = np.flatnonzero(~finite)
        raise MeshError(f"{int((~finite).sum())} vertices have NaN or infinite coordinates (first: vertex "
                        f"{bad_v[0]}) and {int(used_bad.sum())} faces use them; this cannot be repaired")

    referenced = np.zeros(n, dtype=bool)
    referenced[F.ravel()] = True
    check_coordinates(V[referenced])
    diag = _bbox_diagonal(V[referenced]) if referenced.any() else 0.0
    # Weld among referenced vertices only; unreferenced ones are dropped below anyway.
    ref_idx = np.flatnonzero(referenced)
    rep = np.arange(n, dtype=np.int64)
    if len(ref_idx):
        rep[ref_idx] = ref_idx[_weld_groups(V[ref_idx], weld_tolerance * diag)]
    counts["welded_vertices"] = int((rep[ref_idx] != ref_idx).sum())
    F = rep[F]

    keep = ~_repeated_vertex_faces(F)
    counts["repeated_vertex_faces"] = int((~keep).sum())
    F = F[keep]
    for _ in range(8):
        degenerate = degenerate_faces(V, F) if len(F) else np.zeros(0, dtype=bool)
        if not degenerate.any():
            break
        counts["degenerate_faces"] += int(degenerate.sum())
        F = F[~degenerate]
    keep = _unique_face_mask(F)
    counts["duplicate_faces"] = int((~keep).sum())
    F = F[keep]
    if not len(F):
        raise MeshError("no valid face remains after removing degenerate and duplicate faces")

    used = np.zeros(n, dtype=bool)
    used[F.ravel()] = True
    new_index = np.full(n, -1, dtype=np.int64)
    new_index[used] = np.arange(int(used.sum()))
    vertex_map = new_index[rep]
    counts["unreferenced_vertices"] = int(n - used.sum() - counts["welded_vertices"])
    V_out = np.ascontiguousarray(V[used])
    F_out = np.ascontiguousarray(new_index[F])

    messages = {
        "triangulated_polygons": "split polygons into triangles ({} extra faces)",
        "welded_vertices": "welded {} vertices sharing a position with another (seams of UVs or normals, or a "
                           "soup's copies; the file's numbering is kept)",
        "repeated_vertex_faces": "dropped {} faces repeating a vertex",
        "degenerate_faces": "dropped {} zero-area faces",
        "duplicate_faces": "dropped {} duplicate faces",
        "unreferenced_vertices": "dropped {} vertices used by no face",
    }
    for key, template in messages.items():
        if counts[key]:
            report.append(template.format(f"{counts[key]:,}"))
    if report:
        logger.info("repaired mesh: %s", "; ".join(report))
    result = RepairResult(V=V_out, F=F_out, vertex_map=vertex_map, report=report, counts=counts)
    if result.renumbers:
        result.input_V, result.input_F = V, F_input
    return result
