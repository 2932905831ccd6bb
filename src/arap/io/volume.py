"""Volume meshes in files: tetrahedral solids, and triangle meshes (planar ones in particular), in Medit ``.mesh``,
gmsh ``.msh``, VTK ``.vtu`` and ``.vtk`` and TetGen ``.node``/``.ele`` files.

Medit, gmsh and VTK files are read and written through `meshio <https://github.com/nschloe/meshio>`_, imported only
when such a file is (``pip install 'arap[solid]'``). The file's bytes are read here, with the project's checks of
special paths (:mod:`arap.io.paths`: a FIFO, a device or a folder is refused before it is opened), and meshio parses a
private copy; writes go through a private file too and then replace the destination atomically
(:mod:`arap.io.atomic`). TetGen files are read by a strict parser of this module (a pair: given either file, both are
read or written).

A file holding tetrahedra gives ``(V, T)`` with ``T`` of shape (m, 4); boundary triangles, lines and points stored
beside them (as gmsh writes them) are left aside. A file holding only triangles gives ``(V, F)`` with ``F`` (m, 3),
``V`` as stored: (n, 2) from a two-dimensional Medit or Triangle file, else (n, 3), where a planar mesh has a constant
coordinate (``z = 0`` as gmsh and VTK store 2-d meshes), which the solver's ``energy="elements"`` deforms in its plane.
Other cells (hexahedra, wedges, pyramids, quadratic tetrahedra, quads) are refused: ARAP solids take linear
tetrahedra.

:func:`boundary_surface` gives the outward boundary triangles of a tetrahedral mesh
(:func:`arap.meshes.domain.boundary_faces`) with their own vertices, so that a solid can be written as a surface
(:func:`arap.save_mesh`).
"""

from __future__ import annotations

import contextlib
import importlib
import io
import logging
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

import arap.io.formats as formats
from arap.errors import MeshError, MeshFormatError, MeshTooLargeError
from arap.io.atomic import write_atomic
from arap.io.paths import read_regular_file, write_destination
from arap.meshes.domain import boundary_faces

__all__ = [
    "SOLID_EXTRA_HINT",
    "VOLUME_FORMATS",
    "boundary_faces",
    "boundary_surface",
    "is_volume_file",
    "load_volume_mesh",
    "load_volume_mesh_bytes",
    "read_meshio_bytes",
    "save_deformed_volume",
    "save_volume_mesh",
    "tetgen_pair",
    "volume_for_solving",
    "volume_format_of",
]

logger = logging.getLogger(__name__)

#: Volume file types, named by their extension (``node`` and ``ele`` are the two files of a TetGen mesh): the volume
#: formats of :mod:`arap.io.formats`.
VOLUME_FORMATS = tuple(suffix[1:] for suffix in formats.suffixes("volume"))

#: How to install what the Medit, gmsh and VTK files need (meshio).
SOLID_EXTRA_HINT = "pip install 'arap[solid]'"

_MESHIO_NAMES = {"mesh": "medit", "msh": "gmsh", "vtu": "vtu", "vtk": "vtk"}
_TITLES = {f.name: f.title for f in formats.FORMATS if f.kind == "volume"}
#: Cells left aside beside tetrahedra or triangles: lower-dimensional parts gmsh and Medit store with them.
_IGNORED_CELLS = ("line", "vertex")


def volume_format_of(name: str | os.PathLike[str]) -> str:
    """The volume format of a file name: ``"mesh"``, ``"msh"``, ``"vtu"``, ``"vtk"`` or ``"tetgen"`` (for ``.node``
    and ``.ele``).

    Raises
    ------
    MeshFormatError
        Another or no extension.

    Example
    -------
    >>> volume_format_of("bar.ELE"), volume_format_of("part.msh")
    ('tetgen', 'msh')
    """
    text = str(name).strip()
    base = text.replace("\\", "/").rsplit("/", 1)[-1]
    ext = base.rsplit(".", 1)[-1].lower() if "." in base else ""
    found = formats.find(f".{ext}", "volume") if ext else None
    if found is None:
        raise MeshFormatError(f"unsupported volume mesh format {ext!r} (from {text!r}); supported: "
                              f"{', '.join(VOLUME_FORMATS)}")
    return found.name


