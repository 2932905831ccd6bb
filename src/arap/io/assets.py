"""Textured models in, textured models out: what a deformation does not change, kept beside the positions.

A :class:`MeshAsset` holds a mesh file's vertex positions in the file's own numbering, its triangles, and everything
else the file says about the surface: texture coordinates and normals per corner, vertex colours, materials and their
texture images, groups and objects, and for glTF the whole scene (nodes, meshes, primitives, accessors, buffers).
:func:`load_asset` reads one from an OBJ (with its MTL files and textures), PLY or glTF/GLB file, and
:func:`save_asset` writes it back with new positions: the normals are recomputed for the new shape and every other
attribute is written back bit-identical.

Vertex numbering
----------------
``asset.vertices`` are numbered as the file numbers them: the order of the ``v`` lines of an OBJ, the vertex element
of a PLY, and for glTF the POSITION accessors of the triangle primitives, each accessor once, in the order the meshes
and their primitives first name them (several primitives concatenated in order). glTF positions are given in the
scene's coordinates: the transform of the first node showing the mesh is applied (and undone when writing).

Seams
-----
A glTF file (and some OBJ and PLY writers) repeats a vertex wherever its texture coordinates or normals differ on
either side of a seam, which would cut the surface into pieces for the solver. :meth:`MeshAsset.solve_mesh` welds the
vertices at bit-identical positions into one, keeping the first copy's place in the order: the solver sees one
connected mesh, :meth:`SolveMesh.constraints` takes constraint indices in file numbering (any copy of a seam vertex
names the welded one), and :meth:`SolveMesh.file_vertices` (or :func:`save_asset`, which accepts either numbering)
splits the solved positions again for writing: every copy moves with its welded vertex.

Formats
-------
The reader, the writer and the upload hint of each textured format are named by its record in
:mod:`arap.io.formats` (``asset_reader``, ``asset_writer``, ``asset_hint``), and this module calls them from there:
adding a textured format is adding its record and the module that reads and writes it, which builds its
:class:`MeshAsset` with the pieces this module shares (:func:`weld_rows`, :func:`group_normals`,
:func:`vertex_normal_groups`, :func:`fan`, :func:`read_referenced`, :func:`write_beside`).

Bundles
-------
A model with the files it names may come as one zip (the studio's uploads): :func:`read_bundle` checks and reads it,
:func:`bundle_mesh_name` finds its mesh file and :func:`unpacked_bundle` lays it out where the readers find the files.

Normals
-------
A deformed surface needs new normals. They are recomputed per normal *group*, the corners that shared one normal in
the file at one vertex (same position and, for OBJ, the same ``vn`` index; for glTF and PLY, the same normal
value): each group gets the normalised sum of the area-weighted normals of the triangles at its corners. Smooth
shading stays smooth, flat and hard edges stay flat and hard, and a normal shared by far-apart vertices becomes one
per vertex (OBJ ``vn`` lines are then written once per group).
"""

from __future__ import annotations

import logging
import os
import posixpath
import stat
import tempfile
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

import arap.io.formats as formats
from arap.errors import ConstraintError, MeshError, MeshFormatError
from arap.io.paths import read_regular_file

if TYPE_CHECKING:
    import trimesh

__all__ = ["ASSET_FORMATS", "MAX_BUNDLE_FILES", "MAX_TEXTURE_PIXELS", "MeshAsset", "SolveMesh", "asset_format",
           "bundle_mesh_name", "face_normals", "fan", "group_normals", "load_asset", "load_asset_bytes",
           "may_have_attributes", "missing_file_warning", "read_bundle", "read_referenced", "result_trimesh",
           "save_asset", "unpacked_bundle", "vertex_normal_groups", "weld_rows", "write_beside"]

logger = logging.getLogger(__name__)

#: Most pixels of a texture image decoded (for :func:`result_trimesh`); a larger one is left out.
MAX_TEXTURE_PIXELS = 1 << 27

#: File types :func:`load_asset` reads and :func:`save_asset` writes with their attributes (the surface formats of
#: :mod:`arap.io.formats` with an asset reader and writer).
ASSET_FORMATS = formats.names("surface", asset=True)

#: Most files a bundle (a zip of a mesh file with the files it names) may hold.
MAX_BUNDLE_FILES = 256


# ---------------------------------------------------------------------------------------------- the record
def asset_format(name: str | os.PathLike[str]) -> str:
    """The asset format of a file name or a bare type name (``"model.GLB"``, ``".glb"``, ``"glb"``).

    Raises
    ------
    MeshFormatError
        Not a format whose attributes :func:`load_asset` keeps.
    """
    return _asset_record(name).name


