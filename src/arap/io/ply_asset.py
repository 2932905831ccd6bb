"""PLY files with every element and property kept: vertex colours, texture coordinates (per vertex ``s t``/``u v``,
or per face ``texcoord`` lists), normals and whatever else the file holds (see :mod:`arap.io.assets`).

Reading uses trimesh's PLY parser for the raw elements (ASCII and binary of either byte order); writing is binary
little-endian with every property in its own type, except new positions, which are written as doubles (exact).
A ``comment TextureFile NAME`` names the texture image, read from and written beside the file.
"""

from __future__ import annotations

import logging
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arap.errors import MeshError, MeshFormatError, MeshTooLargeError
from arap.io.assets import MeshAsset, fan, group_normals, read_referenced, vertex_normal_groups, write_beside
from arap.io.screening import screen

__all__ = ["PlyData", "PlyElement", "may_have_attributes", "read_ply_asset", "write_ply_asset"]

logger = logging.getLogger(__name__)

_UV_NAMES = (("s", "t"), ("u", "v"), ("texture_u", "texture_v"), ("texture_s", "texture_t"))
_COLOR_NAMES = (("red", "green", "blue", "alpha"), ("r", "g", "b", "a"),
                ("diffuse_red", "diffuse_green", "diffuse_blue", "diffuse_alpha"))
_HEADER_HINTS = (b"red", b"texture", b" s\n", b" u\n", b" s\r\n", b" u\r\n")


@dataclass(eq=False)
class PlyElement:
    """One element of a PLY file: its name, count and properties in order.

    ``properties`` maps each name to ``(dtype, count_dtype)``, ``count_dtype`` None for a scalar property;
    ``data`` maps it to an (n,) array, an (n, k) array for lists of one length, or an (n,) object array of arrays.
    """

    name: str
    count: int
    properties: dict[str, tuple[np.dtype[Any], np.dtype[Any] | None]]
    data: dict[str, NDArray[Any]]


@dataclass(eq=False)
class PlyData:
    """The elements and header comments of a PLY file."""

    elements: list[PlyElement]
    comments: list[str] = field(default_factory=list)
    texture_files: list[str] = field(default_factory=list)

    def element(self, name: str) -> PlyElement | None:
        return next((e for e in self.elements if e.name == name), None)


_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2", "ushort": "u2",
          "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4", "float": "f4", "float32": "f4",
          "double": "f8", "float64": "f8"}


def _header(data: bytes, label: str) -> tuple[str, list[tuple[str, int, list[tuple[str, str, str | None]]]],
                                               list[str], int]:
    """Format, elements (name, count, properties (name, item type, count type or None)), comments and the offset of
    the body."""
    end = data.find(b"end_header")
    body = data.find(b"\n", end) + 1
    lines = data[:end].decode("utf-8", errors="replace").splitlines()
    fmt = ""
    elements: list[tuple[str, int, list[tuple[str, str, str | None]]]] = []
    comments: list[str] = []
    for number, raw in enumerate(lines[1:], 2):
        words = raw.split()
        if not words:
            continue
        try:
            if words[0] == "format":
                fmt = words[1]
            elif words[0] in ("comment", "obj_info"):
                comments.append(raw.strip())
            elif words[0] == "element":
                elements.append((words[1], int(words[2]), []))
            elif words[0] == "property" and words[1] == "list":
                elements[-1][2].append((words[4], _TYPES[words[3]], _TYPES[words[2]]))
            elif words[0] == "property":
                elements[-1][2].append((words[2], _TYPES[words[1]], None))
        except (IndexError, KeyError, ValueError) as exc:
            raise MeshFormatError(f"cannot parse {label} as PLY: header line {number} ({raw.strip()!r}) is not "
                                  "understood") from exc
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise MeshFormatError(f"cannot parse {label} as PLY: unknown format {fmt!r}")
    return fmt, elements, comments, body


