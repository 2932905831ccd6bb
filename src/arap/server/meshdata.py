"""Meshes of the studio: built-in models, the operator's default mesh, client uploads and the ``mesh`` frame that
sends one (the loaded mesh itself, :class:`~arap.server.mesh_model.MeshData`, and its export are
:mod:`arap.server.mesh_model`).

A client never names a file on the server: uploads arrive as bytes and are parsed from memory, and exports are
encoded in memory.
"""

from __future__ import annotations

import logging
import os
import re
from dataclasses import replace
from pathlib import Path

import numpy as np

from arap.errors import ArapError, MeshFormatError, MeshTooLargeError
from arap.io import formats, load_mesh_bytes_with_report, load_mesh_with_report
from arap.meshes.grids import box_tetrahedra
from arap.meshes.mesh import check_mesh
from arap.meshes.shapes import BUILTIN_MESHES, builtin_mesh
from arap.server.errors import RequestError
from arap.server.frames import encode_binary
from arap.server.mesh_model import MeshData
from arap.server.messages import UPLOAD_EXTENSIONS
from arap.server.server_messages import Mesh

__all__ = ["builtin_names", "load_builtin", "load_default", "load_upload", "mesh_frame"]

logger = logging.getLogger(__name__)

SOLID_BUILTINS: dict[str, tuple[tuple[int, int, int], tuple[float, float, float]]] = {
    "solid bar": ((4, 20, 4), (1.0, 5.0, 1.0)),
}
"""Built-in tetrahedral solids (:func:`arap.box_tetrahedra`: cubes each way, extent), drawn by their boundary and
deformed through their tetrahedra."""


def builtin_names() -> list[str]:
    """Names of the built-in models: the surfaces, then the solids."""
    return [*BUILTIN_MESHES, *SOLID_BUILTINS]


def load_builtin(name: str) -> MeshData:
    """A built-in model (marked :attr:`~arap.server.mesh_model.MeshData.builtin`, which a file of the same name is
    not).

    Raises
    ------
    RequestError
        ``bad_message`` for an unknown name.
    """
    names = builtin_names()
    if name not in names:
        raise RequestError("bad_message", f"unknown built-in mesh {name[:64]!r}; expected one of {names}")
    if name in SOLID_BUILTINS:
        (nx, ny, nz), size = SOLID_BUILTINS[name]
        V, T = box_tetrahedra(nx, ny, nz, size=size)
        return replace(MeshData.solid(name, V - np.array([size[0], 0.0, size[2]]) / 2, T), builtin=True)
    V, F = builtin_mesh(name)
    return replace(MeshData.make(name, V, F), builtin=True)


def load_default(spec: str | os.PathLike[str] | MeshData | None) -> MeshData:
    """The mesh every new session starts with: a file given by the server's operator, a built-in name (when no
    such file exists), a :class:`MeshData` (e.g. arrays from a notebook), or None for the first built-in model.

    Raises
    ------
    arap.errors.ArapError
        The file cannot be read or is not a usable mesh.
    """
    if spec is None:
        return load_builtin(builtin_names()[0])
    if isinstance(spec, MeshData):
        return spec
    path = Path(spec)
    if not path.exists() and str(spec) in builtin_names():
        return load_builtin(str(spec))
    if not path.exists():
        raise MeshFormatError(f"{spec}: no such file (built-in meshes: {', '.join(builtin_names())})")
    V, F, repair = load_mesh_with_report(path)
    return MeshData.make(path.stem, V, F, repair.report, repair.vertex_map if repair.renumbers else None)


_SAFE_NAME = re.compile(r"[^A-Za-z0-9._ -]+")


def _display_name(filename: str) -> str:
    base = filename.replace("\\", "/").rsplit("/", 1)[-1]
    stem = base.rsplit(".", 1)[0] if "." in base else base
    stem = _SAFE_NAME.sub("_", stem).strip(" ._")[:64]
    return stem or "upload"


