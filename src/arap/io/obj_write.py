"""OBJ files written back from an asset read by :mod:`arap.io.obj_asset`: the ``v`` lines in their numbering with
new positions, ``vt`` as read, ``vn`` recomputed for the new shape, the polygons with their ``usemtl``/``g``/``o``/
``s`` runs, then the statements the reader did not interpret (``l``, ``p``, curves); the MTL files and the textures
they name are written beside it."""

from __future__ import annotations

from pathlib import Path
from typing import cast

import numpy as np
from numpy.typing import NDArray

from arap.io.assets import MeshAsset, fan, group_normals, weld_rows, write_beside
from arap.io.obj_asset import ObjData

__all__ = ["obj_files", "obj_text", "write_obj_asset"]


def _rows(keyword: str, A: NDArray[np.float64]) -> str:
    if not len(A):
        return ""
    if not np.isnan(A).any():
        return ((keyword + " %r" * A.shape[1] + "\n") * len(A)) % tuple(A.ravel().tolist())
    out = []
    for row in A.tolist():
        out.append(" ".join([keyword, *(repr(x) for x in row if x == x)]) + "\n")
    return "".join(out)


def obj_text(asset: MeshAsset, V: NDArray[np.float64] | None, mtl_names: list[str]) -> str:
    """The OBJ text of an asset with positions ``V`` (None: its own) and its normals recomputed for them."""
    obj: ObjData = asset.data
    positions = asset.vertices if V is None else V
    normals, corner_normals = obj.normals, obj.corner_normals
    if V is not None and len(obj.normals) and (corner_normals >= 0).any():
        keys = np.stack([obj.corner_vertices, corner_normals], axis=1)
        group, first = weld_rows(keys)
        group[corner_normals < 0] = -1
        new, valid = group_normals(positions, asset.faces, fan(obj.face_sizes, group), len(first))
        old = obj.normals[corner_normals[first]]
        normals = np.where(valid[:, None], new, old)
        keep = corner_normals[first] >= 0
        renumber = np.cumsum(keep) - 1
        normals = normals[keep]
        corner_normals = np.where(corner_normals >= 0, renumber[group], -1)
    parts = ["# written by arap\n"]
    parts += [f"mtllib {name}\n" for name in mtl_names]
    parts.append(_rows("v", np.concatenate([positions, obj.vertex_extra], axis=1)))
    parts.append(_rows("vt", obj.texcoords))
    parts.append(_rows("vn", normals))
    names = {"o": obj.objects, "g": asset.groups, "usemtl": asset.materials, "s": obj.smoothing}
    columns = {"o": obj.polygon_objects, "g": obj.polygon_groups, "usemtl": obj.polygon_materials,
               "s": obj.polygon_smoothing}
    previous = {key: -1 for key in columns}
    ends = np.cumsum(obj.face_sizes)
    cv = (obj.corner_vertices + 1).tolist()
    ct = (obj.corner_texcoords + 1).tolist()
    cn = (corner_normals + 1).tolist()
    start = 0
    changes = np.zeros(len(obj.face_sizes), dtype=bool)
    for col in columns.values():
        changes[1:] |= col[1:] != col[:-1]
    changes[0] = True
    lines: list[str] = []
    for p, end in enumerate(ends.tolist()):
        if changes[p]:
            for key, col in columns.items():
                value = int(col[p])
                if value != previous[key]:
                    lines.append(f"{key} {names[key][value]}\n" if value >= 0 else
                                 ("s off\n" if key == "s" else f"{key}\n"))
                    previous[key] = value
        corners = []
        for c in range(start, end):
            t, n = ct[c], cn[c]
            if n:
                corners.append(f"{cv[c]}/{t or ''}/{n}")
            elif t:
                corners.append(f"{cv[c]}/{t}")
            else:
                corners.append(str(cv[c]))
        lines.append("f " + " ".join(corners) + "\n")
        start = end
    parts.append("".join(lines))
    parts += [s + "\n" for s in obj.statements]
    return "".join(parts)


