"""glTF 2.0 (``.gltf`` with its buffers and images, and binary ``.glb``) read and written with the whole scene kept.

The JSON document and the buffers are kept as they are; writing new positions changes only the bytes of the
POSITION accessors (and their ``min``/``max``) and of the NORMAL accessors, in place, so everything else (texture
coordinates, colours, tangents, skins, morph targets, animations, materials, embedded images, other extensions)
is written back bit-identical. See :mod:`arap.io.assets` for the vertex numbering, the seams and the normals.

Triangle primitives (mode 4, and strips and fans, mode 5 and 6) make the surface; points and lines (modes 0-3) are
kept untouched and do not take part in the solve (their vertices move only where they share a POSITION accessor
with triangles). Compressed geometry (``KHR_draco_mesh_compression``, ``EXT_meshopt_compression``), sparse POSITION
accessors and quantized positions (``KHR_mesh_quantization``) are refused with a clear message.
"""

from __future__ import annotations

import base64
import copy
import json
import logging
import urllib.parse
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arap.errors import MeshError, MeshFormatError, MeshTooLargeError
from arap.io.assets import MeshAsset, group_normals, missing_file_warning, vertex_normal_groups, write_beside
from arap.io.gltf_container import (
    COMPRESSION,
    FLOAT,
    GLB_MAGIC,
    MODES,
    UINT,
    GltfData,
    Instance,
    accessor_array,
    accessor_count,
    check_compression,
    format_error,
    glb_bytes,
    item,
    mesh_instances,
    parse_json,
    read_uri,
    split_glb,
    triangles,
)
from arap.io.paths import SpecialFileError

__all__ = ["GltfData", "accessor_array", "geometry_glb", "read_gltf_asset", "write_glb_asset", "write_gltf_asset"]

logger = logging.getLogger(__name__)

_IDENTITY = np.eye(4)
_IDENTITY.setflags(write=False)
MAX_INSTANCED_VERTICES = 1 << 25
"""Most vertices a glTF file's meshes shown by several nodes may make once each instance has its own copy: many
nodes showing one large mesh would cost memory out of all proportion to the file."""
TRIANGLES_PER_VERTEX = 4
"""Most triangles accepted per vertex of a glTF file's triangle primitives: a surface has about two; many more can
only be primitives repeating the same indices, refused before they are read (they would cost memory out of all
proportion to the file)."""


def read_gltf_asset(data: bytes, label: str, folder: Path | None, max_vertices: int | None) -> MeshAsset:
    """A :class:`MeshAsset` from the bytes of a glTF or GLB file (external buffers and images read from
    ``folder``).

    Raises
    ------
    MeshFormatError
        Anything malformed, said in the file's terms where it is checked and as a malformed document otherwise.
    """
    try:
        return _read_gltf_asset(data, label, folder, max_vertices)
    except MeshError:
        raise
    except (KeyError, TypeError, AttributeError, IndexError, ValueError, OverflowError) as exc:
        raise format_error(label, f"the document is malformed ({type(exc).__name__}: {exc})") from exc


