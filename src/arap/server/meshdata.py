"""Meshes of the studio: built-in models, the operator's default mesh, client uploads and exports.

A client never names a file on the server: uploads arrive as bytes and are parsed from memory, and exports are
encoded in memory.
"""

from __future__ import annotations

import logging
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import arap
from arap.errors import ArapError, MeshFormatError, MeshTooLargeError
from arap.io import load_mesh_bytes_with_report, load_mesh_with_report, save_mesh_bytes
from arap.server.protocol import UPLOAD_EXTENSIONS, RequestError, encode_binary
from arap.server.server_messages import Mesh

__all__ = ["MeshData", "builtin_names", "export_mesh", "load_builtin", "load_default", "load_upload", "mesh_frame"]

logger = logging.getLogger(__name__)

EXPORT_MIME = {"obj": "model/obj", "ply": "application/octet-stream"}


@dataclass(frozen=True, eq=False)
class MeshData:
    """A loaded mesh (arrays are read-only and may be shared between sessions).

    Attributes
    ----------
    name : str
        Display name.
    V : (n, 3) float64 array
    F : (m, 3) int64 array
    report : list of str
        Repairs made while loading, one line each.
    vertex_map : (n_file,) int64 array or None
        When repair renumbered the file's vertices (welded or dropped some): the index in :attr:`V` of each vertex
        of the file, -1 for one dropped (:attr:`arap.meshes.repair.RepairResult.vertex_map`). None when the numbering is
        the file's (clean files, built-in models, arrays). Constraints documents use the file's numbering
        (:mod:`arap.server.numbering`).
    """

    name: str
    V: np.ndarray
    F: np.ndarray
    report: list[str] = field(default_factory=list)
    vertex_map: np.ndarray | None = None

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


def builtin_names() -> list[str]:
    """Names of the built-in models."""
    return list(arap.BUILTIN_MESHES)


def load_builtin(name: str) -> MeshData:
    """A built-in model.

    Raises
    ------
    RequestError
        ``bad_message`` for an unknown name.
    """
    names = builtin_names()
    if name not in names:
        raise RequestError("bad_message", f"unknown built-in mesh {name[:64]!r}; expected one of {names}")
    V, F = arap.builtin_mesh(name)
    return MeshData.make(name, V, F)


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


def load_upload(data: bytes | memoryview, filename: str, max_vertices: int) -> MeshData:
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
    try:
        V, F, repair = load_mesh_bytes_with_report(bytes(data), ext[1:], name=f"{name}{ext}",
                                                   max_vertices=max_vertices)
    except MeshTooLargeError as exc:
        raise RequestError("too_large", str(exc)) from exc
    except ArapError as exc:
        raise RequestError("bad_mesh", str(exc)) from exc
    logger.info("loaded upload %s%s: %d vertices, %d faces", name, ext, len(V), len(F))
    return MeshData.make(name, V, F, repair.report, repair.vertex_map if repair.renumbers else None)


def export_mesh(name: str, U: np.ndarray, F: np.ndarray, fmt: str) -> tuple[str, str, bytes]:
    """Encode the deformed mesh as a file.

    Returns
    -------
    filename : str
    mime : str
    data : bytes
    """
    return f"{name}-deformed.{fmt}", EXPORT_MIME[fmt], save_mesh_bytes(U, F, fmt)


def mesh_frame(mesh: MeshData) -> bytes:
    """The ``mesh`` message of ``mesh``: rest positions (float32), faces (uint32) and, for a repaired file, each
    vertex's number in the file (int32)."""
    vmap = mesh.vertex_map
    header = Mesh(name=mesh.name, n_vertices=mesh.n_vertices, n_faces=mesh.n_faces, report=mesh.report,
                  file_vertices=0 if vmap is None else len(vmap)).to_wire()
    parts = [np.ascontiguousarray(mesh.V, dtype="<f4").tobytes(), np.ascontiguousarray(mesh.F, dtype="<u4").tobytes()]
    if vmap is not None:
        parts.append(np.ascontiguousarray(vmap, dtype="<i4").tobytes())
    return encode_binary(header, *parts)
