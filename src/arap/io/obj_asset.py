"""OBJ files with their attributes: ``vt``/``vn`` per corner, ``usemtl``, ``g``/``o``/``s``, ``mtllib`` with the MTL
files and the texture images they name (see :mod:`arap.io.assets`).

Vertices keep the numbering of the ``v`` lines; polygons are kept (and fan-triangulated for the solve); negative
(relative) indices are resolved when reading and written as absolute ones. Lines the reader does not interpret
(``l``, ``p``, curves) are kept for writing (:mod:`arap.io.obj_write`); comments are not kept.
"""

from __future__ import annotations

import itertools
import logging
import posixpath
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arap.errors import MeshError, MeshFormatError, MeshTooLargeError
from arap.io.assets import MeshAsset, fan, read_referenced
from arap.io.screening import screen

__all__ = ["ObjData", "map_file_name", "may_have_attributes", "mtl_texture_references", "parse_obj", "read_obj_asset"]

logger = logging.getLogger(__name__)

#: MTL statements naming a texture image (options first, then the file name to the end of the line).
_MAP_KEYS = {"map_ka", "map_kd", "map_ks", "map_ns", "map_d", "map_bump", "bump", "disp", "decal", "refl", "norm",
             "map_pr", "map_pm", "map_ps", "map_ke", "map_rma", "map_orm", "map_tr"}
_COLOUR_LINE = re.compile(rb"^v[ \t]+(?:\S+[ \t]+){5}\S+", re.M)
_MTLLIB_LINE = re.compile(rb"^[ \t]*mtllib[ \t]+\S", re.M)


@dataclass(eq=False)
class ObjData:
    """What an OBJ file says beyond positions and triangles (see :class:`arap.io.assets.MeshAsset`).

    Attributes
    ----------
    vertex_extra : (n, k) float64 array
        Numbers after ``x y z`` on ``v`` lines (colours, weights), NaN where a line has fewer.
    texcoords : (t, 3) float64 array
        ``vt`` lines, NaN where a line has fewer than 3 numbers.
    normals : (q, 3) float64 array
        ``vn`` lines.
    face_sizes : (p,) int64 array
        Corners of each polygon (``f`` line).
    corner_vertices, corner_texcoords, corner_normals : (c,) int64 arrays
        Each corner's ``v``, ``vt`` and ``vn`` index from 0 (-1 where the corner has none).
    polygon_materials, polygon_groups, polygon_objects, polygon_smoothing : (p,) int64 arrays
        Each polygon's material (into ``MeshAsset.materials``), group (``MeshAsset.groups``), object
        (``objects``) and smoothing group (``smoothing``), -1 for none.
    objects, smoothing : list of str
    mtllibs : list of str
        MTL files named by ``mtllib``, as named.
    mtl_files : dict of str to bytes
        The content of those that could be read.
    statements : list of str
        Lines kept as they are (``l``, ``p``, ...).
    """

    vertex_extra: NDArray[np.float64]
    texcoords: NDArray[np.float64]
    normals: NDArray[np.float64]
    face_sizes: NDArray[np.int64]
    corner_vertices: NDArray[np.int64]
    corner_texcoords: NDArray[np.int64]
    corner_normals: NDArray[np.int64]
    polygon_materials: NDArray[np.int64]
    polygon_groups: NDArray[np.int64]
    polygon_objects: NDArray[np.int64]
    polygon_smoothing: NDArray[np.int64]
    objects: list[str] = field(default_factory=list)
    smoothing: list[str] = field(default_factory=list)
    mtllibs: list[str] = field(default_factory=list)
    mtl_files: dict[str, bytes] = field(default_factory=dict)
    statements: list[str] = field(default_factory=list)