def is_volume_file(name: str | os.PathLike[str]) -> bool:
    """Whether a file name has the extension of a volume format (:data:`VOLUME_FORMATS`)."""
    try:
        volume_format_of(name)
    except MeshFormatError:
        return False
    return True


def tetgen_pair(path: str | os.PathLike[str]) -> tuple[Path, Path]:
    """The ``.node`` and ``.ele`` files of a TetGen mesh named by either of them (the other's extension in the same
    case)."""
    path = Path(path)
    upper = path.suffix.isupper()
    node, ele = (".NODE", ".ELE") if upper else (".node", ".ele")
    return path.with_suffix(node), path.with_suffix(ele)


# ---------------------------------------------------------------------------------------------- reading
def _read(path: Path) -> bytes:
    try:  # a FIFO, a device (/dev/zero) or a socket is refused before it is opened
        data = read_regular_file(path)
    except OSError as exc:
        raise MeshFormatError(f"cannot read {path}: {exc.strerror or exc}") from exc
    if not data.strip():
        raise MeshFormatError(f"{path} is empty")
    return data


def _meshio(ft: str) -> Any:
    try:
        return importlib.import_module("meshio")
    except ImportError as exc:
        raise MeshFormatError(f"{_TITLES[ft]} files are read and written through meshio, which is not installed: "
                              f"{SOLID_EXTRA_HINT}") from exc


@contextlib.contextmanager
def _quiet_meshio() -> Any:
    """meshio prints its warnings and errors on stdout and stderr; they are logged instead, and given back (the
    context's value) for messages."""
    captured = io.StringIO()
    try:
        with contextlib.redirect_stderr(captured), contextlib.redirect_stdout(captured):
            yield captured
    finally:
        if captured.getvalue().strip():
            logger.debug("meshio: %s", " ".join(captured.getvalue().split()))


def load_volume_mesh(path: str | os.PathLike[str], *,
                     max_vertices: int | None = None) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Read a tetrahedral mesh (or a triangle mesh) from a Medit, gmsh, VTK or TetGen file, in file order.

    Parameters
    ----------
    path : path-like
        ``.mesh``, ``.msh``, ``.vtu``, ``.vtk``, or either file of a TetGen pair (``.node``, ``.ele``: both are read).
    max_vertices : int or None
        Largest accepted vertex count (a TetGen file's header is checked before its data is read).

    Returns
    -------
    V : (n, 3) or (n, 2) float64 array
        Positions as stored (two columns only from a two-dimensional Medit or Triangle file).
    T : (m, 4) or (m, 3) int64 array
        Tetrahedra, or triangles when the file holds no tetrahedra; 0-based indices into ``V``.

    Raises
    ------
    MeshFormatError
        Unknown extension, a path that is not a regular file, an unreadable or malformed file (one message naming the
        first defect: counts that do not match, a bad number, an index out of range), cells other than tetrahedra and
        triangles, or meshio missing for a Medit, gmsh or VTK file.
    MeshTooLargeError
        More than ``max_vertices`` vertices.

    Example
    -------
    >>> import tempfile, os
    >>> folder = tempfile.mkdtemp()
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]]); T = np.array([[0, 1, 2, 3]])
    >>> save_volume_mesh(os.path.join(folder, "tet.ele"), V, T)
    >>> sorted(os.listdir(folder))
    ['tet.ele', 'tet.node']
    >>> W, S = load_volume_mesh(os.path.join(folder, "tet.node"))
    >>> bool(np.array_equal(W, V)), S.tolist()
    (True, [[0, 1, 2, 3]])
    """
    path = Path(path)
    ft = volume_format_of(path.name)
    if ft == "tetgen":
        V, T = _load_tetgen(path, max_vertices)
    else:
        V, T = _load_meshio(path, ft)
    if max_vertices is not None and len(V) > max_vertices:
        raise MeshTooLargeError(f"{path} has {len(V):,} vertices; at most {max_vertices:,} vertices are accepted",
                                len(V), max_vertices)
    return V, T


def _load_meshio(path: Path, ft: str) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    return read_meshio_bytes(_read(path), str(path), ft)


def load_volume_mesh_bytes(data: bytes, file_type: str, *, name: str = "uploaded mesh",
                           max_vertices: int | None = None) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Read a tetrahedral (or triangle) mesh from the bytes of a Medit, gmsh or VTK file; see
    :func:`load_volume_mesh`. A TetGen mesh, two files, is read from its path only.

    Parameters
    ----------
    data : bytes
    file_type : str
        ``"mesh"``, ``"msh"``, ``"vtu"`` or ``"vtk"`` (or a file name with that extension).
    name : str
        Label for messages.
    max_vertices : int or None

    Raises
    ------
    MeshFormatError
    MeshTooLargeError
    """
    ft = volume_format_of(file_type if "." in str(file_type) else f".{file_type}")
    if ft == "tetgen":
        raise MeshFormatError(f"{name}: a TetGen mesh is two files (.node and .ele), read from its path")
    if not bytes(data).strip():
        raise MeshFormatError(f"{name} is empty")
    V, T = read_meshio_bytes(bytes(data), name, ft)
    if max_vertices is not None and len(V) > max_vertices:
        raise MeshTooLargeError(f"{name} has {len(V):,} vertices; at most {max_vertices:,} vertices are accepted",
                                len(V), max_vertices)
    return V, T