def _asset_record(name: str | os.PathLike[str]) -> formats.FileFormat:
    """The :mod:`arap.io.formats` record of the asset format of a file name or a bare type name."""
    found = formats.find(name, "surface")
    if found is None or not found.asset:
        text = str(name).strip()
        raise MeshFormatError(f"unsupported textured mesh format {formats.suffix_of(text)[1:]!r} (from {text!r}); "
                              f"supported: {', '.join(formats.names('surface', asset=True))}")
    return found


@dataclass(eq=False)
class SolveMesh:
    """The welded mesh a solver sees, and the way back to the file's numbering (see the module notes on seams).

    Attributes
    ----------
    V : (k, 3) float64 array
        One vertex per distinct position of the file's vertices, in the order of their first copies.
    F : (m, 3) int64 array
        The asset's triangles on the welded vertices.
    to_solve : (n,) int64 array
        For each file vertex, its welded vertex.
    to_file : (k,) int64 array
        For each welded vertex, its first copy in the file.

    Examples
    --------
    >>> import numpy as np
    >>> from arap.io import MeshAsset
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    >>> asset = MeshAsset("obj", V, np.array([[0, 1, 2], [3, 4, 5]]))
    >>> welded = asset.solve_mesh()
    >>> welded.V.shape, welded.to_solve.tolist(), welded.to_file.tolist()
    ((4, 3), [0, 1, 2, 1, 3, 2], [0, 1, 2, 4])
    """

    V: NDArray[np.float64]
    F: NDArray[np.int64]
    to_solve: NDArray[np.int64]
    to_file: NDArray[np.int64]

    def constraints(self, indices: Any, targets: Any = None) -> tuple[NDArray[np.int64], NDArray[np.float64] | None]:
        """Constraint indices in file numbering (and their targets) as welded indices for the solver.

        Copies of one seam vertex name the same welded vertex; they may be listed together only with the same
        target.

        Raises
        ------
        ConstraintError
            An index out of range of the file's vertices, or two copies of one vertex with different targets.
        """
        idx = np.asarray(indices).reshape(-1)
        if idx.size and not np.issubdtype(idx.dtype, np.integer):
            raise ConstraintError(f"constraint indices must be integers, got dtype {idx.dtype}")
        idx = idx.astype(np.int64)
        n = len(self.to_solve)
        bad = (idx < 0) | (idx >= n)
        if bad.any():
            raise ConstraintError(f"constraint index {int(idx[bad][0])} is out of range: the file has {n:,} vertices")
        welded = self.to_solve[idx]
        _, first, inverse = np.unique(welded, return_index=True, return_inverse=True)
        inverse = inverse.reshape(-1)
        order = np.sort(first)  # the first listing of each welded vertex, in the order given
        if targets is None:
            return welded[order], None
        X = np.asarray(targets, dtype=np.float64)
        if X.shape != (len(idx), 3):
            raise ConstraintError(f"targets must have shape ({len(idx)}, 3), got {X.shape}")
        same = first[inverse]
        differ = np.any(X != X[same], axis=1)
        if differ.any():
            i = int(np.flatnonzero(differ)[0])
            raise ConstraintError(f"vertices {int(idx[same[i]])} and {int(idx[i])} of the file are one vertex "
                                  "(copies at a seam) but have different targets")
        return welded[order], X[order]

    def file_vertices(self, V: Any) -> NDArray[np.float64]:
        """Solved positions (welded numbering) for every file vertex: each copy of a seam vertex gets its position."""
        V = np.asarray(V, dtype=np.float64)
        if V.shape != self.V.shape:
            raise MeshError(f"expected positions of shape {self.V.shape} (the welded mesh), got {V.shape}")
        return V[self.to_solve]