def write_obj_asset(path: Path, asset: MeshAsset, V: NDArray[np.float64] | None) -> list[Path]:
    """Write an OBJ, its MTL files (``NAME.mtl``, ``NAME_2.mtl``, ...) and the textures they name beside it."""
    from arap.io.atomic import write_atomic

    obj: ObjData = asset.data
    mtl_names: list[str] = []
    mtl_out: list[tuple[Path, bytes]] = []
    for k, lib in enumerate(obj.mtllibs):
        content = obj.mtl_files.get(lib)
        if content is None:
            mtl_names.append(lib)  # not read: the reference is kept as it was
            continue
        name = f"{path.stem}.mtl" if k == 0 else f"{path.stem}_{k + 1}.mtl"
        mtl_names.append(name)
        mtl_out.append((path.parent / name, content))
    text = obj_text(asset, V, mtl_names)
    written: list[Path] = []
    write_atomic(path, text.encode("utf-8"))
    written.append(path)
    for mtl_path, content in mtl_out:
        write_atomic(mtl_path, content)
        written.append(mtl_path)
    for ref, image in asset.textures.items():
        write_beside(path.parent, ref, image, written)
    return written


_IMAGE_EXTENSIONS = ((b"\x89PNG\r\n\x1a\n", ".png"), (b"\xff\xd8\xff", ".jpg"), (b"RIFF", ".webp"))


def _file_stem(text: str, fallback: str) -> str:
    """A file name stem made of ``text``'s letters, digits, ``-`` and ``_`` (others become ``_``)."""
    stem = "".join(c if c.isalnum() or c in "-_" else "_" for c in text.rsplit("/", 1)[-1].rsplit(".", 1)[0])
    return stem.strip("_") or fallback


def _gltf_materials(asset: MeshAsset) -> list[tuple[tuple[float, ...] | None, str | None]]:
    """For each material of a glTF asset, its base colour factor (None: white) and the name under which
    :attr:`MeshAsset.textures` holds its base-colour image (None: none)."""
    import urllib.parse

    document = getattr(asset.data, "document", {})
    images = document.get("images", [])
    names: list[str] = []
    for i, image in enumerate(images):  # the names the reader gave the images (arap.io.gltf_asset)
        uri = str(image.get("uri", ""))
        name = str(image.get("name") or (urllib.parse.unquote(uri) if uri and not uri.startswith("data:")
                                         else f"image{i}"))
        names.append(f"image{i}" if name in names else name)
    out: list[tuple[tuple[float, ...] | None, str | None]] = []
    for material in document.get("materials", []):
        pbr = material.get("pbrMetallicRoughness", {}) if isinstance(material, dict) else {}
        factor = pbr.get("baseColorFactor")
        colour = tuple(float(x) for x in factor[:3]) if isinstance(factor, list) and len(factor) >= 3 else None
        texture = None
        try:
            source = int(document["textures"][int(pbr["baseColorTexture"]["index"])]["source"])
            texture = names[source]
        except (IndexError, KeyError, TypeError, ValueError):
            pass
        out.append((colour, texture))
    return out