def read_meshio_bytes(data: bytes, name: str, ft: str) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Tetrahedra (or triangles) of a Medit, gmsh or VTK file's bytes, parsed by meshio from a private copy."""
    meshio = _meshio(ft)
    with tempfile.TemporaryDirectory(prefix="arap-") as folder:
        copy = Path(folder) / f"mesh.{ft}"
        copy.write_bytes(data)
        with _quiet_meshio() as said:
            try:
                mesh = meshio.read(copy, file_format=_MESHIO_NAMES[ft])
            # meshio raises anything from its ReadError to KeyError and struct.error, and exits on some errors (after
            # printing the reason)
            except (Exception, SystemExit) as exc:
                printed = [line for line in said.getvalue().splitlines() if line.strip()]
                text = " ".join(str(exc).split()) if isinstance(exc, Exception) else ""
                if not text and printed:
                    text = " ".join(printed[0].split())
                raise MeshFormatError(f"cannot parse {name} as a {_TITLES[ft]} file: "
                                      f"{text or type(exc).__name__}") from exc
    kinds = [str(block.type) for block in mesh.cells]
    other = sorted({k for k in kinds if k not in ("tetra", "triangle", *_IGNORED_CELLS)})
    if other:
        raise MeshFormatError(f"{name} holds {', '.join(other)} cells; ARAP takes linear tetrahedra ('tetra') or "
                              "triangles: convert the other cells first (split hexahedra and wedges into "
                              "tetrahedra, use linear elements)")
    kind = "tetra" if "tetra" in kinds else "triangle"
    blocks = [np.asarray(block.data) for block in mesh.cells if block.type == kind]
    if not blocks:
        raise MeshFormatError(f"{name} holds no tetrahedra and no triangles "
                              f"({'cells: ' + ', '.join(sorted(set(kinds))) if kinds else 'no cells'})")
    V = np.asarray(mesh.points)
    if V.ndim != 2 or V.shape[1] not in (2, 3) or not np.issubdtype(V.dtype, np.number):
        raise MeshFormatError(f"{name}: its points have shape {V.shape}; 2 or 3 coordinates are needed")
    V = np.ascontiguousarray(V, dtype=np.float64)
    if kind == "tetra" and V.shape[1] != 3:
        raise MeshFormatError(f"{name} holds tetrahedra with {V.shape[1]}-d points; tetrahedra need 3 coordinates")
    T = np.ascontiguousarray(np.concatenate(blocks), dtype=np.int64)
    bad = ~np.isfinite(V).all(axis=1)
    if bad.any():
        raise MeshFormatError(f"{name}: {int(bad.sum()):,} points have NaN or infinite coordinates (first: point "
                              f"{int(np.argmax(bad))})")
    if len(T) and (T.min() < 0 or T.max() >= len(V)):
        row = int(np.argmax(((T < 0) | (T >= len(V))).any(axis=1)))
        what = "tetrahedron" if kind == "tetra" else "triangle"
        raise MeshFormatError(f"{name}: {what} {row} names point {T[row].tolist()}, but the file has {len(V):,} "
                              "points (indices 0 to n-1)")
    return V, T


