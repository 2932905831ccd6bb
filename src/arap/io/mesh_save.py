"""Writing triangle meshes (OBJ, OFF, PLY, STL, glTF/GLB) to paths or bytes: exact round trips where the format
allows (OBJ and OFF with 17 significant digits, PLY as binary doubles), atomic writes (:mod:`arap.io.atomic`), and
a textured :class:`~arap.io.assets.MeshAsset` written with its attributes in its own format."""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from arap.errors import MeshError, MeshFormatError
from arap.io.atomic import write_atomic
from arap.io.meshfile import format_of
from arap.meshes.mesh import MeshLike, mesh_arrays

__all__ = ["save_mesh", "save_mesh_bytes"]

logger = logging.getLogger(__name__)


def _check_for_saving(V: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    if V.ndim != 2 or V.shape[1] != 3:
        raise MeshError(f"vertices must have shape (n, 3), got {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3:
        raise MeshError(f"faces must have shape (m, 3), got {F.shape}")
    if len(F) and (F.min() < 0 or F.max() >= len(V)):
        raise MeshError(f"face indices out of range [0, {len(V)})")
    bad = ~np.isfinite(V).all(axis=1)
    if bad.any():  # such a file would not load again
        raise MeshError(f"{int(bad.sum())} vertices have NaN or infinite coordinates (vertex {int(np.argmax(bad))} "
                        "first); the file is not written")
    return V, F


def _ply_bytes(V: np.ndarray, F: np.ndarray) -> bytes:
    """Binary little-endian PLY with double-precision coordinates (exact round trip)."""
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(V)}\nproperty double x\nproperty double y\nproperty double z\n"
        f"element face {len(F)}\nproperty list uchar int vertex_indices\nend_header\n"
    ).encode("ascii")
    faces = np.zeros(len(F), dtype=[("n", "u1"), ("idx", "<i4", (3,))])
    faces["n"] = 3
    faces["idx"] = F
    return header + V.astype("<f8").tobytes() + faces.tobytes()


def _text_bytes(V: np.ndarray, F: np.ndarray, header: str, vkey: str, fkey: str, base: int) -> bytes:
    """OBJ or OFF text: coordinates with 17 significant digits (``%.17g``, exact for every double, tiny and huge
    ones included), faces counted from ``base``."""
    vertices = (f"{vkey}%.17g %.17g %.17g\n" * len(V)) % tuple(V.ravel().tolist())
    faces = (f"{fkey}%d %d %d\n" * len(F)) % tuple((F + base).ravel().tolist())
    return (header + vertices + faces).encode("ascii")


def save_mesh_bytes(V: np.ndarray, F: np.ndarray, file_type: str) -> bytes:
    """Encode a triangle mesh as the bytes of a file.

    OBJ and OFF are written as text with 17 significant digits and PLY as binary doubles, so they round-trip
    exactly; STL is binary single precision (a triangle soup, by the format's definition); GLB and glTF (its buffer
    in a data URI) hold single precision positions and 32-bit indices.

    Parameters
    ----------
    V : (n, 3) float array
    F : (m, 3) int array
    file_type : str
        ``"obj"``, ``"off"``, ``"ply"``, ``"stl"``, ``"glb"`` or ``"gltf"`` (or a file name with that extension).

    Returns
    -------
    bytes
    """
    ft = format_of(file_type)
    V, F = _check_for_saving(V, F)
    if ft == "ply":
        return _ply_bytes(V, F)
    if ft == "obj":
        return _text_bytes(V, F, "", "v ", "f ", 1)
    if ft == "off":
        return _text_bytes(V, F, f"OFF\n{len(V)} {len(F)} 0\n", "", "3 ", 0)
    if ft in ("glb", "gltf"):
        from arap.io.gltf_asset import geometry_glb

        if np.abs(V).max(initial=0.0) > np.finfo(np.float32).max:
            raise MeshError("coordinates beyond the range of single precision, which glTF stores; not written")
        return geometry_glb(V, F, binary=ft == "glb")
    import trimesh

    mesh = trimesh.Trimesh(vertices=V, faces=F, process=False, validate=False)
    return bytes(trimesh.exchange.stl.export_stl(mesh))


def save_mesh(path: str | os.PathLike[str], V: NDArray[np.floating] | MeshLike,
              F: NDArray[np.integer] | None = None) -> None:
    """Write a triangle mesh; the format follows the extension (see :func:`save_mesh_bytes`).

    Given a :class:`~arap.io.assets.MeshAsset` (``save_mesh(path, asset)``) in its own format (OBJ, PLY, or GLB and
    glTF), its texture coordinates, normals, colours, materials and groups are written too
    (:func:`~arap.io.assets.save_asset`); in another format, its geometry.

    The write is atomic (:func:`arap.io.atomic.write_atomic`): an earlier file at ``path`` stays intact until the
    complete new one replaces it, even when the writer is killed.

    A symbolic link is kept and the regular file it points to is replaced. A destination that is not a regular
    file, such as a folder, a FIFO, a device, a socket or a link to one, is refused and left as it is.

    Parameters
    ----------
    path : path-like
        ``.obj``, ``.off``, ``.ply``, ``.stl``, ``.glb`` or ``.gltf``.
    V : (n, 3) float array or MeshLike
        Vertex positions, or a mesh object with ``vertices`` and ``faces`` (``save_mesh(path, mesh)``).
    F : (m, 3) int array or None
        Triangles; None with a mesh object.

    Raises
    ------
    MeshFormatError
        Unknown extension, a destination that is not a regular file, or the file cannot be written (``path`` is
        then unchanged).
    MeshError
        Unusable arrays.
    """
    path = Path(path)
    from arap.io.assets import ASSET_FORMATS, MeshAsset, save_asset

    if isinstance(V, MeshAsset) and F is None:
        ft = format_of(path.name)
        family = {"glb": "gltf"}
        if ft in ASSET_FORMATS and family.get(ft, ft) == family.get(V.format, V.format):
            save_asset(path, V)
            return
    V, F = mesh_arrays(V, F)
    data = save_mesh_bytes(V, F, path.name)
    try:
        write_atomic(path, data)
    except OSError as exc:
        raise MeshFormatError(f"cannot write {path}: {exc.strerror or exc}") from exc
    logger.debug("wrote %s (%d vertices, %d faces)", path, len(V), len(F))
