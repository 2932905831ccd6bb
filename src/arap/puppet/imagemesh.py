"""From a picture to a triangle mesh of its shape, for the puppet warp (Igarashi, Moscovich & Hughes 2005).

The shape's outline (:mod:`arap.puppet.outline`), simplified to the mesh's spacing, is triangulated by a
constrained Delaunay triangulation (PythonCDT) together with points of a triangular lattice at that spacing inside
the shape, away from its outline; the triangulation's holes and outside are left out, and so is any triangle whose
centroid falls on a pixel outside the shape (where the simplified outline cuts a corner).

What the mesh guarantees: every triangle's centroid lies on a shape pixel; all triangles turn the same way (none
is folded over); every shape pixel's centre is within one spacing of the mesh, except specks of a few pixels, which
are left out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from arap.errors import ArapError
from arap.puppet.outline import loop_area, outline_loops, shape_mask, simplify_loop
from arap.puppet.picture import PictureError, as_picture

__all__ = ["DEFAULT_DENSITY", "ImageMesh", "default_spacing", "image_mesh", "mesh_of_mask"]

DEFAULT_DENSITY = 5000
"""Vertices of the default mesh of a shape that fills its picture (fewer for a smaller shape)."""

_SPECK = 2.0
"""Loops enclosing less than this many square pixels are left out."""


@dataclass(frozen=True, eq=False)
class ImageMesh:
    """A triangle mesh of a picture's shape.

    Attributes
    ----------
    vertices : (n, 2) float64 array
        Positions in pixel coordinates (x to the right, y down; pixel ``(row, col)`` covers
        ``[col, col + 1) × [row, row + 1)``).
    triangles : (m, 3) int64 array
        All oriented the same way.
    mask : (h, w) bool array
        The shape's pixels.
    spacing : float
        The mesh's edge length, in pixels.

    Examples
    --------
    >>> import numpy as np, arap
    >>> img = np.zeros((40, 60, 4), dtype=np.uint8); img[10:30, 10:50] = 255    # an opaque 40 x 20 rectangle
    >>> mesh = arap.image_mesh(img, spacing=5)
    >>> mesh.size, mesh.vertices.shape[1], bool(mesh.mask[20, 30]), bool(mesh.mask[5, 5])
    ((60, 40), 2, True, False)
    """

    vertices: NDArray[np.float64]
    triangles: NDArray[np.int64]
    mask: NDArray[np.bool_]
    spacing: float

    @property
    def size(self) -> tuple[int, int]:
        """The picture's (width, height)."""
        return int(self.mask.shape[1]), int(self.mask.shape[0])

    @property
    def uv(self) -> NDArray[np.float64]:
        """(n, 2) texture coordinates: the vertices over the picture's size (v down, as the pixels go)."""
        w, h = self.size
        return self.vertices / np.array([w, h], dtype=np.float64)


def default_spacing(width: int, height: int, density: int = DEFAULT_DENSITY) -> float:
    """The spacing of a triangular lattice with about ``density`` points over the whole picture (at least 2 px).

    Example
    -------
    >>> round(default_spacing(1000, 1000), 1)
    15.2
    """
    if not density >= 1:
        raise ArapError(f"density must be at least 1 vertex, got {density}")
    return max(2.0, math.sqrt(2.0 * width * height / (math.sqrt(3.0) * density)))


def _cdt() -> Any:
    try:
        import pythoncdt
    except ImportError:
        raise ArapError("meshing a picture needs PythonCDT: pip install 'arap[image]'") from None
    return pythoncdt


def _edge_pixels(mask: NDArray[np.bool_]) -> NDArray[np.int64]:
    """(k, 2) (row, column) of the background pixels next to the shape (8-neighbours; the frame around the picture
    counts as background, at row or column -1 and h or w)."""
    m = np.pad(mask, 1)
    near = m.copy()
    near[1:, :] |= m[:-1, :]
    near[:-1, :] |= m[1:, :]
    near[:, 1:] |= near[:, :-1].copy()
    near[:, :-1] |= near[:, 1:].copy()
    return np.argwhere(near & ~m) - 1


def _lattice(mask: NDArray[np.bool_], spacing: float) -> NDArray[np.float64]:
    """Points of a triangular lattice at ``spacing`` on shape pixels at least about half a spacing from its edge.

    A pixel's distance to the nearest background pixel (the Euclidean distance transform, with the frame around the
    picture as background) is its distance to the nearest background pixel next to the shape: one step from any
    other towards the pixel is a nearer one. So only the lattice's points are measured, to those edge pixels.
    """
    h, w = mask.shape
    dy = spacing * math.sqrt(3.0) / 2.0
    ys = np.arange(dy / 2, h, dy)
    xs = np.arange(spacing / 2, w + spacing, spacing)
    X = xs[None, :] + (np.arange(len(ys)) % 2)[:, None] * (spacing / 2)
    Y = np.broadcast_to(ys[:, None], X.shape)
    P = np.column_stack([X.ravel(), Y.ravel()])
    P = P[(P[:, 0] < w) & (P[:, 1] < h)]
    r, c = P[:, 1].astype(np.int64), P[:, 0].astype(np.int64)
    P, r, c = P[mask[r, c]], r[mask[r, c]], c[mask[r, c]]
    edge = _edge_pixels(mask)
    if not len(P) or not len(edge):
        return P
    distance, _ = cKDTree(edge).query(np.column_stack([r, c]))
    return P[distance > 0.55 * spacing + 0.5]