# ---------------------------------------------------------------------------------------------- TetGen
def _data_lines(data: bytes, label: str) -> list[tuple[int, list[str]]]:
    """The lines of a TetGen file that hold data, with their numbers (from 1), comments and blank lines left out."""
    if b"\x00" in data:
        raise MeshFormatError(f"{label} is not a TetGen file: it holds binary data")
    text = data.decode("utf-8", errors="replace")
    found = []
    for number, line in enumerate(text.splitlines(), 1):
        tokens = line.split("#", 1)[0].split()
        if tokens:
            found.append((number, tokens))
    return found


def _header(lines: list[tuple[int, list[str]]], label: str, names: tuple[str, ...],
            defaults: tuple[int, ...]) -> list[int]:
    """The integers of a TetGen header line: ``names[0]`` (the count) required, the others defaulting."""
    if not lines:
        raise MeshFormatError(f"{label} holds no data (only comments or blank lines)")
    number, tokens = lines[0]
    if len(tokens) > len(names):
        raise MeshFormatError(f"{label}, line {number}: the header has {len(tokens)} numbers; at most "
                              f"{len(names)} ({', '.join(names)}) are expected")
    values = list(defaults)
    for k, token in enumerate(tokens):
        try:
            values[k] = int(token)
        except ValueError:
            raise MeshFormatError(f"{label}, line {number}: the header's {names[k]} must be an integer, got "
                                  f"{token!r}") from None
        if values[k] < 0:
            raise MeshFormatError(f"{label}, line {number}: the header's {names[k]} is negative ({values[k]})")
    return values


def _table(lines: list[tuple[int, list[str]]], count: int, columns: int, label: str,
           what: str) -> tuple[NDArray[np.str_], list[int]]:
    """The ``count`` rows of ``columns`` tokens after the header line, as strings, with their line numbers.

    Nothing is allocated from the header's count: the rows are the lines read, so a header announcing more than the
    file holds costs nothing but its message.
    """
    rows = lines[1:]
    if len(rows) < count:
        raise MeshFormatError(f"{label} ends early: its header announces {count:,} {what}, but only {len(rows):,} "
                              "lines follow (a truncated file?)")
    if len(rows) > count:
        raise MeshFormatError(f"{label}, line {rows[count][0]}: more lines than the {count:,} {what} its header "
                              "announces")
    for number, tokens in rows:
        if len(tokens) != columns:
            raise MeshFormatError(f"{label}, line {number}: {len(tokens)} numbers where the header asks for "
                                  f"{columns} (an index, then the values its header announces)")
    return np.array([tokens for _, tokens in rows], dtype=str).reshape(count, columns), [n for n, _ in rows]


def _numbers(table: NDArray[np.str_], numbers: list[int], kind: type, label: str, what: str) -> NDArray[Any]:
    """``table`` converted to ``kind`` (int or float), naming the first token that is not such a number."""
    dtype = np.int64 if kind is int else np.float64
    try:
        out = table.astype(dtype)
    except (ValueError, OverflowError):
        for row, tokens in enumerate(table):
            for token in tokens:
                try:
                    kind(str(token))
                except (ValueError, OverflowError):
                    word = "an integer" if kind is int else "a number"
                    raise MeshFormatError(f"{label}, line {numbers[row]}: {what} must be {word}, got "
                                          f"{str(token)!r}") from None
        raise
    if kind is float and not np.isfinite(out).all():
        row = int(np.argmax(~np.isfinite(out).all(axis=1)))
        raise MeshFormatError(f"{label}, line {numbers[row]}: {what} must be finite, got {table[row].tolist()}")
    return out


def _consecutive(ids: NDArray[np.int64], numbers: list[int], label: str, what: str) -> int:
    """The first index of rows numbered consecutively from 0 or 1 (TetGen's rule)."""
    if not len(ids):
        return 0
    first = int(ids[0])
    if first not in (0, 1):
        raise MeshFormatError(f"{label}, line {numbers[0]}: the first {what} is numbered {first}; TetGen numbers "
                              "from 0 or 1")
    wrong = ids != first + np.arange(len(ids))
    if wrong.any():
        row = int(np.argmax(wrong))
        raise MeshFormatError(f"{label}, line {numbers[row]}: {what} {int(ids[row])} where {first + row} is expected "
                              f"({what}s are numbered consecutively)")
    return first