def load_upload(data: bytes | memoryview, filename: str, max_vertices: int,
                folder: str | os.PathLike[str] | None = None) -> MeshData:
    """Parse an uploaded mesh file from memory.

    Parameters
    ----------
    data : bytes-like
        The file's bytes.
    filename : str
        The client's file name; only its extension (the format) and a sanitised stem (the display name) are used.
    max_vertices : int
        Largest accepted mesh; checked against the file's header or lines before the slow parse (see
        :func:`arap.io.load_mesh_bytes_with_report`).
    folder : path-like or None
        Where the files it names are (a glTF's buffers): the folder of an unpacked bundle; None: nowhere.

    Returns
    -------
    MeshData

    Raises
    ------
    RequestError
        ``bad_mesh`` for an unsupported type or an unreadable or unusable mesh, ``too_large`` for too many
        vertices.
    """
    ext = ("." + filename.rsplit(".", 1)[-1].lower()) if "." in filename else ""
    if ext not in UPLOAD_EXTENSIONS:
        raise RequestError("bad_mesh",
                           f"unsupported file type {ext or '(none)'!r}; expected one of {list(UPLOAD_EXTENSIONS)}")
    name = _display_name(filename)
    if formats.find(ext, "volume") is not None:
        return _load_volume_upload(data, name, ext, max_vertices)
    try:
        V, F, repair = load_mesh_bytes_with_report(bytes(data), ext[1:], name=f"{name}{ext}",
                                                   max_vertices=max_vertices, folder=folder)
    except MeshTooLargeError as exc:
        raise RequestError("too_large", str(exc)) from exc
    except ArapError as exc:
        raise RequestError("bad_mesh", str(exc)) from exc
    logger.info("loaded upload %s%s: %d vertices, %d faces", name, ext, len(V), len(F))
    return MeshData.make(name, V, F, repair.report, repair.vertex_map if repair.renumbers else None)


def _load_volume_upload(data: bytes | memoryview, name: str, ext: str, max_vertices: int) -> MeshData:
    """An uploaded Medit, gmsh or VTK file: a solid of tetrahedra, drawn by its boundary and solved on its tetrahedra
    (as the built-in solids), or a mesh of triangles (a planar one gets ``z = 0``), in the file's numbering."""
    from arap.io.volume import load_volume_mesh_bytes

    try:
        V, T = load_volume_mesh_bytes(bytes(data), ext, name=f"{name}{ext}", max_vertices=max_vertices)
        if T.shape[1] == 3:
            V = V if V.shape[1] == 3 else np.column_stack([V, np.zeros(len(V))])
            mesh = MeshData.make(name, V, T)
            check_mesh(mesh.V, mesh.F)
        else:
            mesh = MeshData.solid(name, V, T)
    except MeshTooLargeError as exc:
        raise RequestError("too_large", str(exc)) from exc
    except ArapError as exc:
        raise RequestError("bad_mesh", str(exc)) from exc
    logger.info("loaded upload %s%s: %d vertices, %s", name, ext, len(V),
                f"{len(T)} tetrahedra" if T.shape[1] == 4 else f"{len(T)} triangles")
    return mesh


def mesh_frame(mesh: MeshData) -> bytes:
    """The ``mesh`` message of ``mesh``: rest positions (float32), faces (uint32) and, for a repaired file, each
    vertex's number in the file (int32)."""
    vmap = mesh.vertex_map
    header = Mesh(name=mesh.name, n_vertices=mesh.n_vertices, n_faces=mesh.n_faces, report=mesh.report,
                  file_vertices=0 if vmap is None else len(vmap),
                  n_tetrahedra=0 if mesh.elements is None else len(mesh.elements),
                  picture=None if mesh.picture is None else [mesh.picture.shape[1], mesh.picture.shape[0]],
                  builtin=mesh.builtin).to_wire()
    parts = [np.ascontiguousarray(mesh.V, dtype="<f4").tobytes(), np.ascontiguousarray(mesh.F, dtype="<u4").tobytes()]
    if vmap is not None:
        parts.append(np.ascontiguousarray(vmap, dtype="<i4").tobytes())
    return encode_binary(header, *parts)