def mesh_of_mask(mask: NDArray[np.bool_], spacing: float) -> ImageMesh:
    """A triangle mesh of the mask's shape at ``spacing`` (see the module's description).

    Raises
    ------
    ArapError
        The mask holds no shape larger than a speck.
    """
    mask = np.asarray(mask, dtype=bool)
    if not spacing > 0 or not math.isfinite(spacing):
        raise ArapError(f"spacing must be a positive number of pixels, got {spacing}")
    if not mask.any():
        raise PictureError("the picture's shape is empty: no pixel is opaque (alpha above the threshold) or "
                           "differs from the background")
    tolerance = min(0.4, spacing / 4)  # under half a pixel: a straight edge keeps its line, not its corners' one
    loops = []
    for loop in outline_loops(mask):
        if abs(loop_area(loop)) < _SPECK:
            continue
        simple = simplify_loop(loop, spacing, tolerance)
        if len(simple) >= 3 and abs(loop_area(simple)) > 0.5 * _SPECK:
            loops.append(simple)
    if not loops:
        raise PictureError("the picture's shape is only specks of a few pixels: nothing to mesh")
    boundary = np.concatenate(loops)
    counts = np.array([len(lp) for lp in loops])
    first = np.repeat(np.cumsum(counts) - counts, counts)
    index = np.arange(len(boundary))
    nxt = np.where(index + 1 - first < np.repeat(counts, counts), index + 1, first)
    edges = np.column_stack([index, nxt])
    interior = _lattice(mask, spacing)
    # Outlines of parts one pixel apart may meet once simplified: a point is inserted once, an edge that would join
    # a point to itself is left out.
    points, first_of = np.unique(np.concatenate([boundary, interior]), axis=0, return_inverse=True)
    edges = first_of.reshape(-1)[edges]
    edges = edges[edges[:, 0] != edges[:, 1]]
    cdt = _cdt()
    t = cdt.Triangulation(cdt.VertexInsertionOrder.AUTO, cdt.IntersectingConstraintEdges.TRY_RESOLVE, 0.0)
    t.insert_vertices(np.ascontiguousarray(points, dtype=np.float64))
    t.insert_edges(np.ascontiguousarray(edges, dtype=np.uintc))
    t.erase_outer_triangles_and_holes()
    vv = t.vertices_array()
    V = np.column_stack([vv["x"], vv["y"]]).astype(np.float64)
    F = np.asarray(t.triangles_array()["vertices"], dtype=np.int64).reshape(-1, 3)
    centroid = V[F].mean(axis=1)
    h, w = mask.shape
    r = np.clip(np.floor(centroid[:, 1]).astype(np.int64), 0, h - 1)
    c = np.clip(np.floor(centroid[:, 0]).astype(np.int64), 0, w - 1)
    e1, e2 = V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]
    signed = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    sliver = max(1e-6 * spacing * spacing, 1e-11 * float(h * h + w * w))  # far above the solver's zero area
    F = F[mask[r, c] & (np.abs(signed) > sliver)]
    if len(F) == 0:
        raise PictureError("the picture's shape is too thin to mesh at this spacing; give a smaller spacing")
    used = np.unique(F)
    renumber = np.full(len(V), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    return ImageMesh(vertices=V[used], triangles=renumber[F], mask=mask, spacing=float(spacing))


def image_mesh(image: object, spacing: float | None = None, *, density: int = DEFAULT_DENSITY,
               alpha_threshold: int = 0, background: tuple[int, int, int] | None = None,
               tolerance: float = 0.0) -> ImageMesh:
    """A triangle mesh of a picture's shape, for the puppet warp.

    Parameters
    ----------
    image : (h, w, 3|4) uint8 array or a path
        The picture (a file is read with Pillow: ``pip install 'arap[image]'``).
    spacing : float or None
        Edge length of the mesh in pixels. None: :func:`default_spacing` for ``density``.
    density : int
        Vertices of the mesh when the shape fills the picture (about 5,000 by default); used when ``spacing`` is
        None.
    alpha_threshold : int
        With alpha, the shape is the pixels whose alpha is above this (0 to 254). Without alpha, the whole frame.
    background : (r, g, b) or None
        Leave out the pixels of this colour (within ``tolerance`` per channel), e.g. a plain backdrop.
    tolerance : float
        See ``background``.

    Returns
    -------
    ImageMesh
        Vertices in pixel coordinates (x to the right, y down), with texture coordinates ``uv``.

    Raises
    ------
    ArapError
        An unreadable picture, an empty shape, a bad spacing or option; PythonCDT missing.

    Example
    -------
    >>> import numpy as np, arap
    >>> img = np.zeros((60, 80, 4), dtype=np.uint8); img[10:50, 10:70] = 255
    >>> mesh = arap.image_mesh(img, spacing=8)
    >>> mesh.vertices.shape[1], mesh.size, bool(len(mesh.triangles) > 50)
    (2, (80, 60), True)
    """
    pixels = as_picture(image)
    mask = shape_mask(pixels, alpha_threshold, background, tolerance)
    h, w = mask.shape
    if spacing is None:
        spacing = default_spacing(w, h, density)
    return mesh_of_mask(mask, float(spacing))
