"""Small textured models made in code for the asset tests: a cube with UV seams as OBJ (+ MTL + PNG), PLY and glTF."""

from __future__ import annotations

import base64
import io
import json
import struct
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

CUBE_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
                  dtype=np.float64) * 2.0 - 1.0
#: Quads, outward (counter-clockwise seen from outside): -z, +z, -y, +x, +y, -x.
CUBE_QUADS = np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6], [3, 0, 4, 7]])
FACE_NORMALS = np.array([[0, 0, -1], [0, 0, 1], [0, -1, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0]], dtype=np.float64)


def png(width: int = 4, height: int = 4, seed: int = 0) -> bytes:
    """A small PNG image with varied pixels."""
    from PIL import Image

    rng = np.random.default_rng(seed)
    image = Image.fromarray(rng.integers(0, 256, size=(height, width, 3), dtype=np.uint8))
    out = io.BytesIO()
    image.save(out, format="PNG")
    return out.getvalue()


def cube_obj(folder: Path, name: str = "cube", texture: bool = True) -> Path:
    """A textured cube: 8 ``v``, 14 ``vt`` (a cross unwrap: seams), 6 ``vn``, quads and triangles, two materials,
    two groups, an object, smoothing groups, a line statement; ``NAME.mtl`` and ``tex/checker.png`` beside it."""
    uv = [(0.25 * (i % 4) + 0.0625 * (i // 4), 0.3 + 0.05 * i) for i in range(14)]
    lines = ["# a textured cube", f"mtllib {name}.mtl", "o box"]
    lines += ["v " + " ".join(repr(float(x)) for x in v) for v in CUBE_V]
    lines += [f"vt {u!r} {w!r}" for u, w in uv]
    lines += ["vn " + " ".join(repr(float(x)) for x in n) for n in FACE_NORMALS]
    lines += ["g front back", "usemtl red", "s 1"]
    t = 0
    for k, quad in enumerate(CUBE_QUADS):
        if k == 2:
            lines += ["g sides", "usemtl blue", "s off"]
        corners = []
        for j, v in enumerate(quad):
            corners.append(f"{v + 1}/{(t + j) % 14 + 1}/{k + 1}")
        t += 2
        if k == 5:  # one face as two triangles, with a relative index
            lines.append(f"f {corners[0]} {corners[1]} {corners[2]}")
            lines.append(f"f {corners[0]} {corners[2]} -1/{(t + 1) % 14 + 1}/-1")
        else:
            lines.append("f " + " ".join(corners))
    lines.append("l 1 7")
    path = folder / f"{name}.obj"
    path.write_text("\n".join(lines) + "\n")
    (folder / f"{name}.mtl").write_text(
        "newmtl red\nKd 1 0 0\nmap_Kd -s 1 1 1 tex/checker.png\n\nnewmtl blue\nKd 0 0 1\nmap_Kd tex/checker.png\n"
        "bump tex/bump.png\n")
    if texture:
        (folder / "tex").mkdir(exist_ok=True)
        (folder / "tex" / "checker.png").write_bytes(png(8, 8, 1))
        (folder / "tex" / "bump.png").write_bytes(png(4, 4, 2))
    return path


def cube_ply(folder: Path, name: str = "cube") -> Path:
    """A cube with 24 vertices (one per face corner: seams), colours, normals, ``s t`` and a face flag, ASCII."""
    V = CUBE_V[CUBE_QUADS].reshape(-1, 3)
    N = np.repeat(FACE_NORMALS, 4, axis=0)
    UV = np.array([(0.1 * (i % 5), 0.07 * i) for i in range(24)])
    C = (np.arange(24 * 3).reshape(24, 3) * 7 % 256).astype(int)
    head = ["ply", "format ascii 1.0", "comment made for a test", "comment TextureFile checker.png",
            "element vertex 24", *(f"property float {p}" for p in ("x", "y", "z", "nx", "ny", "nz")),
            "property uchar red", "property uchar green", "property uchar blue", "property float s",
            "property float t", "element face 6", "property list uchar int vertex_indices", "property uchar flags",
            "end_header"]
    body = [" ".join([*(repr(float(x)) for x in (*V[i], *N[i])), *(str(c) for c in C[i]),
                      repr(float(UV[i, 0])), repr(float(UV[i, 1]))]) for i in range(24)]
    body += [f"4 {4 * k} {4 * k + 1} {4 * k + 2} {4 * k + 3} {k + 10}" for k in range(6)]
    path = folder / f"{name}.ply"
    path.write_text("\n".join(head + body) + "\n")
    (folder / "checker.png").write_bytes(png(8, 8, 3))
    return path


def _align(blob: bytearray) -> None:
    blob += b"\0" * (-len(blob) % 4)


def cube_gltf_document(image: bytes | None = None, *, lines: bool = True,
                       transform: bool = True) -> tuple[dict[str, Any], bytes]:
    """A glTF cube: 24 vertices (4 per face: seams), two meshes of three faces each (own accessors, own materials),
    NORMAL, TEXCOORD_0 and COLOR_0, the second mesh's node rotated, scaled and moved, a lines primitive, and an
    image in a buffer view (when given). Returns the document and its one buffer."""
    blob = bytearray()
    accessors: list[dict[str, Any]] = []
    views: list[dict[str, Any]] = []

    def add(array: np.ndarray, kind: str, component: int, target: int | None = None, minmax: bool = False) -> int:
        _align(blob)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": array.nbytes,
                      **({"target": target} if target else {})})
        blob.extend(array.tobytes())
        acc: dict[str, Any] = {"bufferView": len(views) - 1, "componentType": component, "count": len(array),
                               "type": kind}
        if minmax:
            acc["min"] = [float(x) for x in array.min(axis=0)]
            acc["max"] = [float(x) for x in array.max(axis=0)]
        accessors.append(acc)
        return len(accessors) - 1

    meshes = []
    for half in range(2):
        quads = CUBE_QUADS[3 * half:3 * half + 3]
        V = CUBE_V[quads].reshape(-1, 3).astype("<f4")
        N = np.repeat(FACE_NORMALS[3 * half:3 * half + 3], 4, axis=0).astype("<f4")
        UV = np.array([(0.1 * (i % 5) + 0.01 * half, 0.07 * i) for i in range(12)], dtype="<f4")
        C = (np.arange(12 * 4).reshape(12, 4) * 9 % 256).astype("<u1")
        T = np.array([[4 * k, 4 * k + 1, 4 * k + 2, 4 * k, 4 * k + 2, 4 * k + 3] for k in range(3)],
                     dtype="<u2").reshape(-1)
        pos = add(V, "VEC3", 5126, 34962, minmax=True)
        nor = add(N, "VEC3", 5126, 34962)
        tex = add(UV, "VEC2", 5126, 34962)
        col = add(C, "VEC4", 5121, 34962)
        accessors[col]["normalized"] = True
        idx = add(T, "SCALAR", 5123, 34963)
        prims = [{"attributes": {"POSITION": pos, "NORMAL": nor, "TEXCOORD_0": tex, "COLOR_0": col},
                  "indices": idx, "material": half}]
        if lines and half == 1:
            L = np.array([0, 5, 2, 7], dtype="<u1")
            prims.append({"attributes": {"POSITION": pos}, "indices": add(L, "SCALAR", 5121), "mode": 1})
        meshes.append({"name": f"half{half}", "primitives": prims})
    document: dict[str, Any] = {
        "asset": {"version": "2.0", "generator": "arap tests"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "root", "children": [1, 2], "translation": [0.5, 0, 0] if transform else [0, 0, 0]},
                  {"mesh": 0},
                  {"mesh": 1, **({"rotation": [0, 0.6, 0, 0.8], "scale": [2, 2, 2], "translation": [0, 1, 0]}
                                 if transform else {})}],
        "meshes": meshes,
        "materials": [{"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1]}},
                      {"name": "textured", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "accessors": accessors,
        "bufferViews": views,
        "extras": {"note": "kept"},
    }
    if image is not None:
        _align(blob)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(image)})
        blob.extend(image)
        document["images"] = [{"name": "checker", "bufferView": len(views) - 1, "mimeType": "image/png"}]
        document["textures"] = [{"source": 0}]
        document["samplers"] = [{"magFilter": 9728}]
        document["textures"][0]["sampler"] = 0
    document["buffers"] = [{"byteLength": len(blob)}]
    return document, bytes(blob)


def glb_bytes(document: dict[str, Any], blob: bytes) -> bytes:
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    body = blob + b"\0" * (-len(blob) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(body), 0x004E4942) + body
    return struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks


def cube_glb(folder: Path, name: str = "cube", **kwargs: Any) -> Path:
    document, blob = cube_gltf_document(png(8, 8, 4), **kwargs)
    path = folder / f"{name}.glb"
    path.write_bytes(glb_bytes(document, blob))
    return path


def cube_gltf(folder: Path, name: str = "cube", embedded: bool = False) -> Path:
    """The glTF cube as ``NAME.gltf`` with its buffer in ``NAME-data.bin`` (or a data URI) and its image in a
    PNG file beside it."""
    document, blob = cube_gltf_document(None)
    document["images"] = [{"uri": "images/checker%20one.png"}]
    document["textures"] = [{"source": 0}]
    if embedded:
        document["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
    else:
        document["buffers"][0]["uri"] = f"{name}-data.bin"
        (folder / f"{name}-data.bin").write_bytes(blob)
    (folder / "images").mkdir(exist_ok=True)
    (folder / "images" / "checker one.png").write_bytes(png(8, 8, 5))
    path = folder / f"{name}.gltf"
    path.write_text(json.dumps(document, indent=2))
    return path


def coloured_ply(path: Path, axis: int = 2, subdivisions: int = 1) -> Path:
    """An icosphere with red vertices on the positive side of ``axis`` and blue ones on the other."""
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=subdivisions)
    colors = np.where((mesh.vertices[:, axis] > 0)[:, None], [255, 0, 0, 255], [0, 0, 255, 255]).astype(np.uint8)
    mesh.visual = trimesh.visual.ColorVisuals(mesh, vertex_colors=colors)
    path.write_bytes(mesh.export(file_type="ply"))
    return path


def instanced_glb(folder: Path, name: str = "instanced") -> Path:
    """The glTF cube with its first mesh shown by one more node (moved and turned), as a truck's two wheels share
    one mesh: 24 vertices in the file's accessors, 36 drawn."""
    document, blob = cube_gltf_document(png(8, 8, 4))
    document["nodes"].append({"name": "second", "mesh": 0, "translation": [5.0, 0.0, 0.0],
                              "rotation": [0.0, 0.0, 0.6, 0.8]})
    document["nodes"][0]["children"].append(len(document["nodes"]) - 1)
    path = folder / f"{name}.glb"
    path.write_bytes(glb_bytes(document, blob))
    return path


def zip_of(folder: Path, names: list[str] | None = None, compression: int = zipfile.ZIP_DEFLATED) -> bytes:
    """The files under ``folder`` (or those named) in a zip, by their relative names."""
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", compression=compression) as archive:
        for path in sorted(folder.rglob("*")):
            name = path.relative_to(folder).as_posix()
            if path.is_file() and (names is None or name in names):
                archive.writestr(name, path.read_bytes())
    return out.getvalue()