def _binary_element(buf: bytes, at: int, count: int, props: list[tuple[str, str, str | None]], order: str,
                    label: str, name: str) -> tuple[dict[str, NDArray[Any]], int]:
    """The columns of one binary element starting at byte ``at``, and the byte after it."""
    def short() -> MeshFormatError:
        return MeshFormatError(f"cannot parse {label} as PLY: the file ends early in element {name!r} (truncated?)")

    # Lists of one length (read from the first row) make fixed-size records: one read for the whole element.
    fields: list[tuple[str, str] | tuple[str, str, tuple[int]]] = []
    cursor = at
    for prop, item, counter in props:
        if counter is None:
            fields.append((prop, order + item))
            cursor += np.dtype(item).itemsize
            continue
        if cursor + np.dtype(counter).itemsize > len(buf):
            raise short()
        n = int(np.frombuffer(buf, dtype=order + counter, count=1, offset=cursor)[0]) if count else 0
        fields.append((f"{prop} count", order + counter))
        fields.append((prop, order + item, (n,)))
        cursor += np.dtype(counter).itemsize + n * np.dtype(item).itemsize
    record = np.dtype(fields)
    lists = [(prop, counter) for prop, _, counter in props if counter is not None]
    if at + record.itemsize * count <= len(buf):
        rows = np.frombuffer(buf, dtype=record, count=count, offset=at)
        if all((rows[f"{prop} count"] == rows.dtype[f"{prop}"].shape[0]).all() for prop, _ in lists):
            return {prop: np.ascontiguousarray(rows[prop]) for prop, _, _ in props}, at + record.itemsize * count
    if not lists:
        raise short()
    # Lists of several lengths: row by row.
    columns: dict[str, list[Any]] = {prop: [] for prop, _, _ in props}
    for _ in range(count):
        for prop, item, counter in props:
            kind = np.dtype(order + (counter or item))
            if at + kind.itemsize > len(buf):
                raise short()
            value = np.frombuffer(buf, dtype=kind, count=1, offset=at)[0]
            at += kind.itemsize
            if counter is None:
                columns[prop].append(value)
                continue
            items = np.dtype(order + item)
            if at + int(value) * items.itemsize > len(buf):
                raise short()
            native = items.newbyteorder("=")
            columns[prop].append(np.frombuffer(buf, dtype=items, count=int(value), offset=at).astype(native))
            at += int(value) * items.itemsize
    out: dict[str, NDArray[Any]] = {}
    for prop, item, counter in props:
        if counter is None:
            out[prop] = np.asarray(columns[prop], dtype=item)
        else:
            column = np.empty(count, dtype=object)
            column[:] = columns[prop]
            out[prop] = column
    return out, at


_Elements = list[tuple[str, int, list[tuple[str, str, str | None]]]]


def _ascii_elements(body: bytes, elements: _Elements, label: str) -> list[dict[str, NDArray[Any]]]:
    """The columns of every element of an ASCII PLY body: one element per line, as the format has it (words after
    the properties of a line are ignored: MeshLab writes more than its header says on face lines); a file that
    breaks its lines elsewhere is read as one stream of words."""
    try:
        return _ascii_lines(body, elements, label)
    except MeshFormatError:
        return _ascii_words(body, elements, label)


def _ascii_columns(columns: dict[str, list[Any]], props: list[tuple[str, str, str | None]],
                   count: int) -> dict[str, NDArray[Any]]:
    """Arrays of the values read row by row: a list property of one length as an (n, k) array, of several as an
    object array of arrays."""
    element: dict[str, NDArray[Any]] = {}
    for prop, item, counter in props:
        if counter is None:
            element[prop] = np.asarray(columns[prop]).astype(item)
            continue
        lengths = {len(x) for x in columns[prop]}
        if len(lengths) == 1:
            element[prop] = np.stack(columns[prop]).astype(item) if count else np.zeros((0, 0), dtype=item)
        else:
            column = np.empty(count, dtype=object)
            column[:] = columns[prop]
            element[prop] = column
    return element