def _read_gltf_asset(data: bytes, label: str, folder: Path | None, max_vertices: int | None) -> MeshAsset:
    binary = data[:4] == GLB_MAGIC
    if binary:
        document, chunk = split_glb(data, label)
    else:
        if not data.strip():
            raise MeshFormatError(f"{label} contains no vertices (the file is empty)")
        document, chunk = parse_json(data, label), None
    check_compression(document, label)
    buffers: list[bytes] = []
    for i, buffer in enumerate(document.get("buffers", [])):
        if not isinstance(buffer, dict):
            raise format_error(label, f"buffer {i} is not an object")
        uri = buffer.get("uri")
        if uri is None:
            if not binary or i != 0 or chunk is None:
                raise format_error(label, f"buffer {i} has no URI and there is no binary chunk for it")
            content = chunk
        else:
            try:
                content = read_uri(str(uri), folder)
            except ValueError as exc:
                raise format_error(label, f"buffer {i} has a malformed data URI ({exc})") from exc
            except OSError as exc:
                reason = f" ({exc.strerror})" if isinstance(exc, SpecialFileError) else ""
                raise format_error(label, f"buffer {i} ({str(uri)[:60]!r}) cannot be read{reason}") from exc
        length = int(buffer.get("byteLength", len(content)))
        if len(content) < length:
            raise format_error(label, f"buffer {i} holds {len(content):,} bytes, fewer than its byteLength {length:,} "
                               "(truncated?)")
        buffers.append(content)
    gltf = GltfData(document=document, buffers=buffers, binary=binary)
    instances = mesh_instances(document, label)
    transforms = {m: nodes[0][1] for m, nodes in instances.items()}
    recorded: dict[int, list[tuple[int, NDArray[np.int64], int, int | None]]] = {}  # triangles of each mesh
    blocks: list[NDArray[np.float64]] = []
    faces: list[NDArray[np.int64]] = []
    face_materials: list[NDArray[np.int64]] = []
    face_groups: list[NDArray[np.int64]] = []
    uv_blocks: dict[int, NDArray[np.float64]] = {}
    color_blocks: dict[int, NDArray[Any]] = {}
    where: dict[int, int] = {}  # first vertex of each POSITION accessor read
    counts: dict[int, int] = {}  # and its count
    normal_pairs: set[tuple[int, int]] = set()
    n_vertices = n_triangles = 0
    skipped: dict[str, int] = {}
    meshes = document.get("meshes", [])
    for m, mesh in enumerate(meshes):
        for p, prim in enumerate(mesh.get("primitives", []) if isinstance(mesh, dict) else []):
            what = f"mesh {m} primitive {p}"
            if any(name in prim.get("extensions", {}) for name in COMPRESSION):
                raise MeshFormatError(f"{label}: compressed glTF ({next(iter(prim['extensions']))}) is not supported")
            mode = int(prim.get("mode", 4))
            if mode not in MODES:
                raise format_error(label, f"{what} has an unknown mode {mode}")
            if mode < 4:
                skipped[MODES[mode]] = skipped.get(MODES[mode], 0) + 1
                continue
            attributes = prim.get("attributes", {})
            if "POSITION" not in attributes:
                raise format_error(label, f"{what} has no POSITION attribute")
            pos = int(attributes["POSITION"])
            acc = item(document, "accessors", pos, label, what)
            if pos not in where:
                if acc.get("type") != "VEC3":
                    raise format_error(label, f"{what}'s POSITION accessor has type {acc.get('type')!r}, not VEC3")
                if acc.get("componentType") != FLOAT:
                    raise MeshFormatError(f"{label}: {what} has quantized or non-float positions "
                                          "(KHR_mesh_quantization), which are not supported")
                if "bufferView" not in acc and "sparse" not in acc:
                    raise format_error(label, f"{what}'s POSITION accessor has no buffer view (every vertex would be "
                                       "at the origin)")
                count = accessor_count(document, pos, label)
                total = n_vertices + count
                if max_vertices is not None and total > max_vertices:
                    raise MeshTooLargeError(f"{label} has more than {max_vertices:,} vertices ({total:,} so far); at "
                                            f"most {max_vertices:,} vertices are accepted", total, max_vertices)
                local = accessor_array(document, buffers, pos, label).astype(np.float64)
                M = transforms.get(m, _IDENTITY)
                world = local if M is _IDENTITY or np.array_equal(M, _IDENTITY) else local @ M[:3, :3].T + M[:3, 3]
                where[pos], counts[pos] = n_vertices, len(world)
                n_vertices += len(world)
                gltf.positions.append(pos)
                gltf.offsets.append(where[pos])
                gltf.transforms.append(M)
                blocks.append(world)
                if "TEXCOORD_0" in attributes:
                    uv_blocks[pos] = accessor_array(document, buffers, int(attributes["TEXCOORD_0"]), label,
                                                    len(world))
                if "COLOR_0" in attributes:
                    color_blocks[pos] = accessor_array(document, buffers, int(attributes["COLOR_0"]), label,
                                                       len(world))
            n = counts[pos]
            if "NORMAL" in attributes and (pos, int(attributes["NORMAL"])) not in normal_pairs:
                normal_acc = item(document, "accessors", int(attributes["NORMAL"]), label, what)
                if "bufferView" not in normal_acc and accessor_count(document, int(attributes["NORMAL"]), label) > n:
                    raise format_error(label, f"{what}'s NORMAL accessor has no buffer view and more elements than "
                                       f"its {n:,} vertices")
                normal_pairs.add((pos, int(attributes["NORMAL"])))
                gltf.normals.append((pos, int(attributes["NORMAL"])))
            if "indices" in prim:
                idx_acc = item(document, "accessors", prim["indices"], label, what)
                if idx_acc.get("type") != "SCALAR" or idx_acc.get("componentType") not in (5121, 5123, 5125):
                    raise format_error(label, f"{what} has indices that are not unsigned integer scalars")
                if "bufferView" not in idx_acc:
                    raise format_error(label, f"{what}'s indices have no buffer view (every triangle would be one "
                                       "point)")
                n_indices = accessor_count(document, int(prim["indices"]), label)
            else:
                n_indices = n
            n_triangles += n_indices // 3 if mode == 4 else max(n_indices - 2, 0)
            if n_triangles > TRIANGLES_PER_VERTEX * n_vertices:
                raise format_error(label, f"its triangle primitives make {n_triangles:,} triangles on {n_vertices:,} "
                                   f"vertices, more than {TRIANGLES_PER_VERTEX} per vertex (primitives repeating the "
                                   "same triangles?)")
            if "indices" in prim:
                indices = accessor_array(document, buffers, int(prim["indices"]), label).reshape(-1)
                indices = indices.astype(np.int64)
            else:
                indices = np.arange(n, dtype=np.int64)
            if len(indices) and indices.max() >= n:
                raise format_error(label, f"{what} refers to vertex {int(indices.max())}, but its POSITION accessor "
                                   f"has {n:,} vertices")
            T = triangles(indices, mode) + where[pos]
            faces.append(T)
            material = prim.get("material", -1)
            material = material if isinstance(material, int) else -1
            face_materials.append(np.full(len(T), material, dtype=np.int64))
            face_groups.append(np.full(len(T), m, dtype=np.int64))
            normal = int(attributes["NORMAL"]) if "NORMAL" in attributes else None
            recorded.setdefault(m, []).append((pos, T - where[pos], material, normal))
    # A mesh shown by several nodes: one copy of its vertices per further node, placed by that node's transform.
    separated: list[str] = []
    for m, prims in recorded.items():
        for node, M in instances.get(m, [])[1:]:
            copies: dict[int, int] = {}
            for pos, T_local, material, normal in prims:
                if pos not in copies:
                    total = n_vertices + counts[pos]
                    if total > MAX_INSTANCED_VERTICES:
                        raise format_error(label, f"its meshes shown by several nodes make more than "
                                           f"{MAX_INSTANCED_VERTICES:,} vertices once each instance is a part of "
                                           "its own")
                    if max_vertices is not None and total > max_vertices:
                        raise MeshTooLargeError(f"{label} has more than {max_vertices:,} vertices ({total:,} so far, "
                                                "instances made separate parts); at most "
                                                f"{max_vertices:,} vertices are accepted", total, max_vertices)
                    local = accessor_array(document, buffers, pos, label).astype(np.float64)
                    copies[pos] = n_vertices
                    gltf.instances.append(Instance(node, m, pos, normal, n_vertices, M))
                    blocks.append(local @ M[:3, :3].T + M[:3, 3])
                    n_vertices += counts[pos]
                n_triangles += len(T_local)
                if n_triangles > TRIANGLES_PER_VERTEX * n_vertices:
                    raise format_error(label, f"its triangle primitives make {n_triangles:,} triangles on "
                                       f"{n_vertices:,} vertices, more than {TRIANGLES_PER_VERTEX} per vertex")
                faces.append(T_local + copies[pos])
                face_materials.append(np.full(len(T_local), material, dtype=np.int64))
                face_groups.append(np.full(len(T_local), m, dtype=np.int64))
        if len(instances.get(m, [])) > 1:
            mesh = meshes[m]
            separated.append(f"mesh {mesh.get('name') or m!r} is shown by {len(instances[m])} nodes: its "
                             f"{len(instances[m])} instances were made separate parts")
    if separated:
        import warnings

        warnings.warn(f"{label}: {'; '.join(separated)} (each deforms on its own and is written as its own mesh)",
                      UserWarning, stacklevel=4)
    if skipped:
        logger.info("%s: %s kept as they are (not part of the surface)", label,
                    ", ".join(f"{k} primitives: {v}" for k, v in skipped.items()))
    if not blocks:
        kept = f" (it holds only {', '.join(skipped)})" if skipped else ""
        raise MeshFormatError(f"{label} contains no triangle primitives{kept}; a surface is needed")
    V = np.concatenate(blocks)
    F = np.concatenate(faces)
    if not len(F):
        raise MeshFormatError(f"{label} has {len(V):,} vertices but no faces; a surface is needed")
    uvs = None
    if uv_blocks:
        uv = np.full((len(V), 2), np.nan)
        placed = [(where[pos], pos) for pos in uv_blocks] + [(i.offset, i.position) for i in gltf.instances
                                                            if i.position in uv_blocks]
        for start, pos in placed:
            block = uv_blocks[pos]
            values = block[:, :2].astype(np.float64)
            if block.dtype.kind in "iu":  # normalized integers (KHR_mesh_quantization)
                values = values / float(2 ** (8 * block.dtype.itemsize - (block.dtype.kind == "i")) - 1)
            uv[start:start + len(block)] = values
        uvs = uv[F]
    colors = None
    if len(color_blocks) == len(gltf.positions):
        parts = [color_blocks[pos] for pos in [*gltf.positions, *(i.position for i in gltf.instances)]]
        if len({(p.dtype, p.shape[1]) for p in parts}) == 1:
            colors = np.concatenate(parts)
    textures: dict[str, bytes] = {}
    for i, image in enumerate(document.get("images", [])):
        uri = str(image.get("uri", ""))
        name = str(image.get("name") or (urllib.parse.unquote(uri) if uri and not uri.startswith("data:")
                                         else f"image{i}"))
        if name in textures:
            name = f"image{i}"
        if "bufferView" in image:
            view = item(document, "bufferViews", image["bufferView"], label, f"image {i}")
            start = int(view.get("byteOffset", 0))
            try:
                content = buffers[int(view["buffer"])][start:start + int(view["byteLength"])]
            except (IndexError, KeyError, ValueError) as exc:
                raise format_error(label, f"image {i} refers to a buffer view that cannot be read") from exc
            textures[name] = bytes(content)
        elif "uri" in image:
            blob = _read_image(str(image["uri"]), folder, label)
            if blob is None:
                continue
            textures[name] = blob
            if not str(image["uri"]).startswith("data:"):
                gltf.images[i] = blob
    materials = [str(mat.get("name") or f"material{i}") for i, mat in enumerate(document.get("materials", []))]
    groups = [str(mesh.get("name") or f"mesh{i}") for i, mesh in enumerate(meshes)]
    return MeshAsset(format="glb" if binary else "gltf", vertices=V, faces=F, materials=materials,
                     face_materials=np.concatenate(face_materials), groups=groups,
                     face_groups=np.concatenate(face_groups), uvs=uvs, vertex_colors=colors, textures=textures,
                     data=gltf)