def _load_tetgen(path: Path, max_vertices: int | None) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    node_path, ele_path = tetgen_pair(path)
    for part in (node_path, ele_path):
        if part != path and not part.exists() and not part.is_symlink():
            raise MeshFormatError(f"{path} is one file of a TetGen mesh; its pair {part} does not exist")
    node_data = _read(node_path)
    node_lines = _data_lines(node_data, str(node_path))
    n, dim, n_attributes, n_markers = _header(node_lines, str(node_path),
                                              ("point count", "dimension", "attribute count", "boundary marker flag"),
                                              (0, 3, 0, 0))
    label = str(node_path)
    if dim not in (2, 3):
        raise MeshFormatError(f"{label}: dimension {dim}; TetGen points have 3 coordinates (Triangle's, 2)")
    if n_markers > 1:
        raise MeshFormatError(f"{label}: the boundary marker flag is {n_markers}; it is 0 or 1")
    if n == 0:
        raise MeshFormatError(f"{label} announces no points")
    if max_vertices is not None and n > max_vertices:
        raise MeshTooLargeError(f"{label} holds {n:,} points; at most {max_vertices:,} vertices are accepted",
                                n, max_vertices)
    table, numbers = _table(node_lines, n, 1 + dim + n_attributes + n_markers, label, "points")
    first = _consecutive(_numbers(table[:, :1], numbers, int, label, "a point number")[:, 0], numbers, label,
                         "point")
    V = _numbers(table[:, 1:1 + dim], numbers, float, label, "coordinates")
    if n_attributes:
        _numbers(table[:, 1 + dim:1 + dim + n_attributes], numbers, float, label, "attributes")
    if n_markers:
        _numbers(table[:, 1 + dim + n_attributes:], numbers, int, label, "a boundary marker")
    del table

    ele_data = _read(ele_path)
    label = str(ele_path)
    ele_lines = _data_lines(ele_data, label)
    m, corners, n_regions = _header(ele_lines, label, ("element count", "nodes per element", "attribute count"),
                                    (0, 4, 0))
    if corners in (10, 6):
        raise MeshFormatError(f"{label} holds quadratic elements ({corners} nodes each); ARAP takes linear "
                              "tetrahedra (4 nodes) or triangles (3)")
    if corners != dim + 1:
        raise MeshFormatError(f"{label}: {corners} nodes per element with {dim}-d points; TetGen's tetrahedra have 4 "
                              "(3-d points), Triangle's triangles 3 (2-d points)")
    if m == 0:
        raise MeshFormatError(f"{label} announces no elements")
    table, numbers = _table(ele_lines, m, 1 + corners + n_regions, label, "elements")
    _consecutive(_numbers(table[:, :1], numbers, int, label, "an element number")[:, 0], numbers, label, "element")
    T = _numbers(table[:, 1:1 + corners], numbers, int, label, "point numbers")
    if n_regions:
        _numbers(table[:, 1 + corners:], numbers, float, label, "attributes")
    T -= first
    outside = ((T < 0) | (T >= n)).any(axis=1)
    if outside.any():
        row = int(np.argmax(outside))
        raise MeshFormatError(f"{label}, line {numbers[row]}: element {row + first} names point "
                              f"{int(T[row][(T[row] < 0) | (T[row] >= n)][0]) + first}, but {node_path} numbers its "
                              f"{n:,} points from {first} to {n - 1 + first}")
    return np.ascontiguousarray(V), np.ascontiguousarray(T)


