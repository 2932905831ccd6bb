"""The file formats arap reads and writes, one record each: what a reader, a writer, the screening of a file's bytes,
the studio's upload and export lists, their media types and the command line's help know of a format comes from here.

Adding a format is adding its record to :data:`FORMATS` (and the functions it names to the module that holds them).
The functions are named as ``"module:function"`` and imported on first use, so that this module imports nothing
heavy and every other module may read it.

Kinds
-----
``surface``
    Triangle meshes (:func:`arap.io.load_mesh`, :func:`arap.io.save_mesh`). The reader takes
    ``(data, name, folder, max_vertices)`` and gives ``(V, F)`` as stored; the writer takes ``(V, F)`` and gives the
    file's bytes. ``screen`` (``(data, label) -> data``), ``vertex_count`` (``data -> (count, text) | None``) and
    ``face_count`` (``data -> int | None``) check the bytes before the reader sees them (:mod:`arap.io.screening`).
    With ``asset_reader`` and ``asset_writer`` :func:`arap.io.load_asset` reads it with its texture coordinates,
    colours and materials too, and :func:`arap.io.save_asset` writes it back (:mod:`arap.io.assets`): the reader takes
    ``(data, name, folder, max_vertices)`` and gives a :class:`~arap.io.assets.MeshAsset`, the writer takes
    ``(path, asset, positions or None)`` and gives the files it wrote, the mesh first; ``asset_hint``
    (``data -> bool``) says cheaply whether an upload may hold anything worth that reading (empty: always).
``volume``
    Tetrahedral (or planar triangle) meshes (:func:`arap.io.load_volume_mesh`, :func:`arap.io.save_volume_mesh`).
    The reader of a one-file format takes ``(data, name, format name)`` and gives ``(V, T)``; a TetGen mesh, two
    files, is read from its path.
``picture``
    Pictures the studio meshes for the puppet warp (:func:`arap.puppet.picture.decode_picture`).
``bundle``
    A zip of a model file with the files it names (MTL files, textures, glTF buffers), as the studio's page sends
    several files opened together (:func:`arap.io.assets.read_bundle`).

Example
-------
>>> import typing
>>> get("model.OBJ").title, get(".msh").kind, get("tet.ele").name
('Wavefront OBJ', 'volume', 'tetgen')
>>> names("surface")
('obj', 'off', 'ply', 'stl', 'glb', 'gltf')
>>> len(FORMATS) == len(names()), {f.kind for f in FORMATS} == set(typing.get_args(Kind))
(True, True)
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

__all__ = [
    "FORMATS",
    "FileFormat",
    "Kind",
    "export_names",
    "family",
    "find",
    "get",
    "mime_types",
    "names",
    "suffix_of",
    "suffixes",
    "upload_suffixes",
]

Kind = Literal["surface", "volume", "picture", "bundle"]


@dataclass(frozen=True)
class FileFormat:
    """One file format.

    Attributes
    ----------
    name : str
        Its short name (``"obj"``; ``"tetgen"`` for the ``.node``/``.ele`` pair).
    title : str
        Its name for people (``"Wavefront OBJ"``).
    kind : {"surface", "volume", "picture", "bundle"}
        What it holds (see the module notes).
    suffixes : tuple of str
        Its file name extensions, lower case with the dot, the usual one first.
    mime : str
        Its media type, for downloads.
    reader, writer : str
        ``"module:function"`` reading and writing it (empty when arap does not).
    screen, vertex_count, face_count : str
        ``"module:function"`` checking a surface file's bytes before parsing (empty: none).
    asset_reader, asset_writer, asset_hint : str
        ``"module:function"`` reading and writing it with its attributes (texture coordinates, colours, materials, a
        glTF scene) for :func:`arap.io.load_asset` and :func:`arap.io.save_asset`, and telling whether an upload's
        bytes may hold any (see the module notes); empty when arap keeps none.
    family : str
        Formats of one family hold the same attributes (GLB and glTF): a textured model is written in its family.
    upload : bool
        The studio opens uploads of it.
    export : bool
        The studio's export offers it.

    Examples
    --------
    >>> from arap.io.formats import get
    >>> fmt = get("scan.ply")
    >>> fmt.name, fmt.kind, fmt.suffix, fmt.asset
    ('ply', 'surface', '.ply', True)
    """

    name: str
    title: str
    kind: Kind
    suffixes: tuple[str, ...]
    mime: str = "application/octet-stream"
    reader: str = ""
    writer: str = ""
    screen: str = ""
    vertex_count: str = ""
    face_count: str = ""
    asset_reader: str = ""
    asset_writer: str = ""
    asset_hint: str = ""
    family: str = ""
    upload: bool = False
    export: bool = False

    @property
    def asset(self) -> bool:
        """:func:`arap.io.load_asset` and :func:`arap.io.save_asset` keep its attributes (it has an asset reader and
        an asset writer)."""
        return bool(self.asset_reader and self.asset_writer)

    @property
    def suffix(self) -> str:
        """The usual extension (``".obj"``)."""
        return self.suffixes[0]

    def function(self, role: str) -> Callable[..., Any] | None:
        """The function named by field ``role`` (``"reader"``, ``"writer"``, ``"screen"`` ...), imported now; None
        when the field is empty."""
        spec = getattr(self, role)
        if not spec:
            return None
        module, _, attribute = spec.partition(":")
        found: Callable[..., Any] = getattr(importlib.import_module(module), attribute)
        return found


_M = "arap.io.meshfile"
_S = "arap.io.screening"
_G = "arap.io.gltf_asset"

#: Every format, surfaces first (in the order their lists show them), then volumes, pictures and bundles.
FORMATS: tuple[FileFormat, ...] = (
    FileFormat("obj", "Wavefront OBJ", "surface", (".obj",), "model/obj", f"{_M}:read_obj", f"{_M}:obj_bytes",
               f"{_S}:screen_obj", f"{_S}:obj_vertex_count", asset_reader="arap.io.obj_asset:read_obj_asset",
               asset_writer="arap.io.obj_write:write_obj_asset", asset_hint="arap.io.obj_asset:may_have_attributes",
               upload=True, export=True),
    FileFormat("off", "Object File Format", "surface", (".off",), "application/octet-stream", f"{_M}:read_off",
               f"{_M}:off_bytes", f"{_S}:screen_off", f"{_S}:off_vertex_count", f"{_S}:off_face_count", upload=True),
    FileFormat("ply", "Stanford PLY", "surface", (".ply",), "application/octet-stream", f"{_M}:read_ply",
               f"{_M}:ply_bytes", f"{_S}:screen_ply", f"{_S}:ply_vertex_count", f"{_S}:ply_face_count",
               asset_reader="arap.io.ply_asset:read_ply_asset", asset_writer="arap.io.ply_asset:write_ply_asset",
               asset_hint="arap.io.ply_asset:may_have_attributes", upload=True, export=True),
    FileFormat("stl", "STL", "surface", (".stl",), "model/stl", f"{_M}:read_stl", f"{_M}:stl_bytes",
               f"{_S}:screen_stl", f"{_S}:stl_vertex_count", upload=True),
    FileFormat("glb", "glTF binary (GLB)", "surface", (".glb",), "model/gltf-binary", f"{_M}:read_gltf",
               f"{_M}:glb_bytes", asset_reader=f"{_G}:read_gltf_asset", asset_writer=f"{_G}:write_glb_asset",
               family="gltf", upload=True, export=True),
    FileFormat("gltf", "glTF", "surface", (".gltf",), "model/gltf+json", f"{_M}:read_gltf", f"{_M}:gltf_bytes",
               asset_reader=f"{_G}:read_gltf_asset", asset_writer=f"{_G}:write_gltf_asset", family="gltf",
               upload=True),
    FileFormat("mesh", "Medit", "volume", (".mesh",), reader="arap.io.volume:read_meshio_bytes", upload=True),
    FileFormat("msh", "gmsh", "volume", (".msh",), reader="arap.io.volume:read_meshio_bytes", upload=True),
    FileFormat("vtu", "VTK (.vtu)", "volume", (".vtu",), reader="arap.io.volume:read_meshio_bytes", upload=True),
    FileFormat("vtk", "VTK (.vtk)", "volume", (".vtk",), reader="arap.io.volume:read_meshio_bytes", upload=True),
    FileFormat("tetgen", "TetGen", "volume", (".node", ".ele")),
    FileFormat("png", "PNG picture", "picture", (".png",), "image/png", "arap.puppet.picture:decode_picture",
               upload=True, export=True),
    FileFormat("jpg", "JPEG picture", "picture", (".jpg", ".jpeg"), "image/jpeg", "arap.puppet.picture:decode_picture",
               upload=True),
    FileFormat("webp", "WebP picture", "picture", (".webp",), "image/webp", "arap.puppet.picture:decode_picture",
               upload=True),
    FileFormat("zip", "Zip of a model and its files", "bundle", (".zip",), "application/zip",
               "arap.io.assets:read_bundle", upload=True),
)

_BY_NAME = {f.name: f for f in FORMATS}
_BY_SUFFIX = {s: f for f in FORMATS for s in f.suffixes}


def suffix_of(name: str | os.PathLike[str]) -> str:
    """The lower-case extension of a file name, a suffix or a bare type name, with its dot (``"mesh.OBJ"``,
    ``".obj"`` and ``"obj"`` all give ``".obj"``; a name without a dot gives itself as the suffix).

    Examples
    --------
    >>> suffix_of("models/Mesh.OBJ"), suffix_of(".obj"), suffix_of("obj")
    ('.obj', '.obj', '.obj')
    """
    text = str(name).strip()
    base = text.replace("\\", "/").rsplit("/", 1)[-1]
    return "." + base.rsplit(".", 1)[-1].lower()


def find(name: str | os.PathLike[str], kind: Kind | None = None) -> FileFormat | None:
    """The format of a file name, a suffix, a bare extension or a format name (``"tetgen"``), or None; only of
    ``kind`` when given.

    Examples
    --------
    >>> find("tet.ele").name, find("shape.xyz"), find("model.obj", kind="volume")
    ('tetgen', None, None)
    """
    text = str(name).strip().lower()
    found = _BY_NAME.get(text) or _BY_SUFFIX.get(suffix_of(name))
    return found if found is not None and (kind is None or found.kind == kind) else None


def get(name: str | os.PathLike[str], kind: Kind | None = None) -> FileFormat:
    """The format of a file name, a suffix, a bare extension or a format name.

    Raises
    ------
    MeshFormatError
        No such format (of ``kind``).

    Examples
    --------
    >>> get("model.OBJ").title, get("msh").kind
    ('Wavefront OBJ', 'volume')
    """
    found = find(name, kind)
    if found is None:
        from arap.errors import MeshFormatError

        what = f"{kind} " if kind else ""
        raise MeshFormatError(f"unsupported {what}format {suffix_of(name)[1:]!r} (from {str(name).strip()!r}); "
                              f"supported: {', '.join(names(kind))}")
    return found


def family(name: str | os.PathLike[str]) -> str:
    """The family of a format (``"gltf"`` for GLB and glTF; else the format's own name): a textured model keeps its
    attributes when written in its family.

    Raises
    ------
    MeshFormatError
        No such format.

    Examples
    --------
    >>> family("scene.glb"), family("model.gltf"), family("mesh.obj")
    ('gltf', 'gltf', 'obj')
    """
    found = get(name)
    return found.family or found.name


def names(kind: Kind | None = None, *, asset: bool | None = None) -> tuple[str, ...]:
    """The names of the formats (of ``kind``; with ``asset``, only those whose attributes :func:`arap.io.load_asset`
    keeps, or only the others).

    Examples
    --------
    >>> names("volume")
    ('mesh', 'msh', 'vtu', 'vtk', 'tetgen')
    """
    return tuple(f.name for f in FORMATS if (kind is None or f.kind == kind) and (asset is None or f.asset == asset))


def suffixes(kind: Kind | None = None) -> tuple[str, ...]:
    """Every extension of the formats (of ``kind``), with its dot, in the order of :data:`FORMATS`.

    Examples
    --------
    >>> suffixes("surface")[:3]
    ('.obj', '.off', '.ply')
    """
    return tuple(s for f in FORMATS if kind is None or f.kind == kind for s in f.suffixes)


def upload_suffixes() -> tuple[str, ...]:
    """The extensions of the files the studio opens.

    Examples
    --------
    >>> ".obj" in upload_suffixes(), ".zip" in upload_suffixes()
    (True, True)
    """
    return tuple(s for f in FORMATS if f.upload for s in f.suffixes)


def export_names() -> tuple[str, ...]:
    """The formats the studio exports to.

    Examples
    --------
    >>> "obj" in export_names()
    True
    """
    return tuple(f.name for f in FORMATS if f.export)


def mime_types() -> dict[str, str]:
    """The media type of each format, by name.

    Examples
    --------
    >>> mime_types()["obj"]
    'model/obj'
    """
    return {f.name: f.mime for f in FORMATS}
