"""The glTF 2.0 container: the GLB chunks, the JSON document, buffers and data URIs, accessors as arrays, the
scene's node transforms and primitive modes; and a GLB written back from a document and its binary buffer.

:mod:`arap.io.gltf_asset` reads and writes whole assets with it.
"""

from __future__ import annotations

import base64
import errno
import json
import logging
import re
import struct
import urllib.parse
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arap.errors import MeshFormatError

__all__ = ["MAX_JSON_DEPTH", "MAX_NODE_DEPTH", "GltfData", "Instance", "accessor_array", "accessor_count",
           "check_compression", "data_uri", "format_error", "glb_bytes", "item", "mesh_instances", "mesh_transforms",
           "node_matrix", "pad4", "parse_json", "percent_decoded", "read_uri", "split_glb", "triangles"]

logger = logging.getLogger(__name__)

GLB_MAGIC = b"glTF"
JSON_CHUNK, BIN_CHUNK = 0x4E4F534A, 0x004E4942
FLOAT, UINT = 5126, 5125
COMPONENTS: dict[int, str] = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
COMPRESSION = ("KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_meshopt_compression")
MODES = {0: "points", 1: "lines", 2: "line loops", 3: "line strips", 4: "triangles", 5: "triangle strips",
          6: "triangle fans"}
MAX_JSON_DEPTH = 64
"""Deepest nesting of arrays and objects accepted in a glTF document (a glTF document needs about 8 levels, with
room for deep ``extras``); deeper is refused with a clear error, never a ``RecursionError``."""
MAX_NODE_DEPTH = 1024
"""Deepest node hierarchy accepted (a skeleton needs a few dozen levels)."""
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]+:")
_HEX = np.full(256, -1, dtype=np.int16)
for _digits, _first in ((b"0123456789", 0), (b"abcdef", 10), (b"ABCDEF", 10)):
    _HEX[np.frombuffer(_digits, dtype=np.uint8)] = np.arange(_first, _first + len(_digits))


@dataclass(eq=False)
class Instance:
    """One more copy of a POSITION accessor, for a further node showing its mesh (see :class:`GltfData`).

    Attributes
    ----------
    node, mesh : int
        The node and the mesh it shows.
    position : int
        The POSITION accessor copied.
    normal : int or None
        The NORMAL accessor beside it (None: none).
    offset : int
        The first vertex of the copy in the asset's numbering.
    transform : (4, 4) float64 array
        The node's scene transform applied to the copy.
    """

    node: int
    mesh: int
    position: int
    normal: int | None
    offset: int
    transform: NDArray[np.float64]


@dataclass(eq=False)
class GltfData:
    """The glTF document and buffers, and where the asset's vertices come from.

    Attributes
    ----------
    document : dict
        The JSON document as read.
    buffers : list of bytes
        Every buffer's content (a GLB's binary chunk is buffer 0).
    binary : bool
        Read from a GLB.
    positions : list of int
        The POSITION accessors of the triangle primitives, in vertex order (each once).
    offsets : list of int
        The first vertex of each.
    transforms : list of (4, 4) float64 arrays
        The scene transform applied to each (the first node showing its mesh).
    normals : list of (position accessor, normal accessor) pairs
        The NORMAL accessors of triangle primitives, with the POSITION accessor beside them.
    images : dict of int to bytes
        The content of images stored in files beside the document, by image index.
    instances : list of Instance
        The copies of the POSITION accessors of meshes shown by more than one node, one per further node and
        accessor (the first node's are ``positions``), after every first copy in the vertex numbering.
    """

    document: dict[str, Any]
    buffers: list[bytes]
    binary: bool
    positions: list[int] = field(default_factory=list)
    offsets: list[int] = field(default_factory=list)
    transforms: list[NDArray[np.float64]] = field(default_factory=list)
    normals: list[tuple[int, int]] = field(default_factory=list)
    images: dict[int, bytes] = field(default_factory=dict)
    instances: list[Instance] = field(default_factory=list)


def format_error(label: str, message: str) -> MeshFormatError:
    return MeshFormatError(f"cannot read {label} as glTF: {message}")