@dataclass(eq=False)
class MeshAsset:
    """A mesh file's geometry with everything a deformation leaves as it is (see the module notes).

    Attributes
    ----------
    format : {"obj", "ply", "glb", "gltf"}
        The file type it was read from (and is written as; glTF and GLB convert into each other).
    vertices : (n, 3) float64 array
        Positions, in the file's vertex numbering (glTF: node transforms applied).
    faces : (m, 3) int64 array
        Triangles in that numbering; polygons are fan-triangulated (and written back as polygons).
    materials : list of str
        Material names (OBJ ``usemtl``, glTF materials), in the order faces first use them.
    face_materials : (m,) int64 array
        Each triangle's index into ``materials``, -1 for none.
    groups : list of str
        Group names (OBJ ``g``; glTF mesh names; empty for PLY).
    face_groups : (m,) int64 array
        Each triangle's index into ``groups``, -1 for none.
    uvs : (m, 3, 2) float64 array or None
        Texture coordinates of each triangle's corners (the first set), as stored; None without any.
    vertex_colors : (n, k) array or None
        Colours per vertex, with the file's type (PLY ``red green blue [alpha]``, OBJ ``v x y z r g b``, glTF
        COLOR_0 of the first primitive naming the vertex).
    textures : dict of str to bytes
        Texture images: OBJ and PLY by the reference the MTL file (or PLY comment) gives, glTF by image name or
        URI (``image<i>`` for unnamed embedded ones). A texture file that is missing is not in it (a warning says
        so when loading) but its reference is kept.
    source : Path or None
        The file it was read from.
    data : object
        The format's own record that writing needs (``arap.io.obj_asset.ObjData``, ``arap.io.ply_asset.PlyData``,
        ``arap.io.gltf_asset.GltfData``).

    Examples
    --------
    Two triangles of a square, each with its own copies of the shared corners (a texture seam):

    >>> import os, tempfile, arap
    >>> obj = ("v 0 0 0\\nv 1 0 0\\nv 0 1 0\\nv 1 0 0\\nv 1 1 0\\nv 0 1 0\\n"
    ...        "vt 0 0\\nvt 1 0\\nvt 0 1\\nvt 1 1\\nf 1/1 2/2 3/3\\nf 4/2 5/4 6/3\\n")
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "square.obj")
    ...     with open(path, "w") as file:
    ...         _ = file.write(obj)
    ...     asset = arap.load_asset(path)
    >>> asset.format, asset.vertices.shape, asset.uvs.shape
    ('obj', (6, 3), (2, 3, 2))
    >>> len(asset.solve_mesh().V)                             # the corners the two triangles share are welded
    4
    """

    format: str
    vertices: NDArray[np.float64]
    faces: NDArray[np.int64]
    materials: list[str] = field(default_factory=list)
    face_materials: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    groups: list[str] = field(default_factory=list)
    face_groups: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    uvs: NDArray[np.float64] | None = None
    vertex_colors: NDArray[Any] | None = None
    textures: dict[str, bytes] = field(default_factory=dict)
    source: Path | None = None
    data: Any = None
    _solve: SolveMesh | None = field(default=None, init=False, repr=False)

    def solve_mesh(self) -> SolveMesh:
        """The welded mesh for a solver (vertices at bit-identical positions made one, 0.0 and -0.0 alike), with
        the maps to and from the file's numbering; computed once."""
        if self._solve is None:
            to_solve, to_file = weld_rows(self.vertices + 0.0)  # -0.0 becomes 0.0: the same position
            self._solve = SolveMesh(V=self.vertices[to_file], F=to_solve[self.faces], to_solve=to_solve,
                                    to_file=to_file)
        return self._solve

    def file_positions(self, vertices: Any) -> NDArray[np.float64]:
        """``vertices`` in file numbering: given for every file vertex, or for every welded vertex of
        :meth:`solve_mesh` (then split again over the seams)."""
        V = np.asarray(vertices, dtype=np.float64)
        if V.ndim != 2 or V.shape[1] != 3:
            raise MeshError(f"vertices must have shape (n, 3), got {V.shape}")
        if len(V) == len(self.vertices):
            out = V
        elif len(V) == len(self.solve_mesh().V):
            out = self.solve_mesh().file_vertices(V)
        else:
            raise MeshError(f"{len(V):,} positions given for a mesh of {len(self.vertices):,} file vertices "
                            f"({len(self.solve_mesh().V):,} once welded)")
        if not np.isfinite(out).all():
            raise MeshError("positions with NaN or infinite coordinates; the file is not written")
        return np.ascontiguousarray(out)

    def to_trimesh(self, vertices: Any = None) -> trimesh.Trimesh:
        """A ``trimesh.Trimesh`` of the asset (or of ``vertices`` on it, see :meth:`file_positions`), with its
        texture (the first UV set and the first texture image) or vertex colours when it has them."""
        return result_trimesh(self.vertices if vertices is None else vertices, self)


