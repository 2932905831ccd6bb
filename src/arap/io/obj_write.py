"""OBJ files written back from an asset read by :mod:`arap.io.obj_asset`: the ``v`` lines in their numbering with
new positions, ``vt`` as read, ``vn`` recomputed for the new shape, the polygons with their ``usemtl``/``g``/``o``/
``s`` runs, then the statements the reader did not interpret (``l``, ``p``, curves); the MTL files and the textures
they name are written beside it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from arap.io.asset_model import MeshAsset, fan, group_normals, weld_rows, write_beside
from arap.io.obj_asset import ObjData

__all__ = ["obj_text", "write_obj_asset"]


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