def obj_files(asset: MeshAsset, V: NDArray[np.float64] | None, stem: str) -> dict[str, bytes]:
    """An asset of any format as an OBJ file, its MTL file and its texture images, by file name (the OBJ first):
    the positions ``V`` (file numbering; None: its own), the texture coordinates per corner (glTF's ``v``, counted
    down from the image's top, turned into OBJ's, counted up), the materials by name with their colour and
    base-colour texture (``map_Kd``), the groups.

    An OBJ asset is written as :func:`write_obj_asset` writes it (its own MTL files and textures).
    """
    import tempfile

    positions = asset.vertices if V is None else np.asarray(V, dtype=np.float64)
    if asset.format == "obj":
        with tempfile.TemporaryDirectory(prefix="arap-obj-") as folder:
            written = write_obj_asset(Path(folder) / f"{stem}.obj", asset, positions)
            return {p.relative_to(folder).as_posix(): p.read_bytes() for p in written}
    gltf = asset.format in ("glb", "gltf")
    materials = list(asset.materials)
    face_materials = np.asarray(asset.face_materials, dtype=np.int64) if len(asset.face_materials) == len(
        asset.faces) else np.full(len(asset.faces), -1, dtype=np.int64)
    specs: list[tuple[tuple[float, ...] | None, str | None]] = _gltf_materials(asset) if gltf else []
    if not gltf and asset.textures:  # a PLY naming a texture: one material showing it
        materials, specs = ["material0"], [(None, next(iter(asset.textures)))]
        face_materials = np.zeros(len(asset.faces), dtype=np.int64)
    files: dict[str, bytes] = {}
    image_files: dict[str, str] = {}
    for _, texture in specs:
        if texture is None or texture not in asset.textures or texture in image_files:
            continue
        blob = asset.textures[texture]
        ext = next((e for magic, e in _IMAGE_EXTENSIONS if blob.startswith(magic)), ".png")
        name = f"{_file_stem(texture, 'texture')}{ext}"
        k = 1
        while name in files or name in (f"{stem}.obj", f"{stem}.mtl"):
            k += 1
            name = f"{_file_stem(texture, 'texture')}_{k}{ext}"
        image_files[texture] = name
        files[name] = blob
    lines = ["# written by arap"]
    if materials:
        lines.append(f"mtllib {stem}.mtl")
    lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in positions.tolist()]
    corner_vt = np.full(asset.faces.shape, -1, dtype=np.int64)
    if asset.uvs is not None:
        uv = np.asarray(asset.uvs, dtype=np.float64).reshape(-1, 2).copy()
        if gltf:
            uv[:, 1] = 1.0 - uv[:, 1]
        valid = ~np.isnan(uv).any(axis=1)
        if valid.any():
            inverse, first = weld_rows(uv[valid])
            corner_vt.reshape(-1)[valid] = inverse
            lines += [f"vt {u!r} {w!r}" for u, w in uv[valid][first].tolist()]
    groups = np.asarray(asset.face_groups, dtype=np.int64) if len(asset.face_groups) == len(asset.faces) \
        else np.full(len(asset.faces), -1, dtype=np.int64)
    group, material = -1, -1
    face_rows = cast(list[list[int]], asset.faces.tolist())
    vt_rows = cast(list[list[int]], corner_vt.tolist())
    for f, (corners, vts) in enumerate(zip(face_rows, vt_rows, strict=True)):
        if groups[f] != group and groups[f] >= 0:
            group = int(groups[f])
            lines.append(f"g {asset.groups[group]}")
        if face_materials[f] != material and 0 <= face_materials[f] < len(materials):
            material = int(face_materials[f])
            lines.append(f"usemtl {materials[material]}")
        lines.append("f " + " ".join(f"{v + 1}/{t + 1}" if t >= 0 else f"{v + 1}" for v, t in
                                     zip(corners, vts, strict=True)))
    out = {f"{stem}.obj": ("\n".join(lines) + "\n").encode("utf-8")}
    if materials:
        mtl = ["# written by arap"]
        for k, name in enumerate(materials):
            colour, texture = specs[k] if k < len(specs) else (None, None)
            r, g, b = colour if colour is not None else (1.0, 1.0, 1.0)
            mtl += [f"newmtl {name}", f"Kd {r!r} {g!r} {b!r}"]
            if texture in image_files:
                mtl.append(f"map_Kd {image_files[texture]}")
            mtl.append("")
        out[f"{stem}.mtl"] = "\n".join(mtl).encode("utf-8")
    out.update(files)
    return out