def split_glb(data: bytes, label: str) -> tuple[dict[str, Any], bytes | None]:
    if len(data) < 20:
        raise format_error(label, f"the file is {len(data)} bytes long, too short for a GLB header")
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    if magic != GLB_MAGIC:
        raise format_error(label, "it does not start with 'glTF'")
    if version != 2:
        raise format_error(label, f"GLB version {version} (only glTF 2.0 is supported)")
    if length > len(data):
        raise format_error(label, f"its header announces {length:,} bytes but the file has {len(data):,} (truncated?)")
    text: bytes | None = None
    binary: bytes | None = None
    at = 12
    while at + 8 <= length and binary is None:  # the JSON chunk, then the first binary chunk; others are skipped
        size, kind = struct.unpack_from("<II", data, at)
        if at + 8 + size > length:
            raise format_error(label, f"a chunk of {size:,} bytes runs past the end of the file (truncated?)")
        if text is None:
            if kind != JSON_CHUNK:
                break
            text = data[at + 8:at + 8 + size]
        elif kind == BIN_CHUNK:
            binary = data[at + 8:at + 8 + size]
        at += 8 + size
    if text is None:
        raise format_error(label, "the first chunk is not the JSON document")
    return parse_json(text, label), binary


def _json_depth(document: Any, limit: int) -> int:
    """The nesting depth of parsed JSON (an object or array is one level), counted level by level without recursion
    up to ``limit + 1``."""
    level: list[Any] = [document]
    depth = 0
    while level and depth <= limit:
        depth += 1
        level = [child for value in level for child in (value.values() if isinstance(value, dict) else value)
                 if isinstance(child, dict | list)]
    return depth


def parse_json(text: bytes, label: str) -> dict[str, Any]:
    """The JSON document of a glTF file, an object nested at most :data:`MAX_JSON_DEPTH` levels deep."""
    try:
        document = json.loads(text.decode("utf-8").rstrip(" \0"))
    except RecursionError as exc:
        raise format_error(label, f"the JSON document is nested too deeply (more than {MAX_JSON_DEPTH} levels of "
                           "arrays and objects)") from exc
    except (UnicodeDecodeError, ValueError) as exc:
        raise format_error(label, f"the JSON document is malformed ({exc})") from exc
    if not isinstance(document, dict):
        raise format_error(label, "the JSON document is not an object")
    if _json_depth(document, MAX_JSON_DEPTH) > MAX_JSON_DEPTH:
        raise format_error(label, f"the JSON document is nested too deeply (more than {MAX_JSON_DEPTH} levels of "
                           "arrays and objects)")
    version = str(document.get("asset", {}).get("version", "2.0")) if isinstance(document.get("asset"), dict) \
        else "2.0"
    if not version.startswith("2"):
        raise format_error(label, f"glTF version {version} (only 2.0 is supported)")
    return document


def percent_decoded(text: str) -> bytes:
    """The bytes of percent-encoded text (UTF-8, ``%XX`` escapes decoded, a ``%`` not followed by two hexadecimal
    digits kept), as :func:`urllib.parse.unquote_to_bytes` gives them, in time and memory linear in the length.

    Example
    -------
    >>> percent_decoded("a%20b%zz%4")
    b'a b%zz%4'
    """
    raw = text.encode("utf-8")
    if b"%" not in raw:
        return raw
    parts: list[bytes] = []
    start = 0
    while start < len(raw):  # in pieces, to bound the memory of the index arrays
        end = min(start + _PIECE, len(raw))
        while end < len(raw) and b"%" in raw[end - 2:end]:  # no escape straddles two pieces
            end += 1
        parts.append(_percent_piece(raw[start:end]))
        start = end
    return b"".join(parts)


_PIECE = 1 << 22


def _percent_piece(raw: bytes) -> bytes:
    a = np.frombuffer(raw, dtype=np.uint8)
    at = np.flatnonzero(a[:-2] == ord("%")).astype(np.int32)
    if not len(at):
        return raw
    high, low = _HEX[a[at + 1]], _HEX[a[at + 2]]
    valid = (high >= 0) & (low >= 0)  # the two digits of an escape are never a '%': escapes do not overlap
    at = at[valid]
    out = a.copy()
    out[at] = (high[valid] * 16 + low[valid]).astype(np.uint8)
    keep = np.ones(len(a), dtype=bool)
    keep[at + 1] = False
    keep[at + 2] = False
    return out[keep].tobytes()