def _read_image(uri: str, folder: Path | None, label: str) -> bytes | None:
    """The content of an image's URI (:func:`~arap.io.gltf_container.read_uri`), or None with a warning naming it."""
    try:
        return read_uri(uri, folder)
    except (OSError, ValueError) as exc:
        reason = f" ({exc.strerror})" if isinstance(exc, SpecialFileError) else f" ({exc})" \
            if isinstance(exc, ValueError) else ""
        missing_file_warning(f"{label}: the texture {uri[:200]!r} cannot be read{reason}; its reference is kept")
        return None


# ---------------------------------------------------------------------------------------------- writing
def _new_normals(asset: MeshAsset, gltf: GltfData, V: NDArray[np.float64],
                 buffers: list[bytearray]) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.bool_]] | None:
    """Recompute the NORMAL accessors for the positions ``V`` (file numbering, scene coordinates), in place.

    Returns
    -------
    group : (n,) int64 array
        The normal group of each vertex (-1: none).
    normals : (g, 3) float64 array
        Each group's new normal in scene coordinates, where ``valid``.
    valid : (g,) bool array
    None
        Without NORMAL accessors.
    """
    if not gltf.normals:
        return None
    n = len(asset.vertices)
    slot = {pos: k for k, pos in enumerate(gltf.positions)}
    old = np.full((n, 3), np.nan, dtype=np.float32)
    placed = [(normal, gltf.offsets[slot[pos]]) for pos, normal in gltf.normals]
    placed += [(i.normal, i.offset) for i in gltf.instances if i.normal is not None]
    for normal, start in placed:
        values = accessor_array(gltf.document, gltf.buffers, normal, "the asset")
        if values.dtype != np.float32 or values.shape[1] != 3:
            continue
        count = min(len(values), n - start)
        block = old[start:start + count]
        empty = np.isnan(block[:, 0])
        block[empty] = values[:count][empty]
    group = vertex_normal_groups(asset.solve_mesh().to_solve, old)
    normals, valid = group_normals(V, asset.faces, group[asset.faces], n)
    for pos, normal in gltf.normals:
        k = slot[pos]
        target = accessor_array(gltf.document, buffers, normal, "the asset")
        if target.dtype != np.float32 or target.shape[1] != 3:
            logger.warning("normal accessor %d is not float VEC3; left as it is", normal)
            continue
        rows = group[gltf.offsets[k]:gltf.offsets[k] + len(target)]
        if len(rows) < len(target):
            continue
        world = normals[np.maximum(rows, 0)]
        ok = (rows >= 0) & valid[np.maximum(rows, 0)]
        M = gltf.transforms[k]
        local = world if np.array_equal(M, np.eye(4)) else world @ M[:3, :3]  # n_local ∝ Mᵀ n_world
        length = np.linalg.norm(local, axis=1)
        ok &= length > 0
        local = local / np.where(length > 0, length, 1.0)[:, None]
        target[ok] = local[ok].astype(np.float32)
    return group, normals, valid