def _parse_numbers(text: str, dtype: type) -> NDArray[Any] | None:
    """All the numbers in ``text`` (separated by blanks), or None when a word is not one."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        try:
            return np.fromstring(text, sep=" ", dtype=dtype)
        except (ValueError, DeprecationWarning):
            return None


def _word_counts(rows: list[str]) -> NDArray[np.int64]:
    """The number of blank-separated words on each row (without splitting them in Python)."""
    if not rows:
        return np.zeros(0, dtype=np.int64)
    a = np.frombuffer(("\n".join(rows) + "\n").encode("utf-8"), dtype=np.uint8)
    newline = a == 10
    blank = newline | (a == 32) | (a == 9) | (a == 13) | (a == 11) | (a == 12)
    start = ~blank
    start[1:] &= blank[:-1]
    line = np.cumsum(newline)
    return np.bincount(line[start], minlength=len(rows)).astype(np.int64)


def _numbers(rows: list[str], width: int, what: str, label: str, lines: list[int],
             counts: NDArray[np.int64] | None = None) -> NDArray[np.float64]:
    """Rows of numbers (text after the keyword) as a float array at least ``width`` wide, NaN-padded."""
    if not rows:
        return np.zeros((0, width))
    counts = _word_counts(rows) if counts is None else counts
    longest = max(width, int(counts.max()))
    if (counts == longest).all():
        values = _parse_numbers(" ".join(rows), float)
        if values is not None and values.size == len(rows) * longest:
            return values.reshape(len(rows), longest)
    out = np.full((len(rows), longest), np.nan)
    for i, r in enumerate(r.split() for r in rows):
        try:
            out[i, :len(r)] = [float(x) for x in r]
        except ValueError:
            raise MeshFormatError(f"cannot parse {label} as OBJ: line {lines[i]}: {what} {' '.join(r)!r} is not a "
                                  "list of numbers") from None
    return out


_WHAT = ("vertex", "texture coordinate", "normal")


def _corner_indices(rows: list[str], n: int, label: str, corner_lines: NDArray[np.int64]) -> NDArray[np.int64]:
    """The (n, 3) v/vt/vn numbers of the ``n`` corners of face rows as written (0 where a corner has none)."""
    joined = " ".join(rows)
    slashes, doubles = joined.count("/"), joined.count("//")
    layouts = {(0, 0): [0], (n, 0): [0, 1], (2 * n, 0): [0, 1, 2], (2 * n, n): [0, 2]}
    columns = layouts.get((slashes, doubles))
    if columns is not None:  # every corner written alike: one parse of all the numbers
        values = _parse_numbers(joined.replace("/", " "), np.int64)
        if values is not None and values.size == n * len(columns):
            out = np.zeros((n, 3), dtype=np.int64)
            out[:, columns] = values.reshape(n, len(columns))
            if not (out[:, columns] == 0).any():
                return out
    out = np.zeros((n, 3), dtype=np.int64)
    for c, word in enumerate(itertools.chain.from_iterable(r.split() for r in rows)):
        for k, part in enumerate(word.split("/")[:3]):
            if not part and k:
                continue
            try:
                out[c, k] = int(part)
            except ValueError:
                raise MeshFormatError(f"cannot parse {label} as OBJ: line {int(corner_lines[c])}: face index "
                                      f"{part!r} is not a whole number") from None
            if out[c, k] == 0 and k == 0:  # a texture coordinate or normal 0 is read as none
                raise MeshFormatError(f"{label}, line {int(corner_lines[c])}: a face names vertex 0, but OBJ vertex "
                                      "indices start at 1 (or count back from -1 for the last vertex)")
    return out


def _resolve(index: NDArray[np.int64], before: NDArray[np.int64], what: str, label: str,
             corner_lines: NDArray[np.int64]) -> NDArray[np.int64]:
    """Indices from 0: ``i`` > 0 is ``i - 1``, ``i`` < 0 counts back from the ``before`` entries above its line; 0
    (none written) is -1. A texture coordinate or normal before the first one is read as none."""
    out = np.where(index > 0, index - 1, np.where(index < 0, before + index, -1))
    bad = (index < 0) & (out < 0)
    if bad.any():
        c = int(np.argmax(bad))
        if what != "vertex":
            out[bad] = -1
        else:
            raise MeshFormatError(f"cannot parse {label} as OBJ: line {int(corner_lines[c])}: a face names {what} "
                                  f"{int(index[c])}, but only {int(before[c]):,} come before it")
    return out


def parse_obj(text: bytes, label: str) -> tuple[NDArray[np.float64], ObjData, list[str], list[str]]:
    """Positions and attributes of OBJ text (UTF-8); see :func:`_parse_obj`.

    Raises
    ------
    MeshFormatError
        Anything malformed, naming the line where it can.
    """
    try:
        return _parse_obj(text, label)
    except MeshError:
        raise
    except (OverflowError, ValueError, IndexError) as exc:
        raise MeshFormatError(f"cannot parse {label} as OBJ: {exc}") from exc


def _parse_obj(text: bytes, label: str) -> tuple[NDArray[np.float64], ObjData, list[str], list[str]]:
    """Positions and attributes of OBJ text (UTF-8).

    Lines are sorted by their keyword in one pass; the numbers of each kind are then parsed together.

    Returns
    -------
    V : (n, 3) float64 array
    data : ObjData
    materials, groups : list of str
        Names in the order faces first use them.
    """
    decoded = text.decode("utf-8", errors="replace")
    if "\\\n" in decoded or "\\\r\n" in decoded:  # continued lines
        decoded = re.sub(r"\\\r?\n", " ", decoded)
    rows: dict[str, list[str]] = {"v": [], "vt": [], "vn": [], "f": []}
    numbers: dict[str, list[int]] = {"v": [], "vt": [], "vn": [], "f": []}
    state: list[str | None] = [None, None, None, None]  # material, group, object, smoothing
    runs: list[tuple[int, tuple[str | None, ...]]] = []
    changed = True
    mtllibs: list[str] = []
    statements: list[str] = []
    v_rows, v_numbers, f_rows, f_numbers = rows["v"], numbers["v"], rows["f"], numbers["f"]
    for number, line in enumerate(decoded.splitlines(), 1):
        c = line[:1]
        if c == " " or c == "\t":
            line = line.lstrip()
            c = line[:1]
        if not c or c == "#":
            continue
        second = line[1:2]
        if c == "v" and (second == " " or second == "\t"):
            v_rows.append(line[2:])
            v_numbers.append(number)
            continue
        if c == "f" and (second == " " or second == "\t"):
            if changed:
                runs.append((len(f_rows), tuple(state)))
                changed = False
            f_rows.append(line[2:])
            f_numbers.append(number)
            continue
        split = line.split(None, 1)
        head, rest = split[0], (split[1].strip() if len(split) > 1 else "")
        if head in ("vt", "vn"):
            rows[head].append(rest)
            numbers[head].append(number)
        elif head == "f":
            raise MeshFormatError(f"{label}, line {number}: a face with fewer than 3 vertices ({line.strip()!r}; the "
                                  "file may be cut short)")
        elif head in ("usemtl", "g", "o", "s"):
            value: str | None = " ".join(rest.split()) if head == "g" else rest
            if head == "s" and rest.lower() in ("off", "0"):
                value = None
            state[("usemtl", "g", "o", "s").index(head)] = value or None
            changed = True
        elif head == "mtllib":
            words = rest.split()
            several = len(words) > 1 and all(w.lower().endswith(".mtl") for w in words)
            mtllibs.extend(words if several else [rest] if rest else [])
        else:
            statements.append(line.strip())
    for key in rows:  # comments after the numbers
        rows[key] = [r.split("#", 1)[0] if "#" in r else r for r in rows[key]]
    f_rows = rows["f"]
    v_counts = _word_counts(rows["v"])
    if len(v_counts) and v_counts.min() < 3:
        i = int(np.argmax(v_counts < 3))
        raise MeshFormatError(f"cannot parse {label} as OBJ: the file ends early or a line is cut (line "
                              f"{v_numbers[i]}: a vertex with {int(v_counts[i])} coordinates; truncated?)")
    V_all = _numbers(rows["v"], 3, "vertex", label, v_numbers, v_counts)
    texcoords = _numbers(rows["vt"], 3, "texture coordinate", label, numbers["vt"])[:, :3]
    normals = _numbers(rows["vn"], 3, "normal", label, numbers["vn"])[:, :3]
    sizes = _word_counts(f_rows)
    if len(sizes) and sizes.min() < 3:
        i = int(np.argmax(sizes < 3))
        raise MeshFormatError(f"{label}, line {f_numbers[i]}: a face with fewer than 3 vertices "
                              f"({('f ' + f_rows[i]).strip()!r}; the file may be cut short)")
    corner_lines = np.repeat(np.asarray(f_numbers, dtype=np.int64), sizes)
    raw = _corner_indices(f_rows, int(sizes.sum()), label, corner_lines)
    resolved = []
    for k, key in enumerate(("v", "vt", "vn")):
        before = np.searchsorted(np.asarray(numbers[key], dtype=np.int64), corner_lines)
        resolved.append(_resolve(raw[:, k], before, _WHAT[k], label, corner_lines))
    # Materials, groups, objects and smoothing groups: named in the order faces first use them.
    tables: list[dict[str, int]] = [{}, {}, {}, {}]
    ids = np.full((len(f_rows), 4), -1, dtype=np.int64)
    bounds = [start for start, _ in runs] + [len(f_rows)]
    for (start, names), end in zip(runs, bounds[1:], strict=True):
        if end > start:
            for k, name in enumerate(names):
                if name is not None:
                    ids[start:end, k] = tables[k].setdefault(name, len(tables[k]))
    data = ObjData(
        vertex_extra=np.ascontiguousarray(V_all[:, 3:]),
        texcoords=texcoords,
        normals=normals,
        face_sizes=sizes,
        corner_vertices=resolved[0],
        corner_texcoords=resolved[1],
        corner_normals=resolved[2],
        polygon_materials=ids[:, 0].copy(),
        polygon_groups=ids[:, 1].copy(),
        polygon_objects=ids[:, 2].copy(),
        polygon_smoothing=ids[:, 3].copy(),
        objects=list(tables[2]),
        smoothing=list(tables[3]),
        mtllibs=mtllibs,
        statements=statements,
    )
    V = np.ascontiguousarray(V_all[:, :3])
    if len(data.corner_vertices) and data.corner_vertices.max() >= len(V):
        raise MeshFormatError(f"cannot parse {label} as OBJ: a face refers to vertex "
                              f"{int(data.corner_vertices.max()) + 1}, but the file has {len(V):,} vertices")
    for corners, count, what in ((data.corner_texcoords, len(data.texcoords), "texture coordinates"),
                                 (data.corner_normals, len(data.normals), "normals")):
        bad = corners >= count
        if bad.any():  # as other readers do: the corner has none
            logger.info("%s: %d face corners refer to %s the file does not have; read without", label,
                        int(bad.sum()), what)
            corners[bad] = -1
    return V, data, list(tables[0]), list(tables[1])


#: MTL texture options and how many values follow each (at most; numbers are taken while they read as numbers).
_MAP_OPTIONS = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-imfchan": 1, "-mm": 2,
                "-o": 3, "-s": 3, "-t": 3, "-texres": 1, "-type": 1}
_WORD = re.compile(r"\S+")


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def map_file_name(arguments: str) -> str:
    """The file name of an MTL texture statement: what follows the statement's options (``-s 1 1 1``, ``-clamp on``,
    ``-bm 0.5``, ...), to the end of the line, spaces included.

    Example
    -------
    >>> map_file_name("-s 2 2 -clamp on fuze uv.jpg")
    'fuze uv.jpg'
    """
    words = list(_WORD.finditer(arguments))
    k = 0
    while k < len(words) and words[k].group().startswith("-") and not _is_number(words[k].group()):
        option = words[k].group().lower()
        k += 1
        values = _MAP_OPTIONS.get(option, 1)
        taken = 0
        while taken < values and k < len(words) - 1:  # the last word is the file name
            word = words[k].group()
            if option in ("-o", "-s", "-t", "-mm") and taken and not _is_number(word):
                break
            k += 1
            taken += 1
    return arguments[words[k].start():].strip() if k < len(words) else ""


def mtl_texture_references(mtl: bytes) -> list[str]:
    """The texture files an MTL file names (``map_Kd``, ``bump``, ...), in order, each once."""
    out: list[str] = []
    for raw in mtl.decode("utf-8", errors="replace").splitlines():
        line = raw.strip()
        if not line or line[0] == "#":
            continue
        words = line.split(None, 1)
        if words[0].lower() in _MAP_KEYS and len(words) > 1:
            ref = map_file_name(words[1])
            if ref and ref not in out:
                out.append(ref)
    return out


def may_have_attributes(data: bytes) -> bool:
    """Cheap test of an OBJ file's bytes for what :func:`read_obj_asset` keeps beyond the geometry: vertex colours
    (``v x y z r g b``), or texture coordinates and an ``mtllib`` statement (its files brought along or not)."""
    texcoords = b"\nvt " in data or b"\nvt\t" in data or data.startswith((b"vt ", b"vt\t"))
    mtllib = texcoords and b"mtllib" in data and _MTLLIB_LINE.search(data) is not None
    return mtllib or _COLOUR_LINE.search(data) is not None


def read_obj_asset(data: bytes, label: str, folder: Path | None, max_vertices: int | None) -> MeshAsset:
    """A :class:`MeshAsset` from the bytes of an OBJ file; MTL files and textures are read from ``folder``."""
    text = screen(data, "obj", label, obj_zero_index=False)
    V, obj, materials, groups = parse_obj(text, label)
    if max_vertices is not None and len(V) > max_vertices:
        raise MeshTooLargeError(f"{label} has {len(V):,} vertices; at most {max_vertices:,} vertices are accepted",
                                len(V), max_vertices)
    if not len(obj.face_sizes):
        raise MeshFormatError(f"{label} has {len(V):,} vertices but no faces; a surface is needed")
    textures: dict[str, bytes] = {}
    for lib in obj.mtllibs:
        mtl = read_referenced(folder, lib, label, f"the material file {lib!r}", "the mesh loads without it")
        if mtl is None:
            continue
        obj.mtl_files[lib] = mtl
        beside = posixpath.dirname(lib.replace("\\", "/"))
        for ref in mtl_texture_references(mtl):  # relative to the MTL file, which may be in a folder of its own
            image = read_referenced(folder, posixpath.join(beside, ref.replace("\\", "/")), label,
                                    f"the texture {ref!r} named in {lib!r}", "its reference is kept")
            if image is not None:
                textures[ref] = image
    F = fan(obj.face_sizes, obj.corner_vertices)
    polygon = fan(obj.face_sizes, np.repeat(np.arange(len(obj.face_sizes)), obj.face_sizes))[:, 0]
    uvs = None
    if len(obj.texcoords) and (obj.corner_texcoords >= 0).any():
        table = np.vstack([obj.texcoords[:, :2], np.full((1, 2), np.nan)])  # -1 picks the NaN row
        uvs = fan(obj.face_sizes, table[obj.corner_texcoords])
    colors = obj.vertex_extra if obj.vertex_extra.shape[1] in (3, 4) and not np.isnan(obj.vertex_extra).any() \
        else None
    return MeshAsset(format="obj", vertices=V, faces=F, materials=materials, face_materials=obj.polygon_materials[
        polygon], groups=groups, face_groups=obj.polygon_groups[polygon], uvs=uvs, vertex_colors=colors,
        textures=textures, data=obj)
