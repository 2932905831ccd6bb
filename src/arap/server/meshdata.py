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
from arap.server.protocol import UPLOAD_EXTENSIONS, RequestError

__all__ = ["MeshData", "builtin_names", "export_mesh", "load_builtin", "load_default", "load_upload"]

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
    """

    name: str
    V: np.ndarray
    F: np.ndarray
    report: list[str] = field(default_factory=list)

    @classmethod
    def make(cls, name: str, V: np.ndarray, F: np.ndarray, report: list[str] | None = None) -> MeshData:
        """Freeze copies of the arrays into a :class:`MeshData`."""
        V = np.array(V, dtype=np.float64)
        F = np.array(F, dtype=np.int64)
        V.setflags(write=False)
        F.setflags(write=False)
        return cls(name, V, F, list(report or []))

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
    return MeshData.make(path.stem, V, F, repair.report)


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
    return MeshData.make(name, V, F, repair.report)


def export_mesh(name: str, U: np.ndarray, F: np.ndarray, fmt: str) -> tuple[str, str, bytes]:
    """Encode the deformed mesh as a file.

    Returns
    -------
    filename : str
    mime : str
    data : bytes
    """
    return f"{name}-deformed.{fmt}", EXPORT_MIME[fmt], save_mesh_bytes(U, F, fmt)