def _local(world: NDArray[np.float64], M: NDArray[np.float64], what: str) -> NDArray[np.float32]:
    """Scene positions put back into the coordinates of a node of transform ``M``, as float32."""
    if not np.array_equal(M, np.eye(4)):
        try:
            inverse = np.linalg.inv(M)
        except np.linalg.LinAlgError as exc:
            raise MeshError(f"the transform of {what} cannot be inverted (a zero scale?)") from exc
        world = world @ inverse[:3, :3].T + inverse[:3, 3]
    local = world.astype(np.float32)
    if not np.isfinite(local).all():
        raise MeshError("positions beyond the range of single precision (glTF stores float32); not written")
    return local


def _separate_instances(document: dict[str, Any], buffers: list[bytearray], gltf: GltfData,
                        V: NDArray[np.float64],
                        normals: tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.bool_]] | None) -> None:
    """Give every further node showing a mesh its own copy of the mesh, with its own POSITION (and NORMAL)
    accessors holding its positions (in a new buffer), so that each instance keeps its own deformed shape.

    The copies are appended to ``meshes`` in the order of :attr:`GltfData.instances`: read again, the file numbers
    its vertices as the asset does.
    """
    blob = bytearray()
    b = len(buffers)
    views, accessors = document.setdefault("bufferViews", []), document.setdefault("accessors", [])

    def add(values: NDArray[np.float32], bounds: bool) -> int:
        blob.extend(b"\0" * (-len(blob) % 4))
        views.append({"buffer": b, "byteOffset": len(blob), "byteLength": values.nbytes, "target": 34962})
        blob.extend(np.ascontiguousarray(values, dtype="<f4").tobytes())
        acc: dict[str, Any] = {"bufferView": len(views) - 1, "componentType": FLOAT, "count": len(values),
                               "type": "VEC3"}
        if bounds:
            acc["min"] = [float(x) for x in values.min(axis=0)]
            acc["max"] = [float(x) for x in values.max(axis=0)]
        accessors.append(acc)
        return len(accessors) - 1

    copies: dict[tuple[int, int], dict[int, tuple[int, int | None]]] = {}
    for inst in gltf.instances:
        count = int(document["accessors"][inst.position]["count"])
        rows = slice(inst.offset, inst.offset + count)
        position = add(_local(V[rows], inst.transform, f"node {inst.node}"), True)
        normal = None
        if inst.normal is not None:
            old = accessor_array(gltf.document, gltf.buffers, inst.normal, "the asset")
            values = np.asarray(old[:count, :3], dtype=np.float64).copy() if old.shape[1] >= 3 \
                else np.zeros((count, 3))
            if normals is not None and len(old) >= count:
                group, world, valid = normals
                g = group[rows]
                local = world[np.maximum(g, 0)] @ inst.transform[:3, :3]
                length = np.linalg.norm(local, axis=1)
                ok = (g >= 0) & valid[np.maximum(g, 0)] & (length > 0)
                values[ok] = local[ok] / length[ok, None]
            normal = add(values.astype(np.float32), False)
        copies.setdefault((inst.node, inst.mesh), {})[inst.position] = (position, normal)
    meshes = document["meshes"]
    for (node, m), mapping in copies.items():
        mesh = copy.deepcopy(meshes[m])
        for prim in mesh.get("primitives", []):
            attributes = prim.get("attributes", {})
            if attributes.get("POSITION") in mapping:
                position, normal = mapping[attributes["POSITION"]]
                attributes["POSITION"] = position
                if normal is not None and "NORMAL" in attributes:
                    attributes["NORMAL"] = normal
        meshes.append(mesh)
        document["nodes"][node]["mesh"] = len(meshes) - 1
    document.setdefault("buffers", []).append({"byteLength": len(blob)})
    buffers.append(blob)


