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
import posixpath
import stat
import tempfile
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
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

__all__ = ["ASSET_FORMATS", "MAX_BUNDLE_FILES", "MeshAsset", "SolveMesh", "asset_format", "bundle_mesh_name",
           "load_asset", "load_asset_bytes", "read_bundle", "result_trimesh", "save_asset", "unpacked_bundle"]

#: Most files a bundle (a zip of a mesh file with the files it names) may hold.
MAX_BUNDLE_FILES = 256

#: Extensions of the mesh file of a bundle; the other files are what it names.
BUNDLE_MESH_EXTENSIONS = (".obj", ".ply", ".glb", ".gltf", ".off", ".stl")


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
    meshes = [n for n in files if n.lower().endswith(BUNDLE_MESH_EXTENSIONS)]
    if len(meshes) != 1:
        found = f"{len(meshes)}: {', '.join(meshes[:5])}" if meshes else "none"
        raise MeshFormatError(f"{label} must hold one mesh file ({', '.join(BUNDLE_MESH_EXTENSIONS)}) with the files "
                              f"it names; it holds {found}")
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