# ---------------------------------------------------------------------------------------------- writing
def _check_for_saving(V: Any, T: Any) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    V = np.asarray(V)
    T = np.asarray(T)
    if V.ndim != 2 or V.shape[1] not in (2, 3) or not np.issubdtype(V.dtype, np.number):
        raise MeshError(f"vertices must have shape (n, 3), or (n, 2) for a planar mesh, got {V.shape}")
    if T.ndim != 2 or T.shape[1] not in (3, 4) or not np.issubdtype(T.dtype, np.integer):
        raise MeshError(f"elements must be integer tetrahedra (m, 4) or triangles (m, 3), got {T.shape} of {T.dtype}")
    if T.shape[1] == 4 and V.shape[1] != 3:
        raise MeshError(f"tetrahedra need 3-d vertices, got shape {V.shape}")
    V = np.ascontiguousarray(V, dtype=np.float64)
    T = np.ascontiguousarray(T, dtype=np.int64)
    if len(T) and (T.min() < 0 or T.max() >= len(V)):
        raise MeshError(f"element indices out of range [0, {len(V)})")
    bad = ~np.isfinite(V).all(axis=1)
    if bad.any():  # such a file would not load again
        raise MeshError(f"{int(bad.sum())} vertices have NaN or infinite coordinates (vertex {int(np.argmax(bad))} "
                        "first); the file is not written")
    return V, T


def _tetgen_bytes(V: NDArray[np.float64], T: NDArray[np.int64]) -> tuple[bytes, bytes]:
    """A ``.node`` and an ``.ele`` file numbering from 1 (TetGen's default), coordinates with 17 significant digits
    (exact for every double)."""
    n, dim = V.shape
    m, k = T.shape
    node_rows = (("%d" + " %.17g" * dim + "\n") * n) % tuple(np.column_stack([np.arange(1, n + 1), V]).ravel().tolist())
    ele_rows = (("%d" + " %d" * k + "\n") * m) % tuple(np.column_stack([np.arange(1, m + 1), T + 1]).ravel().tolist())
    node = f"# written by arap\n{n} {dim} 0 0\n" + node_rows
    ele = f"# written by arap\n{m} {k} 0\n" + ele_rows
    return node.encode("ascii"), ele.encode("ascii")


def _meshio_bytes(V: NDArray[np.float64], T: NDArray[np.int64], ft: str) -> bytes:
    meshio = _meshio(ft)
    if V.shape[1] == 2 and ft != "mesh":  # gmsh and VTK store 3 coordinates: a planar mesh lies in z = 0
        V = np.column_stack([V, np.zeros(len(V))])
    mesh = meshio.Mesh(V, [("tetra" if T.shape[1] == 4 else "triangle", T)])
    options = {"binary": False} if ft == "msh" else {}  # gmsh 4.1 text; VTK binary (exact), VTU zlib-compressed
    with tempfile.TemporaryDirectory(prefix="arap-") as folder:
        copy = Path(folder) / f"mesh.{ft}"
        try:
            with _quiet_meshio():
                meshio.write(copy, mesh, file_format=_MESHIO_NAMES[ft], **options)
        except Exception as exc:
            raise MeshFormatError(f"cannot write a {_TITLES[ft]} file: {exc}") from exc
        return copy.read_bytes()


def save_volume_mesh(path: str | os.PathLike[str], V: NDArray[np.floating], T: NDArray[np.integer]) -> None:
    """Write a tetrahedral mesh (or a triangle mesh) as a Medit, gmsh, VTK or TetGen file; the format follows the
    extension.

    Coordinates round-trip exactly (text with 17 significant digits, or binary doubles). A TetGen mesh is written as
    its pair of files, ``.node`` and ``.ele`` beside each other, numbered from 1. A planar mesh given with two
    coordinates keeps them in Medit and TetGen (Triangle's format) files; gmsh and VTK files get ``z = 0``.

    The write is atomic (:func:`arap.io.atomic.write_atomic`): an earlier file stays intact until the complete new one
    replaces it; a destination that is not a regular file is refused before anything is written.

    Parameters
    ----------
    path : path-like
        ``.mesh``, ``.msh``, ``.vtu``, ``.vtk``, ``.node`` or ``.ele``.
    V : (n, 3) or (n, 2) float array
    T : (m, 4) or (m, 3) int array
        Tetrahedra or triangles, 0-based.

    Raises
    ------
    MeshFormatError
        Unknown extension, a destination that is not a regular file or cannot be written, meshio missing.
    MeshError
        Unusable arrays (wrong shapes, indices out of range, non-finite coordinates); nothing is written.

    Examples
    --------
    >>> import os, tempfile, arap
    >>> V, T = arap.box_tetrahedra(2, 2, 2)
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = os.path.join(folder, "box.mesh")
    ...     arap.save_volume_mesh(path, V, T)
    ...     V2, T2 = arap.load_volume_mesh(path)
    >>> bool((T2 == T).all() and abs(V2 - V).max() < 1e-12)
    True
    """
    path = Path(path)
    ft = volume_format_of(path.name)
    V, T = _check_for_saving(V, T)
    targets = list(tetgen_pair(path)) if ft == "tetgen" else [path]
    for target in targets:  # every destination checked before anything is written
        try:
            write_destination(target)
        except OSError as exc:
            raise MeshFormatError(f"cannot write {target}: {exc.strerror or exc}") from exc
    payloads = list(_tetgen_bytes(V, T)) if ft == "tetgen" else [_meshio_bytes(V, T, ft)]
    for target, data in zip(targets, payloads, strict=True):
        try:
            write_atomic(target, data)
        except OSError as exc:
            raise MeshFormatError(f"cannot write {target}: {exc.strerror or exc}") from exc
    logger.debug("wrote %s (%d vertices, %d elements)", path, len(V), len(T))


