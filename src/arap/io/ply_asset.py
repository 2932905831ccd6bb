"""PLY files with every element and property kept: vertex colours, texture coordinates (per vertex ``s t``/``u v``,
or per face ``texcoord`` lists), normals and whatever else the file holds (see :mod:`arap.io.assets`).

Reading uses trimesh's PLY parser for the raw elements (ASCII and binary of either byte order); writing is binary
little-endian with every property in its own type, except new positions, which are written as doubles (exact).
A ``comment TextureFile NAME`` names the texture image, read from and written beside the file.
"""

from __future__ import annotations

import io
import logging
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arap.errors import MeshFormatError, MeshTooLargeError
from arap.io.assets import MeshAsset, fan, group_normals, missing_file_warning, vertex_normal_groups, write_beside
from arap.io.screening import screen

__all__ = ["PlyData", "PlyElement", "read_ply_asset", "write_ply_asset"]

logger = logging.getLogger(__name__)

_UV_NAMES = (("s", "t"), ("u", "v"), ("texture_u", "texture_v"), ("texture_s", "texture_t"))
_COLOR_NAMES = (("red", "green", "blue", "alpha"), ("r", "g", "b", "a"),
                ("diffuse_red", "diffuse_green", "diffuse_blue", "diffuse_alpha"))
_LIST = re.compile(r"^\s*(\S+),\s*\((?:\$LIST|\d+),\)\s*(\S+)\s*$")


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


def _column(values: Any, count: int) -> NDArray[Any]:
    A = np.asarray(values)
    if A.dtype.names:  # a binary list of one length: (count, items) records
        A = A[A.dtype.names[-1]]
    if A.dtype == object:
        return A
    if A.ndim == 2 and A.shape[1] == 1:
        return A[:, 0]
    return A.reshape(count, -1) if A.ndim > 1 else A


def read_ply_asset(data: bytes, label: str, folder: Path | None, max_vertices: int | None) -> MeshAsset:
    """A :class:`MeshAsset` from the bytes of a PLY file (its texture read from ``folder``)."""
    from trimesh.exchange.ply import load_ply

    data = screen(data, "ply", label)
    end = data.find(b"end_header")
    header_lines = data[:end].decode("utf-8", errors="replace").splitlines()
    comments = [line.strip() for line in header_lines if line.strip().split(" ", 1)[0] in ("comment", "obj_info")]
    counts = dict(re.findall(r"^\s*element\s+(\S+)\s+(\d+)", "\n".join(header_lines), re.M))
    if max_vertices is not None and int(counts.get("vertex", 0)) > max_vertices:
        n = int(counts["vertex"])
        raise MeshTooLargeError(f"{label} has {n:,} vertices; at most {max_vertices:,} vertices are accepted",
                                n, max_vertices)
    # The texture is read here, not by the parser (which has no folder to read it from).
    parsed = re.sub(rb"(?m)^([ \t]*comment[ \t]+)TextureFile", rb"\1Texture-file", data[:end]) + data[end:]
    try:
        loaded = load_ply(io.BytesIO(parsed), fix_texture=False, prefer_color=None)
    except Exception as exc:  # the parser raises anything from ValueError to struct.error
        raise MeshFormatError(f"cannot parse {label} as PLY: {exc or type(exc).__name__}") from exc
    raw = loaded.get("metadata", {}).get("_ply_raw")
    if not raw or "vertex" not in raw:
        raise MeshFormatError(f"{label} contains no vertices (empty, or not a PLY file)")
    elements: list[PlyElement] = []
    for name, element in raw.items():
        count = int(element["length"])
        props: dict[str, tuple[np.dtype[Any], np.dtype[Any] | None]] = {}
        for prop, kind in element["properties"].items():
            match = _LIST.match(str(kind))
            props[prop] = (np.dtype(match.group(2)), np.dtype(match.group(1))) if match else (np.dtype(kind), None)
        columns = {prop: _column(element["data"][prop], count) for prop in props}
        elements.append(PlyElement(name=name, count=count, properties=props, data=columns))
    ply = PlyData(elements=elements, comments=comments)
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
    for ref in ply.texture_files:
        blob = None
        if folder is not None:
            from arap.io.paths import read_regular_file

            try:
                blob = read_regular_file(folder / ref)
            except OSError:
                blob = None
        if blob is None:
            missing_file_warning(f"{label}: the texture {ref!r} cannot be read; its reference is kept")
        else:
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