def _updated(asset: MeshAsset, V: NDArray[np.float64] | None) -> tuple[dict[str, Any], list[bytes]]:
    """The document and buffers with the positions ``V`` (None: as they are) and their normals."""
    gltf: GltfData = asset.data
    if V is None:
        return copy.deepcopy(gltf.document), list(gltf.buffers)
    document = copy.deepcopy(gltf.document)
    buffers = [bytearray(b) for b in gltf.buffers]
    for k, pos in enumerate(gltf.positions):
        target = accessor_array(document, buffers, pos, "the asset")
        local = _local(V[gltf.offsets[k]:gltf.offsets[k] + len(target)], gltf.transforms[k],
                       f"POSITION accessor {pos}")
        target[...] = local
        acc = document["accessors"][pos]
        acc["min"] = [float(x) for x in local.min(axis=0)]
        acc["max"] = [float(x) for x in local.max(axis=0)]
    normals = _new_normals(asset, gltf, V, buffers)
    if gltf.instances:
        _separate_instances(document, buffers, gltf, V, normals)
    return document, [bytes(b) for b in buffers]

def write_glb_asset(path: Path, asset: MeshAsset, V: NDArray[np.float64] | None) -> list[Path]:
    """Write a glTF asset as GLB (buffers merged into the binary chunk; data URIs kept); image files it names are
    written beside it. The files written, the GLB first."""
    return _write_gltf(path, asset, V, binary=True)