# ---------------------------------------------------------------------------------------------- entry points
def load_asset_bytes(data: bytes, file_type: str, *, name: str = "uploaded mesh",
                     folder: str | os.PathLike[str] | None = None,
                     max_vertices: int | None = None) -> MeshAsset:
    """Read a textured mesh from the bytes of a file; see :func:`load_asset`.

    Parameters
    ----------
    folder : path-like or None
        Where files the mesh names (MTL files, textures, glTF buffers) are looked for; None: nowhere (they are
        missing, with a warning; a glTF buffer that cannot be read is an error).
    """
    read = _asset_record(file_type).function("asset_reader")
    assert read is not None  # an asset format has an asset reader
    asset: MeshAsset = read(bytes(data), name, Path(folder) if folder is not None else None, max_vertices)
    return asset


def may_have_attributes(data: bytes, file_type: str) -> bool:
    """Whether the bytes of a mesh file may hold anything :func:`load_asset_bytes` keeps beyond the geometry
    (texture coordinates with a material file, colours, a glTF scene): a cheap look at the bytes by the format's
    ``asset_hint`` (:mod:`arap.io.formats`; a format without one always may). False for a format whose attributes
    are not kept."""
    found = formats.find(file_type, "surface")
    if found is None or not found.asset:
        return False
    hint = found.function("asset_hint")
    return hint is None or bool(hint(bytes(data)))


def load_asset(path: str | os.PathLike[str], *, max_vertices: int | None = None) -> MeshAsset:
    """Read a textured mesh file: OBJ (with its MTL files and textures), PLY, glTF or GLB.

    Parameters
    ----------
    path : path-like
    max_vertices : int or None
        Largest accepted vertex count.

    Returns
    -------
    MeshAsset
        Positions in the file's vertex numbering; see :meth:`MeshAsset.solve_mesh` for the welded mesh to solve.

    Raises
    ------
    MeshFormatError
        Unknown extension, an unreadable or malformed file, compressed glTF (Draco, meshopt), sparse or quantized
        positions, a path that is not a regular file.

    Warns
    -----
    UserWarning
        An MTL file or texture image the file names cannot be read, or may not be: only regular files inside the
        file's own folder are read (:func:`arap.io.paths.read_reference`); the mesh loads without it (its reference
        is kept for writing). A glTF buffer that cannot be read is a :class:`MeshFormatError`.

    Examples
    --------
    >>> import os, tempfile, arap
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "triangle.obj")
    ...     with open(path, "w") as file:
    ...         _ = file.write("v 0 0 0\\nv 1 0 0\\nv 0 1 0\\nvt 0 0\\nvt 1 0\\nvt 0 1\\nf 1/1 2/2 3/3\\n")
    ...     asset = arap.load_asset(path)
    >>> asset.format, asset.faces.tolist(), asset.uvs[0].tolist()
    ('obj', [[0, 1, 2]], [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    """
    path = Path(path)
    if path.is_dir():
        raise MeshFormatError(f"{path} is a folder, not a mesh file")
    ft = asset_format(path.name)
    try:
        data = read_regular_file(path)
    except OSError as exc:
        raise MeshFormatError(f"cannot read {path}: {exc.strerror or exc}") from exc
    asset = load_asset_bytes(data, ft, name=str(path), folder=path.parent, max_vertices=max_vertices)
    asset.source = path
    return asset


def save_asset(path: str | os.PathLike[str], asset: MeshAsset, vertices: Any = None) -> list[Path]:
    """Write a textured mesh with new positions; every attribute but positions and normals is kept bit-identical.

    OBJ writes an MTL file beside it (``NAME.mtl``, its content unchanged) and the texture images its references
    name, relative to it, where they are not there yet. glTF writes its external buffers beside it
    (``NAME.bin``); GLB embeds them. Every file is written atomically (:mod:`arap.io.atomic`).

    Parameters
    ----------
    path : path-like
        The extension picks the format: the asset's own (``.glb`` and ``.gltf`` convert into each other).
    asset : MeshAsset
    vertices : (n, 3) or (k, 3) float array or None
        New positions in file numbering, or for the welded vertices of :meth:`MeshAsset.solve_mesh`; None writes
        the asset's own positions and normals.

    Returns
    -------
    list of Path
        The files written, the mesh first.

    Raises
    ------
    MeshFormatError
        An extension of another format, a destination that is not a regular file, a write that fails.
    MeshError
        Positions of the wrong shape or not finite.

    Examples
    --------
    >>> import os, tempfile, arap
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     source = os.path.join(folder, "triangle.obj")
    ...     with open(source, "w") as file:
    ...         _ = file.write("v 0 0 0\\nv 1 0 0\\nv 0 1 0\\nvt 0 0\\nvt 1 0\\nvt 0 1\\nf 1/1 2/2 3/3\\n")
    ...     asset = arap.load_asset(source)
    ...     written = arap.save_asset(os.path.join(folder, "moved.obj"), asset, asset.vertices * 2)
    ...     again = arap.load_asset(written[0])
    >>> again.vertices[2].tolist(), again.uvs[0, 2].tolist()   # new positions, the same texture coordinates
    ([0.0, 2.0, 0.0], [0.0, 1.0])
    """
    path = Path(path)
    fmt = _asset_record(path.name)
    family = formats.family(asset.format)
    if formats.family(fmt.name) != family:
        raise MeshFormatError(f"{path}: a textured {asset.format.upper()} mesh is written as "
                              f"{'GLB or glTF' if family == 'gltf' else asset.format.upper()} "
                              "(save_mesh writes its geometry in any format)")
    V = None if vertices is None else asset.file_positions(vertices)
    write = fmt.function("asset_writer")
    assert write is not None  # an asset format has an asset writer
    try:
        written: list[Path] = write(path, asset, V)
        return written
    except OSError as exc:
        raise MeshFormatError(f"cannot write {path}: {exc.strerror or exc}") from exc


