"""Reading and writing triangle meshes (OBJ, OFF, PLY, STL, glTF/GLB), from paths or from bytes.

Reading goes through format parsers without any processing, so vertices keep their file order (vertex indices in
constraint files refer to that order): OBJ through :mod:`arap.io.fastobj` or :mod:`arap.io.obj_asset` (texture
coordinates, normals, groups and materials do not change the ``v`` numbering), glTF and GLB through
:mod:`arap.io.gltf_asset` (the POSITION accessors of the triangle primitives in order, node transforms applied),
OFF, PLY and STL through trimesh's parsers. Polygons are fan-triangulated. Attributes other than positions are
read and written by :mod:`arap.io.assets` (:func:`~arap.io.assets.load_asset`, :func:`~arap.io.assets.save_asset`,
or :func:`save_mesh` given a :class:`~arap.io.assets.MeshAsset`). By default the loaded mesh goes
through :func:`arap.meshes.repair.repair_mesh`, which welds STL triangle soups and drops degenerate faces; a clean mesh
comes back unchanged.

Before parsing, :mod:`arap.io.screening` decodes text robustly, refuses binary junk and OBJ faces naming vertex
0, and reads the vertex count from the header or the lines, so that a caller's ``max_vertices`` refuses a huge file
before the slow parse.

Writing gives exact round trips where the format allows (OBJ and OFF with 17 significant digits, PLY as binary
doubles), atomically (:mod:`arap.io.atomic`); a textured :class:`~arap.io.assets.MeshAsset` is written with its
attributes in its own format.

Each format's reader and writer here is named by its record in :mod:`arap.io.formats`, which the functions of this
module read to pick them.
"""

from __future__ import annotations

import io
import logging
import os
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

import arap.io.formats as formats
from arap.errors import MeshError, MeshFormatError, MeshTooLargeError
from arap.io.atomic import write_atomic
from arap.io.fastobj import parse_plain_obj
from arap.io.paths import read_regular_file
from arap.io.screening import (
    announced_faces,
    check_size,
    screen,
)
from arap.meshes.mesh import MeshLike, mesh_arrays, triangulate_polygons
from arap.meshes.repair import RepairResult, repair_mesh

if TYPE_CHECKING:
    from arap.io.assets import MeshAsset

__all__ = [
    "MESH_FORMATS",
    "format_of",
    "load_mesh",
    "load_mesh_bytes",
    "load_mesh_bytes_with_report",
    "load_mesh_with_report",
    "mesh_of_asset",
    "save_mesh",
    "save_mesh_bytes",
]

logger = logging.getLogger(__name__)

#: File types read and written, named by their usual extension (the surface formats of :mod:`arap.io.formats`).
MESH_FORMATS = formats.names("surface")


def format_of(name: str | os.PathLike[str]) -> str:
    """The mesh format of a file name or of a bare type name (``"mesh.OBJ"``, ``".obj"`` and ``"obj"`` all give
    ``"obj"``).

    Raises
    ------
    MeshFormatError
        Unsupported or missing extension.
    """
    text = str(name).strip()
    base = text.replace("\\", "/").rsplit("/", 1)[-1]
    ext = base.rsplit(".", 1)[-1].lower()
    if ext not in MESH_FORMATS:
        volume = (" (a volume mesh: arap.load_volume_mesh reads it; arap deform, animate, batch, constraints and info "
                  "take it)" if formats.find(f".{ext}", "volume") is not None else "")
        raise MeshFormatError(
            f"unsupported mesh format {ext!r} (from {text!r}){volume}; supported: {', '.join(MESH_FORMATS)}"
        )
    return ext


# ---------------------------------------------------------------------------------------------- reading
def _named(file_type: str) -> str:
    """"an OBJ", "an OFF", "a PLY", "an STL" (for messages)."""
    name = file_type.upper()
    return f"{'an' if name[0] in 'AEFHILMNORSX' else 'a'} {name}"