def write_gltf_asset(path: Path, asset: MeshAsset, V: NDArray[np.float64] | None) -> list[Path]:
    """Write a glTF asset as glTF, its external buffers beside it as ``NAME.bin``, ``NAME_1.bin``, ... (data URIs
    kept); image files it names are written beside it. The files written, the glTF first."""
    return _write_gltf(path, asset, V, binary=False)


def _write_gltf(path: Path, asset: MeshAsset, V: NDArray[np.float64] | None, *, binary: bool) -> list[Path]:
    """Write a glTF asset as GLB (``binary``) or glTF (see :func:`write_glb_asset`, :func:`write_gltf_asset`)."""
    from arap.io.atomic import write_atomic

    gltf: GltfData = asset.data
    document, buffers = _updated(asset, V)
    written: list[Path] = []
    extra: list[tuple[Path, bytes]] = []
    specs = document.get("buffers", [])
    if binary:
        merged = bytearray()
        base: list[int] = []
        for i, content in enumerate(buffers):
            uri = specs[i].get("uri")
            if uri is not None and str(uri).startswith("data:"):
                base.append(-1)  # an embedded data URI stays where it is
                continue
            merged += b"\0" * (-len(merged) % 16)
            base.append(len(merged))
            merged += content
        moved = [i for i, b in enumerate(base) if b >= 0]
        if moved:
            renumber = {old: (0 if base[old] >= 0 else None) for old in range(len(buffers))}
            kept = [i for i in range(len(buffers)) if base[i] < 0]
            for j, old in enumerate(kept, start=1):
                renumber[old] = j
            for view in document.get("bufferViews", []):
                old = int(view.get("buffer", 0))
                if base[old] > 0:
                    view["byteOffset"] = int(view.get("byteOffset", 0)) + base[old]
                view["buffer"] = renumber[old]
            document["buffers"] = [{"byteLength": len(merged)}] + [specs[i] for i in kept]
        data = glb_bytes(document, bytes(merged) if moved else None)
    else:
        external = [i for i, s in enumerate(specs) if s.get("uri") is None or not str(s["uri"]).startswith("data:")]
        for i, spec in enumerate(specs):
            if i in external:
                name = f"{path.stem}.bin" if len(external) == 1 else f"{path.stem}_{external.index(i)}.bin"
                spec["uri"] = urllib.parse.quote(name)
                extra.append((path.parent / name, buffers[i]))
            else:
                spec["uri"] = "data:application/octet-stream;base64," + base64.b64encode(buffers[i]).decode("ascii")
        data = json.dumps(document, indent=1, ensure_ascii=False).encode("utf-8")
    write_atomic(path, data)
    written.append(path)
    for extra_path, content in extra:
        write_atomic(extra_path, content)
        written.append(extra_path)
    for i, image in enumerate(document.get("images", [])):
        if i in gltf.images:
            write_beside(path.parent, urllib.parse.unquote(str(image["uri"])), gltf.images[i], written)
    return written