# ---------------------------------------------------------------------------------------------- shared helpers
def weld_rows(A: NDArray[Any]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Group equal rows of ``A`` (bitwise, -0.0 and 0.0 apart), numbered in the order of their first occurrence.

    Rows are hashed to 64 bits and sorted by hash; rows found equal by their hash are compared in full, and a
    collision (never seen in practice) falls back to an exact :func:`numpy.unique`.

    Returns
    -------
    inverse : (n,) int64 array
        Each row's group.
    first : (k,) int64 array
        Each group's first row.
    """
    A = np.ascontiguousarray(A)
    n = len(A)
    if n == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    raw = A.view(np.uint8).reshape(n, -1)
    words = raw.view(np.uint64) if raw.shape[1] % 8 == 0 else raw.view(np.uint32) if raw.shape[1] % 4 == 0 else raw
    with np.errstate(over="ignore"):
        h = words[:, 0].astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15)
        for j in range(1, words.shape[1]):
            h ^= h >> np.uint64(31)
            h = (h ^ words[:, j].astype(np.uint64)) * np.uint64(0xBF58476D1CE4E5B9)
        h ^= h >> np.uint64(29)
    order = np.argsort(h)
    hs = h[order]
    starts = np.ones(n, dtype=bool)
    starts[1:] = hs[1:] != hs[:-1]
    begin = np.flatnonzero(starts)
    group_sorted = np.cumsum(starts) - 1
    first_of_group = np.minimum.reduceat(order, begin)
    if not np.array_equal(words[order], words[first_of_group[group_sorted]]):  # a collision: exact grouping
        _, first_u, inverse_u = np.unique(words, axis=0, return_index=True, return_inverse=True)
        rank = np.empty(len(first_u), dtype=np.int64)
        rank[np.argsort(first_u)] = np.arange(len(first_u))
        return rank[inverse_u.reshape(-1)], np.sort(first_u).astype(np.int64)
    by_first = np.argsort(first_of_group)
    rank = np.empty(len(begin), dtype=np.int64)
    rank[by_first] = np.arange(len(begin))
    inverse = np.empty(n, dtype=np.int64)
    inverse[order] = rank[group_sorted]
    return inverse, first_of_group[by_first].astype(np.int64)


def face_normals(V: NDArray[np.float64], F: NDArray[np.int64]) -> NDArray[np.float64]:
    """Area-weighted normals of triangles (the cross product of two edges, twice the area long), shape (m, 3)."""
    x, y, z = (np.ascontiguousarray(V[:, k]) for k in range(3))
    a, b, c = F[:, 0], F[:, 1], F[:, 2]
    ux, uy, uz = x[b] - x[a], y[b] - y[a], z[b] - z[a]
    vx, vy, vz = x[c] - x[a], y[c] - y[a], z[c] - z[a]
    return np.stack([uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx], axis=1)


def group_normals(V: NDArray[np.float64], F: NDArray[np.int64], corner_group: NDArray[np.int64],
                  n_groups: int) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Unit normals per normal group: the sum of the area-weighted normals of the triangles at the group's corners.

    Parameters
    ----------
    corner_group : (m, 3) int64 array
        Each triangle corner's group, -1 for corners without a normal.

    Returns
    -------
    normals : (n_groups, 3) float64 array
    valid : (n_groups,) bool array
        False where the sum vanishes (only degenerate triangles); those normals are zero.
    """
    N = face_normals(V, F)
    sums = np.zeros((n_groups, 3))
    for corner in range(3):
        g = corner_group[:, corner]
        keep = g >= 0
        if not keep.all():
            g = g[keep]
        for k in range(3):
            w = N[:, k] if keep.all() else N[keep, k]
            sums[:, k] += np.bincount(g, weights=w, minlength=n_groups)
    length = np.sqrt(np.einsum("ij,ij->i", sums, sums))
    valid = length > 0
    sums[valid] /= length[valid, None]
    return sums, valid


def vertex_normal_groups(to_solve: NDArray[np.int64], normals: NDArray[np.float32]) -> NDArray[np.int64]:
    """Normal groups of vertices with one normal each (glTF, PLY): copies of one welded vertex with bit-identical
    normals share a group (a UV seam stays smooth), other vertices are their own. Each group is named by its first
    vertex; vertices without a normal (NaN) get -1."""
    n = len(to_solve)
    group = np.arange(n, dtype=np.int64)
    copies = np.flatnonzero(np.bincount(to_solve, minlength=n)[to_solve] > 1)
    if len(copies):
        keys = np.concatenate([to_solve[copies, None].view(np.uint32).reshape(len(copies), -1),
                               np.ascontiguousarray(normals[copies], dtype=np.float32).view(np.uint32)], axis=1)
        inverse, first = weld_rows(keys)
        group[copies] = copies[first][inverse]
    group[np.isnan(normals[:, 0])] = -1
    return group


def fan(face_sizes: NDArray[np.int64], corners: NDArray[Any]) -> NDArray[Any]:
    """Fan triangulation of polygons given as concatenated corners: ``(a, b, c, d, e)`` gives ``(a, b, c),
    (a, c, d), (a, d, e)``. In a mix of only triangles and quads, a quad ``(a, b, c, d)`` gives ``(a, b, c),
    (c, d, a)``: the same triangles, started where :func:`arap.load_mesh` has always started them.

    Works on any per-corner array (vertex indices, texture coordinate indices, (c, k) values).
    """
    sizes = np.asarray(face_sizes, dtype=np.int64)
    starts = np.concatenate(([0], np.cumsum(sizes)[:-1])).astype(np.int64)
    if len(sizes) and np.all(sizes == 3):
        return corners.reshape((len(sizes), 3, *corners.shape[1:]))
    tris = np.maximum(sizes - 2, 0)
    poly = np.repeat(np.arange(len(sizes)), tris)
    k = np.arange(int(tris.sum())) - np.repeat(np.cumsum(tris) - tris, tris)
    base = starts[poly]
    index = np.stack([base, base + k + 1, base + k + 2], axis=1)
    if ((sizes == 3) | (sizes == 4)).all() and (sizes == 3).any():
        second_of_quad = (sizes[poly] == 4) & (k == 1)
        index[second_of_quad] = np.roll(index[second_of_quad], -1, axis=1)
    return corners[index]


def missing_file_warning(message: str) -> None:
    """A warning (and a log line) about a texture or material file that cannot be read; the mesh still loads."""
    import warnings

    warnings.warn(message, UserWarning, stacklevel=4)
    logger.warning("%s", message)


def read_referenced(folder: Path | None, reference: str, label: str, what: str, consequence: str) -> bytes | None:
    """The content of a file a mesh file names (an MTL file, a texture image), read by the one rule of
    :func:`arap.io.paths.read_reference` (inside the mesh file's folder, a regular file, within the size limit);
    None with a warning naming the reference (and why it is refused) when it is missing or may not be read.

    Parameters
    ----------
    folder : Path or None
        The folder of the mesh file (None: there is none, and the file is missing).
    label : str
        The mesh file, for the warning.
    what : str
        What the reference is, ``"the texture 'a.png' named in 'a.mtl'"``.
    consequence : str
        What loading does without it, ``"its reference is kept"``.
    """
    from arap.io.paths import SpecialFileError, read_reference

    reason = ""
    if folder is not None:
        try:
            return read_reference(folder, reference)
        except SpecialFileError as exc:
            reason = f" ({exc.strerror})"
        except OSError:
            pass
    missing_file_warning(f"{label}: {what} cannot be read{reason}; {consequence}")
    return None


def write_beside(folder: Path, reference: str, data: bytes, written: list[Path]) -> None:
    """Write a file the mesh names by a relative reference (a texture), unless the same bytes are already there.

    A reference that leaves ``folder`` (absolute, or with ``..``) is not written; a warning says so when it does not
    name a readable file from there.
    """
    from arap.io.atomic import write_atomic

    ref = reference.replace("\\", "/")
    parts = Path(ref).parts
    if Path(ref).is_absolute() or ".." in parts or not parts:
        if not (folder / ref).is_file():
            missing_file_warning(f"{reference} is outside the folder written to and is not there; not copied")
        return
    dest = folder / ref
    try:
        if dest.is_file() and dest.stat().st_size == len(data) and dest.read_bytes() == data:
            return
    except OSError:
        pass
    dest.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(dest, data)
    written.append(dest)


# ---------------------------------------------------------------------------------------------- trimesh
def result_trimesh(vertices: Any, mesh: Any) -> trimesh.Trimesh:
    """A ``trimesh.Trimesh`` of positions on a mesh: ``mesh`` is the faces array, or a :class:`MeshAsset` (its
    texture or vertex colours kept where simple: the first UV set and the first texture image).

    ``vertices`` are for the asset's file vertices or for its welded ones (:meth:`MeshAsset.solve_mesh`).
    """
    import trimesh

    V = np.asarray(vertices, dtype=np.float64)
    if not isinstance(mesh, MeshAsset):
        F = np.asarray(mesh)
        if F.ndim != 2 or F.shape[1] != 3 or not np.issubdtype(F.dtype, np.integer):
            raise MeshError("to_trimesh needs the faces (m, 3) or the MeshAsset the solve came from")
        return trimesh.Trimesh(vertices=V, faces=F, process=False)
    asset = mesh
    V = asset.file_positions(V)
    F = asset.faces
    if asset.uvs is not None:
        # trimesh keeps one UV per vertex: split vertices whose corners have different texture coordinates.
        corner_v = F.reshape(-1)
        corner_uv = asset.uvs.reshape(-1, 2)
        keys = np.concatenate([corner_v[:, None].astype(np.float64), corner_uv], axis=1)
        inverse, first = weld_rows(keys)
        uv = corner_uv[first]
        image = None
        if asset.textures:
            import io

            from PIL import Image

            for name, blob in asset.textures.items():
                try:
                    image = Image.open(io.BytesIO(blob))  # reads the header: the size is known before decoding
                    if image.width * image.height > MAX_TEXTURE_PIXELS:
                        missing_file_warning(f"the texture {name!r} is {image.width:,} x {image.height:,} pixels, "
                                             f"more than the {MAX_TEXTURE_PIXELS:,} decoded; left out")
                        image = None
                        continue
                    image.load()
                    break
                except Exception:  # noqa: BLE001 - an unreadable image only costs the picture, not the mesh
                    image = None
        visual = trimesh.visual.TextureVisuals(uv=uv, image=image)
        return trimesh.Trimesh(vertices=V[corner_v[first]], faces=inverse.reshape(-1, 3), visual=visual,
                               process=False)
    if asset.vertex_colors is not None and asset.vertex_colors.shape[1] in (3, 4):
        return trimesh.Trimesh(vertices=V, faces=F, vertex_colors=asset.vertex_colors, process=False)
    return trimesh.Trimesh(vertices=V, faces=F, process=False)


# ---------------------------------------------------------------------------------------------- bundles
def _bundle_name(raw: str, label: str) -> str:
    """The relative name of a zip member (``/`` between folders), or a :class:`MeshFormatError` for one that could
    lead anywhere else: absolute, with a drive, with ``..``, or with a NUL character."""
    name = raw.replace("\\", "/")
    parts = [p for p in name.split("/") if p not in ("", ".")]
    if (name.startswith("/") or (len(name) > 1 and name[1] == ":") or ".." in parts or "\0" in name
            or not parts):
        raise MeshFormatError(f"{label}: the file name {raw[:200]!r} leads outside the archive (absolute or with "
                              "'..'); nothing was extracted")
    return "/".join(parts)


def read_bundle(data: bytes, *, max_bytes: int, max_files: int = MAX_BUNDLE_FILES,
                label: str = "the zip file") -> dict[str, bytes]:
    """The files of a zip archive holding a mesh file and the files it names (MTL files, textures, glTF buffers).

    Everything is checked from the archive's directory before a byte is extracted: at most ``max_files`` files
    and ``max_bytes`` bytes once uncompressed in all (a zip bomb is refused without being inflated), only regular
    files (no symbolic links), names relative to the archive (no absolute path, no ``..``), none twice, none
    encrypted. Each file is then read no further than its announced size. Folders and the metadata folders of
    archivers (``__MACOSX/``, ``._`` files) are left out.

    Parameters
    ----------
    data : bytes
        The archive.
    max_bytes : int
        Largest total size of the files once uncompressed.
    max_files : int
        Most files.

    Returns
    -------
    dict of str to bytes
        Each file's content by its name in the archive (``/`` between folders).

    Raises
    ------
    MeshFormatError
        Not a zip archive, or one that breaks a rule above (the message says which).
    """
    import io

    try:
        archive = zipfile.ZipFile(io.BytesIO(bytes(data)))
    except (zipfile.BadZipFile, OSError, ValueError) as exc:
        raise MeshFormatError(f"{label} is not a readable zip archive ({exc})") from exc
    with archive:
        members = [m for m in archive.infolist() if not m.is_dir()]
        members = [m for m in members if not (m.filename.startswith("__MACOSX/")
                                              or posixpath.basename(m.filename).startswith("._"))]
        if len(members) > max_files:
            raise MeshFormatError(f"{label} holds {len(members):,} files, more than the {max_files:,} accepted; "
                                  "nothing was extracted")
        total = sum(m.file_size for m in members)
        if total > max_bytes:
            raise MeshFormatError(f"{label} holds {total:,} bytes once uncompressed, more than the {max_bytes:,} "
                                  "accepted; nothing was extracted")
        names: dict[str, zipfile.ZipInfo] = {}
        for m in members:
            name = _bundle_name(m.filename, label)
            mode = m.external_attr >> 16
            if m.create_system == 3 and stat.S_IFMT(mode) and not stat.S_ISREG(mode):  # made on Unix: typed
                raise MeshFormatError(f"{label}: {name!r} is a symbolic link or a special file, not a regular file; "
                                      "nothing was extracted")
            if m.flag_bits & 0x1:
                raise MeshFormatError(f"{label}: {name!r} is encrypted; nothing was extracted")
            if name in names:
                raise MeshFormatError(f"{label} holds {name!r} twice; nothing was extracted")
            names[name] = m
        folders = {"/".join(name.split("/")[:k]) for name in names for k in range(1, name.count("/") + 1)}
        both = sorted(folders.intersection(names))
        if both:
            raise MeshFormatError(f"{label} holds {both[0]!r} both as a file and as a folder; nothing was extracted")
        files: dict[str, bytes] = {}
        for name, m in names.items():
            try:
                with archive.open(m) as stream:
                    content = stream.read(m.file_size + 1)
            except (zipfile.BadZipFile, OSError, ValueError, NotImplementedError, EOFError) as exc:
                raise MeshFormatError(f"{label}: {name!r} cannot be extracted ({exc})") from exc
            if len(content) != m.file_size:
                raise MeshFormatError(f"{label}: {name!r} does not hold the {m.file_size:,} bytes its archive "
                                      "announces; nothing was extracted")
            files[name] = content
    return files


def bundle_mesh_name(files: dict[str, bytes] | list[str], label: str = "the zip file") -> str:
    """The mesh file among the files of a bundle: the one file with a mesh extension (OBJ, PLY, glTF, GLB, OFF,
    STL).

    Raises
    ------
    MeshFormatError
        None or several.
    """
    extensions = formats.suffixes("surface")
    meshes = [n for n in files if n.lower().endswith(extensions)]
    if len(meshes) != 1:
        found = f"{len(meshes)}: {', '.join(meshes[:5])}" if meshes else "none"
        raise MeshFormatError(f"{label} must hold one mesh file ({', '.join(extensions)}) with the files it names; "
                              f"it holds {found}")
    return meshes[0]


@contextmanager
def unpacked_bundle(files: dict[str, bytes]) -> Iterator[Path]:
    """A new temporary folder holding ``files`` (names from :func:`read_bundle`), removed afterwards: a mesh file
    read from there finds the files of its bundle, and nothing else (:func:`arap.io.paths.read_reference`).

    Raises
    ------
    MeshFormatError
        A file cannot be written there (a name too long for the file system).
    """
    from arap.io.atomic import write_atomic

    with tempfile.TemporaryDirectory(prefix="arap-bundle-") as folder:
        root = Path(folder)
        for name, content in files.items():
            dest = root / _bundle_name(name, "the bundle")
            try:
                dest.parent.mkdir(parents=True, exist_ok=True)
                write_atomic(dest, content)
            except OSError as exc:
                raise MeshFormatError(f"{name[:200]!r} cannot be extracted: {exc.strerror or exc}") from exc
        yield root