def _parse_error(exc: Exception, file_type: str, label: str) -> MeshFormatError:
    """A parser's failure said in the file's terms (not numpy's): 1-based OBJ indices, counts that do not match."""
    what = f"cannot parse {label} as {file_type.upper()}"
    text = str(exc)
    out_of_range = re.search(r"index (-?\d+) is out of bounds for axis 0 with size (\d+)", text)
    if isinstance(exc, IndexError) and out_of_range:
        index, size = int(out_of_range.group(1)), int(out_of_range.group(2))
        shown = index + 1 if file_type == "obj" and index >= 0 else index  # OBJ counts vertices from 1
        return MeshFormatError(f"{what}: a face refers to vertex {shown}, but the file has {size:,} vertices")
    if isinstance(exc, IndexError):
        return MeshFormatError(f"{what}: a face refers to a vertex the file does not have ({text})")
    if isinstance(exc, ValueError) and ("cannot reshape" in text or "inhomogeneous" in text):
        return MeshFormatError(f"{what}: the file ends early or its data does not match its counts (truncated?)")
    return MeshFormatError(f"{what}: {text}")


_PLY_TEXTURE = re.compile(rb"^[ \t]*(?:comment[ \t]+TextureFile|property[ \t]+list[ \t]+\w+[ \t]+\w+[ \t]+texcoord)\b",
                          re.MULTILINE | re.IGNORECASE)
"""A PLY header naming a texture image or giving texture coordinates per face corner."""