# ---------------------------------------------------------------------------------------------- boundary
def boundary_surface(V: NDArray[np.floating], T: NDArray[np.integer]) -> tuple[
        NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]]:
    """The boundary surface of a tetrahedral mesh with its own vertices: the boundary vertices only, in their order in
    ``V`` (interior vertices left out).

    Returns
    -------
    V_surface : (k, 3) float64 array
    F : (f, 3) int64 array
        Outward triangles (:func:`arap.meshes.domain.boundary_faces`) into ``V_surface``.
    vertices : (k,) int64 array
        The index in ``V`` of every surface vertex (increasing): ``V_surface = V[vertices]``.

    Example
    -------
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [.2, .2, .2]])
    >>> _, F, kept = boundary_surface(V, np.array([[0, 1, 2, 4], [0, 1, 4, 3], [0, 4, 2, 3], [4, 1, 2, 3]]))
    >>> len(F), kept.tolist()
    (4, [0, 1, 2, 3])
    """
    P = np.asarray(V, dtype=np.float64)
    F = boundary_faces(T, P)
    vertices = np.unique(F)
    index = np.full(len(P), -1, dtype=np.int64)
    index[vertices] = np.arange(len(vertices))
    return P[vertices], index[F], vertices


# ---------------------------------------------------------------------------------------------- deforming
def volume_for_solving(path: str | os.PathLike[str], *, max_vertices: int | None = None) -> tuple[
        NDArray[np.float64], NDArray[np.int64], int]:
    """A volume file as a solver takes it (:func:`load_volume_mesh`, with ``z = 0`` added to a planar mesh stored with
    two coordinates).

    Returns
    -------
    V : (n, 3) float64 array
    T : (m, 4) or (m, 3) int64 array
    columns : int
        Coordinates per vertex in the file (2 or 3), for :func:`save_deformed_volume`.
    """
    V, T = load_volume_mesh(path, max_vertices=max_vertices)
    columns = V.shape[1]
    if columns == 2:
        V = np.column_stack([V, np.zeros(len(V))])
    return V, T, columns


def save_deformed_volume(path: str | os.PathLike[str], U: NDArray[np.floating], T: NDArray[np.integer],
                         columns: int = 3) -> NDArray[np.float64]:
    """Write a deformed volume mesh: to a volume format as it is (with its file's ``columns``), to a surface format
    (:func:`arap.io.save_mesh`) as its boundary surface (tetrahedra) or its triangles.

    Returns
    -------
    (k, 2 or 3) float64 array
        The positions written (the boundary vertices, in their order, for a solid written as a surface).

    Raises
    ------
    MeshFormatError
        An extension of no mesh format, a destination that cannot be written.
    """
    from arap.io.meshfile import save_mesh

    P = np.asarray(U, dtype=np.float64)
    if is_volume_file(path):
        out = P[:, :columns] if columns == 2 else P
        save_volume_mesh(path, out, T)
        return out
    if np.shape(T)[1] == 4:
        surface, faces, _ = boundary_surface(P, T)
        save_mesh(path, surface, faces)
        return surface
    save_mesh(path, P, T)
    return P