def data_uri(uri: str, max_bytes: int | None = None) -> bytes | None:
    """The content of a ``data:`` URI (base64 or percent-encoded), None for another URI.

    Raises
    ------
    ValueError
        Malformed base64, or content longer than ``max_bytes``.
    """
    if not uri.startswith("data:"):
        return None
    head, _, payload = uri.partition(",")
    base64_encoded = head.endswith(";base64")
    if max_bytes is not None and (len(payload) // 4 * 3 if base64_encoded else len(payload) // 3) > max_bytes:
        raise ValueError(f"it holds more than the {max_bytes:,} bytes accepted")
    data = base64.b64decode(payload) if base64_encoded else percent_decoded(payload)
    if max_bytes is not None and len(data) > max_bytes:
        raise ValueError(f"it holds {len(data):,} bytes, more than the {max_bytes:,} accepted")
    return data


def read_uri(uri: str, folder: Path | None) -> bytes:
    """The content of a buffer's or image's URI: a ``data:`` URI decoded, or a file inside ``folder`` named by a
    relative URI (:func:`arap.io.paths.read_reference`: nothing outside the folder is read); other URIs (``file:``,
    ``http:``) are not read.

    Raises
    ------
    ValueError
        A malformed or too long data URI.
    OSError
        The file cannot or may not be read; ``strerror`` says why where the reference itself is refused.
    """
    from arap.io.paths import MAX_REFERENCED_BYTES, SpecialFileError, read_reference

    data = data_uri(uri, MAX_REFERENCED_BYTES)
    if data is not None:
        return data
    if _SCHEME.match(uri):
        raise SpecialFileError(errno.EPERM, "only data: URIs and files beside the mesh file are read", uri)
    if folder is None:
        raise FileNotFoundError(errno.ENOENT, "there is no folder to read it from", uri)
    return read_reference(folder, urllib.parse.unquote(uri))


def item(document: dict[str, Any], key: str, index: Any, label: str, what: str) -> dict[str, Any]:
    items = document.get(key)
    if not isinstance(index, int) or not isinstance(items, list) or not 0 <= index < len(items) \
            or not isinstance(items[index], dict):
        raise format_error(label, f"{what} refers to {key[:-1]} {index!r}, which the file does not have")
    return items[index]


def accessor_count(document: dict[str, Any], index: int, label: str) -> int:
    """The ``count`` of an accessor, read without reading the accessor."""
    acc = item(document, "accessors", index, label, "a primitive")
    try:
        count = int(acc["count"])
    except (KeyError, TypeError, ValueError) as exc:
        raise format_error(label, f"accessor {index} has no valid count") from exc
    if count < 0:
        raise format_error(label, f"accessor {index} has a negative count")
    return count


def accessor_array(document: dict[str, Any], buffers: list[Any], index: int, label: str,
                   max_count: int | None = None) -> NDArray[Any]:
    """The (count, width) array of an accessor, a view into its buffer (writable where the buffer is).

    The count is checked before anything is allocated: against the bytes of its buffer view, or for an accessor
    without one (zeros by the specification) against ``max_count`` (None: no limit; the readers give the count of
    the vertices the accessor belongs to).
    """
    acc = item(document, "accessors", index, label, "a primitive")
    if "sparse" in acc:
        raise format_error(label, f"accessor {index} is sparse (sparse accessors are not supported here)")
    try:
        dtype = np.dtype(COMPONENTS[acc["componentType"]])
        width = WIDTHS[acc["type"]]
        count = int(acc["count"])
    except (KeyError, TypeError, ValueError) as exc:
        raise format_error(label, f"accessor {index} has no valid componentType, type or count") from exc
    if count < 0:
        raise format_error(label, f"accessor {index} has a negative count")
    if "bufferView" not in acc:
        if max_count is not None and count > max_count:
            raise format_error(label, f"accessor {index} has no buffer view and {count:,} elements, more than the "
                               f"{max_count:,} vertices it belongs to")
        return np.zeros((count, width), dtype=dtype)
    view = item(document, "bufferViews", acc["bufferView"], label, f"accessor {index}")
    buffer_index = view.get("buffer")
    if not isinstance(buffer_index, int) or not 0 <= buffer_index < len(buffers):
        raise format_error(label, f"buffer view {acc['bufferView']} refers to buffer {buffer_index!r}, which the file "
                           "does not have")
    buf = buffers[buffer_index]
    view_offset = int(view.get("byteOffset", 0))
    view_length = int(view.get("byteLength", 0))
    element = dtype.itemsize * width
    stride = int(view.get("byteStride") or element)
    offset = int(acc.get("byteOffset", 0))
    need = offset + stride * (count - 1) + element if count else 0
    if view_offset + view_length > len(buf) or need > view_length or stride < element:
        raise format_error(label, f"accessor {index} reads past the end of its buffer (bytes "
                           f"{view_offset + offset:,} to {view_offset + need:,} of a buffer of {len(buf):,}; "
                           "malformed or truncated)")
    if count == 0:
        return np.zeros((0, width), dtype=dtype)
    return np.ndarray((count, width), dtype=dtype, buffer=buf, offset=view_offset + offset,
                      strides=(stride, dtype.itemsize))


_TRANSFORM_KEYS = frozenset(("matrix", "rotation", "scale", "translation"))


def node_matrix(node: dict[str, Any]) -> NDArray[np.float64]:
    if "matrix" in node:
        return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T  # stored column by column
    M = np.eye(4)
    x, y, z, w = (float(c) for c in node.get("rotation", (0.0, 0.0, 0.0, 1.0)))
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    M[:3, :3] = R * np.asarray(node.get("scale", (1.0, 1.0, 1.0)), dtype=np.float64)
    M[:3, 3] = np.asarray(node.get("translation", (0.0, 0.0, 0.0)), dtype=np.float64)
    return M


def mesh_instances(document: dict[str, Any],
                   label: str = "the document") -> dict[int, list[tuple[int, NDArray[np.float64]]]]:
    """The nodes showing each mesh, depth first through the scene, with their scene transforms: for each mesh, a
    list of ``(node, transform)``, each node once.

    Raises
    ------
    MeshFormatError
        A hierarchy more than :data:`MAX_NODE_DEPTH` levels deep.
    """
    nodes = document.get("nodes", [])
    scenes = document.get("scenes", [])
    if scenes:
        roots = scenes[document.get("scene", 0) if isinstance(document.get("scene", 0), int)
                       and 0 <= document.get("scene", 0) < len(scenes) else 0].get("nodes", [])
    else:
        children = {c for node in nodes for c in node.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    out: dict[int, list[tuple[int, NDArray[np.float64]]]] = {}
    identity = np.eye(4)
    stack = [(int(i), identity, 1) for i in reversed(roots)]
    seen: set[int] = set()
    while stack:  # each node once, without recursion
        i, parent, depth = stack.pop()
        if i in seen or not 0 <= i < len(nodes):
            continue
        if depth > MAX_NODE_DEPTH:
            raise format_error(label, f"its node hierarchy is more than {MAX_NODE_DEPTH} levels deep")
        seen.add(i)
        node = nodes[i]
        M = parent @ node_matrix(node) if _TRANSFORM_KEYS.intersection(node) else parent
        if "mesh" in node:
            out.setdefault(int(node["mesh"]), []).append((i, M))
        stack.extend((int(c), M, depth + 1) for c in reversed(node.get("children", [])))
    return out


def mesh_transforms(document: dict[str, Any], label: str = "the document") -> dict[int, NDArray[np.float64]]:
    """The transform of the first node (depth first through the scene) showing each mesh (see
    :func:`mesh_instances`)."""
    return {m: instances[0][1] for m, instances in mesh_instances(document, label).items()}


def triangles(indices: NDArray[np.int64], mode: int) -> NDArray[np.int64]:
    if mode == 4:
        return indices[: len(indices) // 3 * 3].reshape(-1, 3)
    if len(indices) < 3:
        return np.zeros((0, 3), dtype=np.int64)
    k = np.arange(len(indices) - 2)
    if mode == 5:  # strip: every other triangle flipped to keep the orientation
        odd = k % 2 == 1
        a, b = np.where(odd, k + 1, k), np.where(odd, k, k + 1)
        return np.stack([indices[a], indices[b], indices[k + 2]], axis=1)
    return np.stack([np.full_like(k, indices[0]), indices[k + 1], indices[k + 2]], axis=1)


def check_compression(document: dict[str, Any], label: str) -> None:
    used = set(document.get("extensionsRequired", [])) | set(document.get("extensionsUsed", []))
    for name in COMPRESSION:
        if name in used:
            raise MeshFormatError(f"{label}: compressed glTF ({name}) is not supported; export it without "
                                  "compression")


def pad4(data: bytes, fill: bytes) -> bytes:
    return data + fill * (-len(data) % 4)


def glb_bytes(document: dict[str, Any], binary: bytes | None) -> bytes:
    text = pad4(json.dumps(document, separators=(",", ":"), ensure_ascii=False).encode("utf-8"), b" ")
    chunks = struct.pack("<II", len(text), JSON_CHUNK) + text
    if binary is not None:
        body = pad4(binary, b"\0")
        chunks += struct.pack("<II", len(body), BIN_CHUNK) + body
    return struct.pack("<4sII", GLB_MAGIC, 2, 12 + len(chunks)) + chunks