def _parse(stream: io.BytesIO, file_type: str, label: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces (polygons triangulated) as stored, without any processing."""
    from trimesh.exchange.load import mesh_loaders

    if file_type == "ply" and _PLY_TEXTURE.search(stream.getvalue()[:stream.getvalue().find(b"end_header")]):
        # trimesh would split the vertices at the seams of per-face texture coordinates (so that the mesh no longer
        # matches the file's numbering) and log a traceback for the texture file it cannot open
        from arap.io.ply_asset import read_ply_asset

        asset = read_ply_asset(stream.getvalue(), label, None, None, textures=False)
        return asset.vertices, asset.faces
    kwargs: dict[str, object] = {"file_type": file_type}
    if file_type == "obj":
        kwargs.update(skip_materials=True, maintain_order=True)
    try:
        loaded = mesh_loaders[file_type](stream, **kwargs)
    except Exception as exc:  # the parsers raise anything from ValueError to struct.error
        error = _parse_error(exc, file_type, label)
        if file_type == "ply":  # trimesh refuses binary polygons of several sizes: read them with arap's own parser
            ply = _ply_polygons(stream.getvalue(), label)
            if ply is not None:
                return ply
        raise error from exc
    parts = list(loaded["geometry"].values()) if "geometry" in loaded else [loaded]
    blocks: list[tuple[np.ndarray, np.ndarray]] = []
    for part in parts:
        if not isinstance(part, dict) or "vertices" not in part:
            continue
        try:  # a line cut short (a truncated file) leaves a coordinate count that is not a multiple of 3
            V = np.asarray(part["vertices"], dtype=np.float64).reshape(-1, 3)
            F = _faces_array(part.get("faces"))
        except (ValueError, IndexError) as exc:
            raise _parse_error(exc, file_type, label) from exc
        blocks.append((V, F))
    if not blocks or all(len(V) == 0 for V, _ in blocks):
        raise MeshFormatError(f"{label} contains no vertices (empty, or not {_named(file_type)} file)")
    if all(len(b[0]) == len(blocks[0][0]) and np.array_equal(b[0], blocks[0][0]) for b in blocks):
        # Parts indexing one shared vertex list (OBJ groups and materials keep file order).
        V = blocks[0][0]
        F = np.concatenate([b[1] for b in blocks])
    else:
        offsets = np.cumsum([0] + [len(b[0]) for b in blocks[:-1]])
        V = np.concatenate([b[0] for b in blocks])
        F = np.concatenate([b[1] + off for b, off in zip(blocks, offsets, strict=True)])
    if len(F) == 0:
        raise MeshFormatError(f"{label} has {len(V):,} vertices but no faces (a point cloud, or a truncated "
                              "file?); a surface is needed")
    return V, F


def _parse_obj(data: bytes, label: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (``v`` lines in order) and triangles of an OBJ file with any statements: texture coordinates,
    normals, groups and materials leave the vertex numbering as it is."""
    from arap.io.assets import fan
    from arap.io.obj_asset import parse_obj

    V, obj, _, _ = parse_obj(data, label)
    if len(V) == 0:
        raise MeshFormatError(f"{label} contains no vertices (empty, or not an OBJ file)")
    if len(obj.face_sizes) == 0:
        raise MeshFormatError(f"{label} has {len(V):,} vertices but no faces (a point cloud, or a truncated "
                              "file?); a surface is needed")
    return V, fan(obj.face_sizes, obj.corner_vertices)


def _ply_polygons(data: bytes, label: str) -> tuple[np.ndarray, np.ndarray] | None:
    """Vertices and triangles of a PLY file read by :mod:`arap.io.ply_asset`, or None when it cannot read it either
    (the first parser's error is then the one reported)."""
    from arap.io.ply_asset import read_ply_asset

    try:
        asset = read_ply_asset(data, label, None, None)
    except MeshError:
        return None
    return asset.vertices, asset.faces


def _faces_array(faces: Any) -> np.ndarray:
    if faces is None:
        return np.zeros((0, 3), dtype=np.int64)
    if isinstance(faces, np.ndarray) and faces.dtype != object:
        if faces.size == 0:
            return np.zeros((0, 3), dtype=np.int64)
        F = faces.astype(np.int64).reshape(len(faces), -1)
        return F if F.shape[1] == 3 else triangulate_polygons(F)
    return triangulate_polygons([list(np.asarray(f).ravel()) for f in faces])


def _finish(
    V: np.ndarray, F: np.ndarray, repair: bool, label: str
) -> tuple[np.ndarray, np.ndarray, RepairResult]:
    if repair:
        try:
            result = repair_mesh(V, F)
        except MeshError as exc:
            raise MeshError(f"{label}: {exc}") from exc
        if result.report:
            logger.info("%s: %s", label, "; ".join(result.report))
        return result.V, result.F, result
    return V, F, RepairResult.identity(V, F)


def read_obj(data: bytes, name: str, folder: Path | None, max_vertices: int | None) -> tuple[
        np.ndarray, np.ndarray]:
    """Vertices and triangles of screened OBJ bytes, as stored: the fast reader for plain files (faces numbered from
    1 up), else the full one, which refuses vertex 0 and short faces naming the line."""
    plain = parse_plain_obj(data)
    return plain if plain is not None else _parse_obj(data, name)


def read_off(data: bytes, name: str, folder: Path | None, max_vertices: int | None) -> tuple[
        np.ndarray, np.ndarray]:
    """Vertices and triangles of screened OFF bytes, as stored."""
    return _parse(io.BytesIO(data), "off", name)


def read_ply(data: bytes, name: str, folder: Path | None, max_vertices: int | None) -> tuple[
        np.ndarray, np.ndarray]:
    """Vertices and triangles of screened PLY bytes, as stored."""
    return _parse(io.BytesIO(data), "ply", name)


def read_stl(data: bytes, name: str, folder: Path | None, max_vertices: int | None) -> tuple[
        np.ndarray, np.ndarray]:
    """Vertices and triangles of screened STL bytes: the triangle soup as stored (welded by repair)."""
    return _parse(io.BytesIO(data), "stl", name)


def read_gltf(data: bytes, name: str, folder: Path | None, max_vertices: int | None) -> tuple[
        np.ndarray, np.ndarray]:
    """Vertices and triangles of a glTF or GLB file: the POSITION accessors of its triangle primitives in order,
    node transforms applied (:func:`arap.io.gltf_asset.read_gltf_asset`); its buffers looked for in ``folder``."""
    from arap.io.gltf_asset import read_gltf_asset

    asset = read_gltf_asset(data, name, folder, max_vertices)
    return asset.vertices, asset.faces


def mesh_of_asset(asset: MeshAsset, *, repair: bool = True, name: str = "mesh") -> tuple[
        np.ndarray, np.ndarray, RepairResult]:
    """The mesh to solve of an asset read from a glTF or GLB file, as :func:`load_mesh_with_report` gives it for
    that file (so a caller that needs the asset too reads the file once).

    Parameters
    ----------
    asset : arap.io.assets.MeshAsset
    repair : bool
    name : str
        The file's name, for messages.

    Returns
    -------
    V : (n, 3) float64 array
    F : (m, 3) int64 array
    repair : RepairResult
    """
    return _finish(asset.vertices, asset.faces, repair, name)


def load_mesh_bytes_with_report(
    data: bytes, file_type: str, *, repair: bool = True, name: str = "uploaded mesh", max_vertices: int | None = None,
    folder: str | os.PathLike[str] | None = None,
) -> tuple[np.ndarray, np.ndarray, RepairResult]:
    """Read a mesh from the bytes of a file, with what repair did.

    Parameters
    ----------
    data : bytes
        The whole file content.
    file_type : str
        ``"obj"``, ``"off"``, ``"ply"``, ``"stl"``, ``"glb"`` or ``"gltf"`` (a file name or ``".obj"`` also works).
    repair : bool
        Run :func:`arap.meshes.repair.repair_mesh` (weld duplicates, drop degenerate faces). If False the arrays are
        returned as stored, unvalidated, and the result has an identity ``vertex_map``.
    name : str
        Label for messages.
    max_vertices : int or None
        Largest accepted vertex count, checked against the file's header (OFF, PLY, binary STL) or its lines (OBJ,
        ASCII STL) before parsing and against the loaded mesh after repair. An STL soup may hold up to twice as
        many triangles (a closed surface has about half as many vertices as triangles).

    Returns
    -------
    V : (n, 3) float64 array
    F : (m, 3) int64 array
    result : RepairResult
        ``report`` lines, ``counts`` and ``vertex_map`` (file vertex index → returned index or -1).

    Raises
    ------
    MeshTooLargeError
        More than ``max_vertices`` vertices.
    MeshFormatError
        Unknown type, binary data where text is expected, unparsable content, an OBJ face naming vertex 0, no
        vertices or no faces.
    MeshError
        The content cannot be repaired (faces using NaN vertices or out-of-range indices, coordinates of an
        unsupported scale).
    """
    fmt = formats.get(format_of(file_type))
    data = bytes(data)
    if fmt.screen:  # text decoded, junk refused, a huge file refused from its header before the slow parse
        check_size(data, fmt.name, name, max_vertices)
        data = screen(data, fmt.name, name, obj_zero_index=False)
    read = fmt.function("reader")
    assert read is not None
    V, F = read(data, name, Path(folder) if folder is not None else None, max_vertices)
    announced = announced_faces(data, fmt.name)
    if announced is not None and len(F) < announced:  # polygons are triangulated: never fewer triangles than faces
        raise MeshFormatError(f"{name} ends early: its header announces {announced:,} faces, but only {len(F):,} "
                              "could be read (a truncated file?)")
    V, F, result = _finish(V, F, repair, name)
    if max_vertices is not None and len(V) > max_vertices:
        raise MeshTooLargeError(f"{name} has {len(V):,} vertices; at most {max_vertices:,} vertices are accepted",
                                len(V), max_vertices)
    return V, F, result


def load_mesh_bytes(data: bytes, file_type: str, *, repair: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Read a mesh from the bytes of a file; see :func:`load_mesh_bytes_with_report`.

    Returns
    -------
    V : (n, 3) float64 array
    F : (m, 3) int64 array

    Examples
    --------
    >>> import arap
    >>> V, F = arap.load_mesh_bytes(b"OFF\\n3 1 0\\n0 0 0\\n1 0 0\\n0 1 0\\n3 0 1 2\\n", "off")
    >>> V.shape, F.tolist()
    ((3, 3), [[0, 1, 2]])
    """
    V, F, _ = load_mesh_bytes_with_report(data, file_type, repair=repair)
    return V, F


def load_mesh_with_report(
    path: str | os.PathLike[str], *, repair: bool = True, max_vertices: int | None = None
) -> tuple[np.ndarray, np.ndarray, RepairResult]:
    """Read a mesh file, with what repair did; see :func:`load_mesh_bytes_with_report`.

    Raises
    ------
    MeshFormatError
        Unknown extension, missing or unreadable file, a path that is not a regular file (a folder, a FIFO, a
        device, a socket, or a link to one), unparsable content, no faces.

    Examples
    --------
    A square with a vertex that no face uses: the vertex is dropped, and the report says so:

    >>> import os, tempfile, arap
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "square.obj")
    ...     with open(path, "w") as file:
    ...         _ = file.write("v 0 0 0\\nv 1 0 0\\nv 1 1 0\\nv 0 1 0\\nv 5 5 5\\nf 1 2 3\\nf 1 3 4\\n")
    ...     V, F, repair = arap.load_mesh_with_report(path)
    >>> V.shape, repair.report
    ((4, 3), ['dropped 1 vertices used by no face'])
    """
    path = Path(path)
    if path.is_dir():
        raise MeshFormatError(f"{path} is a folder, not a mesh file")
    ft = format_of(path.name)
    try:  # a FIFO, a device (/dev/zero) or a socket is refused before it is opened
        data = read_regular_file(path)
    except OSError as exc:
        raise MeshFormatError(f"cannot read {path}: {exc.strerror or exc}") from exc
    return load_mesh_bytes_with_report(data, ft, repair=repair, name=str(path), max_vertices=max_vertices,
                                       folder=path.parent)


def load_mesh(path: str | os.PathLike[str], *, repair: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Read a triangle mesh file (OBJ, OFF, PLY, STL, GLB or glTF) in file vertex order.

    Parameters
    ----------
    path : path-like
    repair : bool
        Weld duplicate vertices (STL soups), drop degenerate, duplicate and unused elements
        (:func:`arap.meshes.repair.repair_mesh`); a clean mesh is returned unchanged.

    Returns
    -------
    V : (n, 3) float64 array
    F : (m, 3) int64 array

    Examples
    --------
    >>> import os, tempfile, arap
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "sphere.obj")
    ...     arap.save_mesh(path, *arap.sphere(1))
    ...     V, F = arap.load_mesh(path)
    >>> V.shape, F.shape
    ((42, 3), (80, 3))
    """
    V, F, _ = load_mesh_with_report(path, repair=repair)
    return V, F


# ---------------------------------------------------------------------------------------------- writing
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


def ply_bytes(V: np.ndarray, F: np.ndarray) -> bytes:
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

    Examples
    --------
    >>> import arap
    >>> data = arap.save_mesh_bytes(*arap.sphere(1), "off")
    >>> data.splitlines()[:2]
    [b'OFF', b'42 80 0']
    >>> arap.load_mesh_bytes(data, "off")[1].shape
    (80, 3)
    """
    V, F = _check_for_saving(V, F)
    write = formats.get(format_of(file_type)).function("writer")
    assert write is not None
    return bytes(write(V, F))


def obj_bytes(V: np.ndarray, F: np.ndarray) -> bytes:
    """OBJ text, exact (17 significant digits)."""
    return _text_bytes(V, F, "", "v ", "f ", 1)


def off_bytes(V: np.ndarray, F: np.ndarray) -> bytes:
    """OFF text, exact (17 significant digits)."""
    return _text_bytes(V, F, f"OFF\n{len(V)} {len(F)} 0\n", "", "3 ", 0)


def _gltf_geometry(V: np.ndarray, F: np.ndarray, binary: bool) -> bytes:
    from arap.io.gltf_asset import geometry_glb

    if np.abs(V).max(initial=0.0) > np.finfo(np.float32).max:
        raise MeshError("coordinates beyond the range of single precision, which glTF stores; not written")
    return geometry_glb(V, F, binary=binary)


def glb_bytes(V: np.ndarray, F: np.ndarray) -> bytes:
    """GLB: single precision positions and 32-bit indices."""
    return _gltf_geometry(V, F, True)


def gltf_bytes(V: np.ndarray, F: np.ndarray) -> bytes:
    """glTF with its buffer in a data URI: single precision positions and 32-bit indices."""
    return _gltf_geometry(V, F, False)


def stl_bytes(V: np.ndarray, F: np.ndarray) -> bytes:
    """Binary STL, single precision (a triangle soup, by the format's definition)."""
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

    Examples
    --------
    >>> import os, tempfile, arap
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     arap.save_mesh(os.path.join(folder, "sphere.ply"), *arap.sphere(1))   # the extension picks the format
    ...     print(os.listdir(folder))
    ['sphere.ply']
    """
    path = Path(path)
    from arap.io.assets import MeshAsset, save_asset

    if isinstance(V, MeshAsset) and F is None:
        fmt = formats.get(format_of(path.name))
        if fmt.asset and formats.family(fmt.name) == formats.family(V.format):
            save_asset(path, V)
            return
    V, F = mesh_arrays(V, F)
    data = save_mesh_bytes(V, F, path.name)
    try:
        write_atomic(path, data)
    except OSError as exc:
        raise MeshFormatError(f"cannot write {path}: {exc.strerror or exc}") from exc
    logger.debug("wrote %s (%d vertices, %d faces)", path, len(V), len(F))