def _ascii_lines(body: bytes, elements: _Elements, label: str) -> list[dict[str, NDArray[Any]]]:
    lines = [line for line in body.splitlines() if line.strip()]
    at = 0
    out = []
    for name, count, props in elements:
        rows = lines[at:at + count]
        at += count
        if len(rows) < count:
            raise MeshFormatError(f"cannot parse {label} as PLY: the file ends early in element {name!r} "
                                  "(truncated?)")
        width = len(props)
        try:
            if all(c is None for _, _, c in props):
                words = b" ".join(rows).split()
                if len(words) != width * count:
                    words = [w for row in rows for w in row.split()[:width] + [b"x"] * (width - len(row.split()))]
                table = np.array(words, dtype=np.float64).reshape(count, width)
                out.append({prop: table[:, k].astype(item) for k, (prop, item, _) in enumerate(props)})
                continue
            columns: dict[str, list[Any]] = {prop: [] for prop, _, _ in props}
            for row in rows:
                words = row.split()
                k = 0
                for prop, item, counter in props:
                    if counter is None:
                        columns[prop].append(float(words[k]))
                        k += 1
                    else:
                        n = int(words[k])
                        if k + 1 + n > len(words):
                            raise IndexError
                        columns[prop].append(np.array(words[k + 1:k + 1 + n], dtype=np.float64).astype(item))
                        k += n + 1
        except (IndexError, ValueError) as exc:
            raise MeshFormatError(f"cannot parse {label} as PLY: element {name!r} ends early or holds a word that "
                                  "is not a number") from exc
        out.append(_ascii_columns(columns, props, count))
    return out


def _ascii_words(body: bytes, elements: _Elements, label: str) -> list[dict[str, NDArray[Any]]]:
    words = body.split()
    at = 0
    out = []
    for name, count, props in elements:
        width = len(props)
        if all(c is None for _, _, c in props):
            block = words[at:at + width * count]
            if len(block) < width * count:
                raise MeshFormatError(f"cannot parse {label} as PLY: the file ends early in element {name!r} "
                                      "(truncated?)")
            try:
                table = np.array(block, dtype=np.float64).reshape(count, width)
            except ValueError as exc:
                raise MeshFormatError(f"cannot parse {label} as PLY: element {name!r} holds a word that is not a "
                                      "number") from exc
            out.append({prop: table[:, k].astype(item) for k, (prop, item, _) in enumerate(props)})
            at += width * count
            continue
        columns: dict[str, list[Any]] = {prop: [] for prop, _, _ in props}
        try:
            for _ in range(count):
                for prop, item, counter in props:
                    if counter is None:
                        columns[prop].append(float(words[at]))
                        at += 1
                    else:
                        n = int(words[at])
                        columns[prop].append(np.array(words[at + 1:at + 1 + n], dtype=np.float64).astype(item))
                        if len(columns[prop][-1]) < n:
                            raise IndexError
                        at += n + 1
        except (IndexError, ValueError) as exc:
            raise MeshFormatError(f"cannot parse {label} as PLY: element {name!r} ends early or holds a word that "
                                  "is not a number") from exc
        out.append(_ascii_columns(columns, props, count))
    return out


def parse_ply(data: bytes, label: str) -> PlyData:
    """Every element and property of a PLY file (ASCII or binary), in the file's order and types."""
    fmt, header, comments, body = _header(data, label)
    if fmt == "ascii":
        columns = _ascii_elements(data[body:], header, label)
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        columns = []
        at = body
        for name, count, props in header:
            element, at = _binary_element(data, at, count, props, order, label, name)
            columns.append({k: (v.astype(v.dtype.newbyteorder("=")) if v.dtype != object else v)
                            for k, v in element.items()})
    elements = [PlyElement(name=name, count=count,
                           properties={p: (np.dtype(item), None if c is None else np.dtype(c)) for p, item, c in props},
                           data=column)
                for (name, count, props), column in zip(header, columns, strict=True)]
    return PlyData(elements=elements, comments=comments)


def may_have_attributes(data: bytes) -> bool:
    """Cheap test of a PLY file's header for what :func:`read_ply_asset` keeps beyond the geometry: colours,
    texture coordinates or a texture file."""
    end = data.find(b"end_header")
    return any(h in data[: end if end > 0 else 4096] for h in _HEADER_HINTS)


