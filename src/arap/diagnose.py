"""Describe a mesh without changing it: counts, components, boundary, defects and weight statistics."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components as _cc

from arap.meshes._weld import _unique_face_mask, _weld_groups
from arap.meshes.mesh import (
    WELD_TOLERANCE,
    _as_faces,
    _as_vertices,
    _bbox_diagonal,
    _repeated_vertex_faces,
    coordinate_problem,
    degenerate_faces,
)
from arap.meshes.topology import directed_half_edges, edge_face_counts, non_manifold_vertices
from arap.method.weights import edge_weight_matrix, face_cotangents

FLAT_ANGLE_DEGREES = 179.0
"""Triangles with an angle above this are reported as nearly flat: their cotangent weights (below about −57) can
make the spokes energies fold or blow up there (a 1e-4-high cap on a sphere sent the shape 31× its size)."""

__all__ = ["FLAT_ANGLE_DEGREES", "MeshInfo", "flat_faces", "inspect_mesh"]


@dataclass
class MeshInfo:
    """Description of a triangle mesh and its defects (see :func:`inspect_mesh`).

    Attributes
    ----------
    n_vertices, n_faces, n_edges : int
    bbox_min, bbox_max : (3,) float64 arrays
        Bounding box of the finite vertices.
    diagonal : float
        Bounding-box diagonal length.
    component_sizes : list of int
        Vertex count of each connected component of the faces, largest first (unreferenced vertices excluded).
    boundary_edges, boundary_loops : int
        Edges used by one face, and the connected chains they form.
    non_manifold_edges : int
        Edges used by more than two faces.
    inconsistent_edges : int
        Edges between two faces that traverse them in the same direction (the faces disagree on orientation).
    misoriented_faces : int
        Fewest faces to flip so that every orientable part is consistently oriented.
    non_orientable_parts : int
        Connected parts (across manifold edges) that no choice of face orientations makes consistent, such as a
        Möbius strip.
    duplicate_vertices : int
        Vertices :func:`arap.meshes.repair.repair_mesh` would weld into an earlier one.
    repeated_vertex_faces, degenerate_faces, duplicate_faces : int
        Faces repeating a vertex, other zero-area faces, and repeated faces.
    unreferenced_vertices, nonfinite_vertices, out_of_range_faces : int
    scale_problem : str or None
        Why the coordinates' scale is unusable (:func:`arap.meshes.mesh.check_coordinates`), or None.
    negative_weight_share : float
        Share of edges whose cotangent weight ``½ Σ cot(opposite angles)`` is negative (0 to 1).
    euler_characteristic : int
        ``V − E + F`` over the referenced vertices.
    nonfinite_faces : int
        Faces using a vertex with non-finite coordinates (left out of the edges, components and surface).
    non_manifold_vertices : int
        Vertices where separate sheets of faces meet at a point (a bow-tie).

    Examples
    --------
    >>> import arap
    >>> V, F = arap.sphere(1)
    >>> info = arap.inspect_mesh(V, F[1:])                 # one triangle cut out
    >>> info.boundary_loops, info.boundary_edges
    (1, 3)
    """

    n_vertices: int
    n_faces: int
    n_edges: int
    bbox_min: np.ndarray
    bbox_max: np.ndarray
    diagonal: float
    component_sizes: list[int]
    boundary_edges: int
    boundary_loops: int
    non_manifold_edges: int
    inconsistent_edges: int
    misoriented_faces: int
    non_orientable_parts: int
    duplicate_vertices: int
    repeated_vertex_faces: int
    degenerate_faces: int
    duplicate_faces: int
    unreferenced_vertices: int
    nonfinite_vertices: int
    out_of_range_faces: int
    scale_problem: str | None
    negative_weight_share: float
    euler_characteristic: int
    nonfinite_faces: int = 0
    """Faces using a vertex with non-finite coordinates: left out of the edges, components and surface above."""
    non_manifold_vertices: int = 0
    """Vertices where separate sheets of faces meet at a point (:func:`arap.meshes.topology.non_manifold_vertices`)."""
    flat_faces: int = 0
    """Faces with an angle above :data:`FLAT_ANGLE_DEGREES` (nearly flat, not degenerate)."""
    lowest_weight: float = 0.0
    """The most negative cotangent edge weight ``½ Σ cot(opposite angles)`` (0 when none is negative)."""

    @property
    def n_components(self) -> int:
        """Number of connected components."""
        return len(self.component_sizes)

    @property
    def closed(self) -> bool:
        """True when every edge has exactly two faces."""
        return (self.boundary_edges == 0 and self.non_manifold_edges == 0 and self.non_manifold_vertices == 0
                and self.n_faces > 0)

    @property
    def problems(self) -> list[str]:
        """Defects, one line each: what :func:`check_mesh` rejects, what :func:`arap.meshes.repair.repair_mesh`
        fixes, and flaws of the surface (non-manifold edges, inconsistent orientation) that ARAP tolerates but a user
        should know."""
        items = [
            (self.nonfinite_vertices, "vertices with NaN or infinite coordinates"
                                      + (f" ({self.nonfinite_faces:,} faces use them; the topology above leaves "
                                         "those faces out)" if self.nonfinite_faces else "")),
            (self.out_of_range_faces, "faces with out-of-range indices"),
            (self.duplicate_vertices, "duplicate vertices"),
            (self.repeated_vertex_faces, "faces repeating a vertex"),
            (self.degenerate_faces, "zero-area faces"),
            (self.duplicate_faces, "duplicate faces"),
            (self.unreferenced_vertices, "vertices used by no face"),
            (self.non_manifold_edges, "non-manifold edges"),
            (self.non_manifold_vertices, "non-manifold vertices (separate sheets meeting at a point)"),
            (self.misoriented_faces, "faces oriented against their neighbours "
                                     f"({self.inconsistent_edges:,} edges where adjacent faces disagree)"),
            (self.non_orientable_parts, "non-orientable parts (like a Möbius strip)"),
        ]
        lines = [f"{count:,} {what}" for count, what in items if count]
        if self.inconsistent_edges and not self.misoriented_faces and not self.non_orientable_parts:
            lines.append(f"{self.inconsistent_edges:,} edges where adjacent faces disagree on orientation")
        if self.scale_problem:
            lines.insert(0, self.scale_problem)
        return lines

    def lines(self) -> list[str]:
        """Human-readable summary, one fact per line."""
        sizes = ", ".join(f"{s:,}" for s in self.component_sizes[:8])
        if len(self.component_sizes) > 8:
            sizes += ", …"
        lo = ", ".join(f"{x:.4g}" for x in self.bbox_min)
        hi = ", ".join(f"{x:.4g}" for x in self.bbox_max)
        shape = "closed" if self.closed else (
            f"open: {self.boundary_edges:,} boundary edges in {self.boundary_loops:,} loops"
            if self.boundary_edges else "not closed"
        )
        out = [
            f"vertices: {self.n_vertices:,}",
            f"faces: {self.n_faces:,}",
            f"edges: {self.n_edges:,}",
            f"bounding box: [{lo}] to [{hi}] (diagonal {self.diagonal:.4g})",
            f"components: {self.n_components:,} ({sizes} vertices)",
            f"surface: {shape}; Euler characteristic {self.euler_characteristic}",
            f"negative cotangent weights: {100 * self.negative_weight_share:.1f}% of edges" + (
                f"; {self.flat_faces:,} nearly flat faces (an angle above {FLAT_ANGLE_DEGREES:g}°, weights down to "
                f"{self.lowest_weight:.3g}), where the spokes energies can fold or blow up: spokes_and_rims (the "
                "default) does not" if self.flat_faces else ""),
        ]
        problems = self.problems
        out.append("defects: " + ("none" if not problems else "; ".join(problems)))
        return out

    def __str__(self) -> str:
        return "\n".join(self.lines())


def _negative_weights(V: np.ndarray, F: np.ndarray) -> tuple[float, float]:
    """Share of undirected edges whose summed cotangent weight is negative, and the most negative weight (or 0)."""
    if not len(F):
        return 0.0, 0.0
    with np.errstate(invalid="ignore"):
        upper = sp.triu(edge_weight_matrix(V, F), k=1).tocsr()
    lowest = float(np.nanmin(upper.data, initial=0.0))
    return float((upper.data < 0).mean()), lowest


def flat_faces(V: np.ndarray, F: np.ndarray) -> int:
    """Number of faces with an angle above :data:`FLAT_ANGLE_DEGREES` (nearly flat triangles of positive area).

    Example
    -------
    >>> V = np.array([[0.0, 0, 0], [2, 0, 0], [1, 1e-3, 0], [1, 1, 0]])
    >>> flat_faces(V, np.array([[0, 1, 2], [0, 1, 3]]))
    1
    """
    if not len(F):
        return 0
    with np.errstate(invalid="ignore", divide="ignore"):
        cot = face_cotangents(np.asarray(V, dtype=np.float64), np.asarray(F))
    return int(np.count_nonzero((cot < 1.0 / np.tan(np.radians(FLAT_ANGLE_DEGREES))).any(axis=1)))


def _orientation(F: np.ndarray) -> tuple[int, int, int]:
    """Orientation defects across manifold edges: ``(inconsistent_edges, misoriented_faces, non_orientable_parts)``.

    Every face gets two nodes, "as stored" and "flipped"; an edge whose two faces agree links like nodes, one where
    they disagree links opposite nodes. A part is orientable when no face's two nodes end up connected, and then
    the smaller of its two node sets is the fewest faces to flip.
    """
    m = len(F)
    if not m:
        return 0, 0, 0
    he = directed_half_edges(F)
    face = np.repeat(np.arange(m, dtype=np.int64), 3)
    forward = he[:, 0] < he[:, 1]
    base = int(he.max()) + 1
    key = np.minimum(he[:, 0], he[:, 1]) * base + np.maximum(he[:, 0], he[:, 1])
    order = np.argsort(key, kind="stable")
    _, start, counts = np.unique(key[order], return_index=True, return_counts=True)
    first = order[start[counts == 2]]
    second = order[start[counts == 2] + 1]
    fa, fb = face[first], face[second]
    disagree = forward[first] == forward[second]
    rows = np.concatenate([fa, fa + m])
    cols = np.concatenate([np.where(disagree, fb + m, fb), np.where(disagree, fb, fb + m)])
    G = sp.coo_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(2 * m, 2 * m))
    _, labels = _cc(G, directed=False)
    kept, flipped = labels[:m], labels[m:]
    twisted = kept == flipped
    non_orientable = len(np.unique(kept[twisted]))
    part = np.minimum(kept, flipped)[~twisted]
    side = (kept < flipped)[~twisted]
    if len(part):
        _, part = np.unique(part, return_inverse=True)
        as_stored = np.bincount(part, weights=side)
        total = np.bincount(part)
        misoriented = int(np.minimum(as_stored, total - as_stored).sum())
    else:
        misoriented = 0
    return int(disagree.sum()), misoriented, non_orientable


def _face_graph(F: np.ndarray, n: int) -> sp.coo_matrix:
    """Vertex graph with one entry per face side (duplicates are harmless for connectivity)."""
    rows = F.ravel()
    cols = np.roll(F, -1, axis=1).ravel()
    return sp.coo_matrix((np.ones(len(rows), dtype=np.int8), (rows, cols)), shape=(n, n))


def _boundary_loops(bedges: np.ndarray, n: int) -> int:
    if not len(bedges):
        return 0
    verts, local = np.unique(bedges, return_inverse=True)
    local = local.reshape(-1, 2)
    k = len(verts)
    G = sp.coo_matrix((np.ones(len(local), dtype=np.int8), (local[:, 0], local[:, 1])), shape=(k, k))
    count, _ = _cc(G, directed=False)
    return int(count)


def _unit_scaled(V: np.ndarray, finite: np.ndarray) -> np.ndarray:
    """``V`` times a power of two that brings its largest finite coordinate near 1 (exact, so every scale-free
    count stays the same, while squared lengths and areas of huge or tiny meshes stay representable)."""
    reach = float(np.abs(V[finite]).max()) if finite.any() else 0.0
    if not 0.0 < reach < np.inf:
        return V
    return V * 2.0 ** -np.frexp(reach)[1]


def inspect_mesh(V: np.ndarray, F: np.ndarray) -> MeshInfo:
    """Describe a mesh and count its defects without changing or rejecting it.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array

    Returns
    -------
    MeshInfo

    Raises
    ------
    MeshError
        Only for arrays of the wrong shape or type.

    Examples
    --------
    >>> import arap
    >>> info = arap.inspect_mesh(*arap.sphere(1))
    >>> info.n_vertices, info.n_faces, info.boundary_loops, info.component_sizes
    (42, 80, 0, [42])
    """
    V = _as_vertices(V)
    F = _as_faces(F)
    n, m = len(V), len(F)
    finite = np.all(np.isfinite(V), axis=1)
    in_range = np.all((F >= 0) & (F < n), axis=1) if m else np.zeros(0, dtype=bool)
    out_of_range = int((~in_range).sum())
    Fv = F[in_range]
    used = np.zeros(n, dtype=bool)
    used[Fv.ravel()] = True  # by any face, also one the topology below leaves out
    with_finite = finite[Fv].all(axis=1) if len(Fv) else np.zeros(0, dtype=bool)
    nonfinite_faces = int((~with_finite).sum())
    Fv = Fv[with_finite]
    referenced = np.zeros(n, dtype=bool)
    referenced[Fv.ravel()] = True
    if finite.any():
        bmin, bmax = V[finite].min(axis=0), V[finite].max(axis=0)
    else:
        bmin = bmax = np.zeros(3)
    with np.errstate(over="ignore", under="ignore"):
        diag = float(np.linalg.norm(bmax - bmin))
    scale_problem = coordinate_problem(V[referenced]) if referenced.any() else None
    V = _unit_scaled(V, finite)

    repeated = _repeated_vertex_faces(Fv)
    degenerate = degenerate_faces(V, Fv) & ~repeated if len(Fv) else np.zeros(0, dtype=bool)
    duplicate = int((~_unique_face_mask(Fv)).sum())
    ref_idx = np.flatnonzero(referenced)
    dup_vertices = 0
    if len(ref_idx):
        rep = _weld_groups(V[ref_idx], WELD_TOLERANCE * _bbox_diagonal(V[ref_idx]))
        dup_vertices = int((rep != np.arange(len(ref_idx))).sum())

    edges, counts = edge_face_counts(Fv)
    bedges = edges[counts == 1]
    if len(ref_idx):
        _, labels = _cc(_face_graph(Fv, n), directed=False)
        sizes = np.bincount(labels[referenced])
        component_sizes = sorted((int(s) for s in sizes if s), reverse=True)
    else:
        component_sizes = []
    good = Fv[~repeated & ~degenerate] if len(Fv) else Fv
    inconsistent, misoriented, non_orientable = _orientation(Fv[~repeated & _unique_face_mask(Fv)])
    negative_share, lowest_weight = _negative_weights(V, good)
    return MeshInfo(
        n_vertices=n,
        n_faces=m,
        n_edges=len(edges),
        bbox_min=bmin,
        bbox_max=bmax,
        diagonal=diag,
        component_sizes=component_sizes,
        boundary_edges=len(bedges),
        boundary_loops=_boundary_loops(bedges, n),
        non_manifold_edges=int((counts > 2).sum()),
        inconsistent_edges=inconsistent,
        misoriented_faces=misoriented,
        non_orientable_parts=non_orientable,
        duplicate_vertices=dup_vertices,
        repeated_vertex_faces=int(repeated.sum()),
        degenerate_faces=int(degenerate.sum()),
        duplicate_faces=duplicate,
        unreferenced_vertices=int(n - used.sum()),
        nonfinite_vertices=int((~finite).sum()),
        out_of_range_faces=out_of_range,
        scale_problem=scale_problem,
        negative_weight_share=negative_share,
        euler_characteristic=int(referenced.sum()) - len(edges) + len(Fv),
        nonfinite_faces=nonfinite_faces,
        non_manifold_vertices=len(non_manifold_vertices(Fv, n)),
        flat_faces=flat_faces(V, good),
        lowest_weight=lowest_weight,
    )
