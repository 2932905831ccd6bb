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

Normals
-------
A deformed surface needs new normals. They are recomputed per normal *group*, the corners that shared one normal in
the file at one vertex (same position and, for OBJ, the same ``vn`` index; for glTF and PLY, the same normal
value): each group gets the normalised sum of the area-weighted normals of the triangles at its corners. Smooth
shading stays smooth, flat and hard edges stay flat and hard, and a normal shared by far-apart vertices becomes one
per vertex (OBJ ``vn`` lines are then written once per group).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import arap.io.formats as formats
from arap.errors import MeshFormatError
from arap.io.asset_model import ASSET_FORMATS, MeshAsset, SolveMesh, asset_format, result_trimesh
from arap.io.gltf_asset import read_gltf_asset, write_gltf_asset
from arap.io.obj_asset import read_obj_asset
from arap.io.obj_write import write_obj_asset
from arap.io.paths import read_regular_file
from arap.io.ply_asset import read_ply_asset, write_ply_asset

__all__ = ["ASSET_FORMATS", "MeshAsset", "SolveMesh", "asset_format", "load_asset", "load_asset_bytes",
           "result_trimesh", "save_asset"]


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
    ft = asset_format(file_type)
    base = Path(folder) if folder is not None else None
    if ft == "obj":
        return read_obj_asset(bytes(data), name, base, max_vertices)
    if ft == "ply":
        return read_ply_asset(bytes(data), name, base, max_vertices)
    return read_gltf_asset(bytes(data), name, base, max_vertices)


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
    """
    path = Path(path)
    ft = asset_format(path.name)
    family = {name: formats.family(name) for name in ASSET_FORMATS}
    if family[ft] != family[asset.format]:
        raise MeshFormatError(f"{path}: a textured {asset.format.upper()} mesh is written as "
                              f"{'GLB or glTF' if family[asset.format] == 'gltf' else asset.format.upper()} "
                              "(save_mesh writes its geometry in any format)")
    V = None if vertices is None else asset.file_positions(vertices)
    try:
        if ft == "obj":
            return write_obj_asset(path, asset, V)
        if ft == "ply":
            return write_ply_asset(path, asset, V)
        return write_gltf_asset(path, asset, V, binary=ft == "glb")
    except OSError as exc:
        raise MeshFormatError(f"cannot write {path}: {exc.strerror or exc}") from exc