def geometry_glb(V: NDArray[np.float64], F: NDArray[np.int64], *, binary: bool = True) -> bytes:
    """A minimal glTF of positions (float32) and triangles (uint32): one mesh, one node, one scene; as GLB, or as
    glTF JSON with the buffer in a data URI."""
    positions = np.ascontiguousarray(V, dtype="<f4")
    indices = np.ascontiguousarray(F, dtype="<u4")
    blob = positions.tobytes() + indices.tobytes()
    document: dict[str, Any] = {
        "asset": {"version": "2.0", "generator": "arap"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 4}]}],
        "accessors": [
            {"bufferView": 0, "componentType": FLOAT, "count": len(positions), "type": "VEC3",
             "min": [float(x) for x in positions.min(axis=0)] if len(positions) else [0.0] * 3,
             "max": [float(x) for x in positions.max(axis=0)] if len(positions) else [0.0] * 3},
            {"bufferView": 1, "componentType": UINT, "count": indices.size, "type": "SCALAR"},
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": positions.nbytes, "target": 34962},
            {"buffer": 0, "byteOffset": positions.nbytes, "byteLength": indices.nbytes, "target": 34963},
        ],
        "buffers": [{"byteLength": len(blob)}],
    }
    if binary:
        return glb_bytes(document, blob)
    document["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(blob).decode("ascii")
    return json.dumps(document, indent=1).encode("utf-8")