def read_ply_asset(data: bytes, label: str, folder: Path | None, max_vertices: int | None, *,
                   textures: bool = True) -> MeshAsset:
    """A :class:`MeshAsset` from the bytes of a PLY file (its texture read from ``folder``; with ``textures``
    False, not read at all, without a warning).

    Raises
    ------
    MeshFormatError
        Anything malformed.
    """
    try:
        return _read_ply_asset(data, label, folder, max_vertices, textures)
    except MeshError:
        raise
    except (KeyError, TypeError, IndexError, ValueError, OverflowError) as exc:
        raise MeshFormatError(f"cannot parse {label} as PLY: {type(exc).__name__}: {exc}") from exc


def _read_ply_asset(data: bytes, label: str, folder: Path | None, max_vertices: int | None,
                    read_textures: bool = True) -> MeshAsset:
    data = screen(data, "ply", label)
    end = data.find(b"end_header")
    counts = dict(re.findall(rb"^\s*element\s+(\S+)\s+(\d+)", data[:end], re.M))
    if max_vertices is not None and int(counts.get(b"vertex", 0)) > max_vertices:
        n = int(counts[b"vertex"])
        raise MeshTooLargeError(f"{label} has {n:,} vertices; at most {max_vertices:,} vertices are accepted",
                                n, max_vertices)
    ply = parse_ply(data, label)
    comments = ply.comments
    if ply.element("vertex") is None:
        raise MeshFormatError(f"{label} contains no vertices (empty, or not a PLY file)")
    ply.texture_files = [c.split(None, 2)[2] for c in comments
                         if len(c.split(None, 2)) == 3 and c.split(None, 2)[1].lower() == "texturefile"]
    vertex = ply.element("vertex")
    assert vertex is not None
    if not all(k in vertex.data for k in "xyz"):
        raise MeshFormatError(f"{label}: the vertex element has no x, y, z properties")
    V = np.stack([vertex.data[k].astype(np.float64) for k in "xyz"], axis=1)
    face = ply.element("face")
    key = None if face is None else next((k for k in ("vertex_indices", "vertex_index") if k in face.data), None)
    if face is None or key is None or face.count == 0:
        raise MeshFormatError(f"{label} has {len(V):,} vertices but no faces; a surface is needed")
    sizes, corners = _lists(face.data[key])
    if (sizes < 3).any():
        raise MeshFormatError(f"{label}: face {int(np.argmax(sizes < 3))} has fewer than 3 vertices")
    corners = corners.astype(np.int64)
    if len(corners) and (corners.min() < 0 or corners.max() >= len(V)):
        raise MeshFormatError(f"cannot parse {label} as PLY: a face refers to vertex {int(corners.max())}, but the "
                              f"file has {len(V):,} vertices")
    F = fan(sizes, corners)
    uvs = None
    for u, v in _UV_NAMES:
        if u in vertex.data and v in vertex.data:
            uv = np.stack([vertex.data[u], vertex.data[v]], axis=1).astype(np.float64)
            uvs = uv[F]
            break
    if uvs is None and "texcoord" in face.data:
        tsizes, tc = _lists(face.data["texcoord"])
        if np.array_equal(tsizes, 2 * sizes):
            uvs = fan(sizes, tc.astype(np.float64).reshape(-1, 2))
    colors = None
    for names in _COLOR_NAMES:
        if all(n in vertex.data for n in names[:3]):
            present = [n for n in names if n in vertex.data]
            colors = np.stack([vertex.data[n] for n in present], axis=1)
            break
    textures: dict[str, bytes] = {}
    for ref in ply.texture_files if read_textures else []:
        blob = read_referenced(folder, ref, label, f"the texture {ref!r}", "its reference is kept")
        if blob is not None:
            textures[ref] = blob
    return MeshAsset(format="ply", vertices=V, faces=F, face_materials=np.full(len(F), -1, dtype=np.int64),
                     face_groups=np.full(len(F), -1, dtype=np.int64), uvs=uvs, vertex_colors=colors,
                     textures=textures, data=ply)


