"""The glTF 2.0 container: the GLB chunks, the JSON document, buffers and data URIs, accessors as arrays, the
scene's node transforms and primitive modes; and a GLB written back from a document and its binary buffer.

:mod:`arap.io.gltf_asset` reads and writes whole assets with it.
"""

from __future__ import annotations

import base64
import json
import logging
import struct
import urllib.parse
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arap.errors import MeshFormatError

__all__ = ["GltfData", "accessor_array", "check_compression", "data_uri", "format_error", "glb_bytes", "item",
           "mesh_transforms", "node_matrix", "pad4", "parse_json", "read_uri", "split_glb", "triangles"]

logger = logging.getLogger(__name__)

GLB_MAGIC = b"glTF"
JSON_CHUNK, BIN_CHUNK = 0x4E4F534A, 0x004E4942
FLOAT, UINT = 5126, 5125
COMPONENTS: dict[int, str] = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
COMPRESSION = ("KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_meshopt_compression")
MODES = {0: "points", 1: "lines", 2: "line loops", 3: "line strips", 4: "triangles", 5: "triangle strips",
          6: "triangle fans"}


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
    """

    document: dict[str, Any]
    buffers: list[bytes]
    binary: bool
    positions: list[int] = field(default_factory=list)
    offsets: list[int] = field(default_factory=list)
    transforms: list[NDArray[np.float64]] = field(default_factory=list)
    normals: list[tuple[int, int]] = field(default_factory=list)
    images: dict[int, bytes] = field(default_factory=dict)


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
    chunks: list[tuple[int, bytes]] = []
    at = 12
    while at + 8 <= length:
        size, kind = struct.unpack_from("<II", data, at)
        if at + 8 + size > length:
            raise format_error(label, f"a chunk of {size:,} bytes runs past the end of the file (truncated?)")
        chunks.append((kind, data[at + 8:at + 8 + size]))
        at += 8 + size
    if not chunks or chunks[0][0] != JSON_CHUNK:
        raise format_error(label, "the first chunk is not the JSON document")
    document = parse_json(chunks[0][1], label)
    binary = next((c for k, c in chunks[1:] if k == BIN_CHUNK), None)
    return document, binary


def parse_json(text: bytes, label: str) -> dict[str, Any]:
    try:
        document = json.loads(text.decode("utf-8").rstrip(" \0"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise format_error(label, f"the JSON document is malformed ({exc})") from exc
    if not isinstance(document, dict):
        raise format_error(label, "the JSON document is not an object")
    version = str(document.get("asset", {}).get("version", "2.0")) if isinstance(document.get("asset"), dict) \
        else "2.0"
    if not version.startswith("2"):
        raise format_error(label, f"glTF version {version} (only 2.0 is supported)")
    return document


def data_uri(uri: str) -> bytes | None:
    if not uri.startswith("data:"):
        return None
    head, _, payload = uri.partition(",")
    if head.endswith(";base64"):
        return base64.b64decode(payload)
    return urllib.parse.unquote_to_bytes(payload)


def read_uri(uri: str, folder: Path | None) -> bytes | None:
    from arap.io.paths import read_regular_file

    data = data_uri(uri)
    if data is not None:
        return data
    if folder is None:
        return None
    try:
        return read_regular_file(folder / urllib.parse.unquote(uri))
    except OSError:
        return None


def item(document: dict[str, Any], key: str, index: Any, label: str, what: str) -> dict[str, Any]:
    items = document.get(key)
    if not isinstance(index, int) or not isinstance(items, list) or not 0 <= index < len(items) \
            or not isinstance(items[index], dict):
        raise format_error(label, f"{what} refers to {key[:-1]} {index!r}, which the file does not have")
    return items[index]


def accessor_array(document: dict[str, Any], buffers: list[Any], index: int, label: str) -> NDArray[Any]:
    """The (count, width) array of an accessor, a view into its buffer (writable where the buffer is)."""
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


def mesh_transforms(document: dict[str, Any]) -> dict[int, NDArray[np.float64]]:
    """The transform of the first node (depth first through the scene) showing each mesh."""
    nodes = document.get("nodes", [])
    scenes = document.get("scenes", [])
    if scenes:
        roots = scenes[document.get("scene", 0) if isinstance(document.get("scene", 0), int)
                       and 0 <= document.get("scene", 0) < len(scenes) else 0].get("nodes", [])
    else:
        children = {c for node in nodes for c in node.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    out: dict[int, NDArray[np.float64]] = {}
    stack = [(int(i), np.eye(4)) for i in reversed(roots)]
    seen: set[int] = set()
    while stack:
        i, parent = stack.pop()
        if i in seen or not 0 <= i < len(nodes):
            continue
        seen.add(i)
        M = parent @ node_matrix(nodes[i])
        if "mesh" in nodes[i]:
            mesh = int(nodes[i]["mesh"])
            if mesh in out and not np.array_equal(out[mesh], M):
                logger.info("mesh %d is shown by several nodes; its vertices are placed by the first, and every "
                            "instance shows the deformed mesh", mesh)
            out.setdefault(mesh, M)
        stack.extend((int(c), M) for c in reversed(nodes[i].get("children", [])))
    return out


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