def _lists(values: NDArray[Any]) -> tuple[NDArray[np.int64], NDArray[Any]]:
    """Lengths and concatenated items of a list property."""
    if values.dtype != object:
        A = values.reshape(len(values), -1)
        return np.full(len(A), A.shape[1], dtype=np.int64), A.reshape(-1)
    sizes = np.array([len(x) for x in values], dtype=np.int64)
    items = np.concatenate([np.asarray(x).ravel() for x in values]) if len(values) else np.zeros(0)
    return sizes, items


def _type_name(dtype: np.dtype[Any]) -> str:
    names = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int", "u4": "uint", "f4": "float",
             "f8": "double"}
    return names[dtype.str[1:]]


def _element_bytes(element: PlyElement, data: dict[str, NDArray[Any]],
                   types: dict[str, tuple[np.dtype[Any], np.dtype[Any] | None]]) -> bytes:
    blocks: list[NDArray[np.uint8] | list[bytes]] = []
    ragged = False
    n = element.count
    for prop, (dtype, count_dtype) in types.items():
        little = dtype.newbyteorder("<")
        values = data[prop]
        if count_dtype is None:
            blocks.append(np.ascontiguousarray(values.reshape(n).astype(little)).view(np.uint8).reshape(n, -1))
            continue
        counter = count_dtype.newbyteorder("<")
        if values.dtype != object:
            A = values.reshape(n, -1)
            head = np.full(n, A.shape[1]).astype(counter).view(np.uint8).reshape(n, -1)
            body = np.ascontiguousarray(A.astype(little)).view(np.uint8).reshape(n, -1)
            blocks.append(np.hstack([head, body]))
        else:
            ragged = True
            blocks.append([np.array([len(x)], dtype=counter).tobytes() + np.asarray(x).astype(little).tobytes()
                           for x in values])
    if not ragged:
        return np.hstack(blocks).tobytes() if blocks else b""
    rows: list[list[bytes]] = [[] for _ in range(n)]
    for block in blocks:
        if isinstance(block, list):
            for row, b in zip(rows, block, strict=True):
                row.append(b)
        else:
            for row, b in zip(rows, block, strict=True):
                row.append(b.tobytes())
    return b"".join(b"".join(r) for r in rows)


def ply_bytes(asset: MeshAsset, V: NDArray[np.float64] | None) -> bytes:
    """Binary little-endian PLY of an asset with positions ``V`` (None: its own) and normals recomputed."""
    ply: PlyData = asset.data
    header = ["ply", "format binary_little_endian 1.0", *ply.comments]
    body: list[bytes] = []
    for element in ply.elements:
        data = dict(element.data)
        types = dict(element.properties)
        if element.name == "vertex" and V is not None:
            for k, axis in enumerate("xyz"):
                data[axis] = V[:, k]
                types[axis] = (np.dtype("<f8"), None)
            if all(k in data for k in ("nx", "ny", "nz")):
                old = np.stack([data[k] for k in ("nx", "ny", "nz")], axis=1)
                group = vertex_normal_groups(asset.solve_mesh().to_solve, old.astype(np.float32))
                new, valid = group_normals(V, asset.faces, group[asset.faces], len(group))
                rows = np.maximum(group, 0)
                normals = np.where(((group >= 0) & valid[rows])[:, None], new[rows], old)
                for k, axis in enumerate(("nx", "ny", "nz")):
                    data[axis] = normals[:, k].astype(element.properties[axis][0])
        header.append(f"element {element.name} {element.count}")
        for prop, (dtype, count_dtype) in types.items():
            if count_dtype is None:
                header.append(f"property {_type_name(dtype)} {prop}")
            else:
                header.append(f"property list {_type_name(count_dtype)} {_type_name(dtype)} {prop}")
        body.append(_element_bytes(element, data, types))
    header.append("end_header")
    return ("\n".join(header) + "\n").encode("utf-8") + b"".join(body)


def write_ply_asset(path: Path, asset: MeshAsset, V: NDArray[np.float64] | None) -> list[Path]:
    """Write a PLY asset and, beside it, its texture."""
    from arap.io.atomic import write_atomic

    write_atomic(path, ply_bytes(asset, V))
    written = [path]
    for ref, image in asset.textures.items():
        write_beside(path.parent, ref, image, written)
    return written
