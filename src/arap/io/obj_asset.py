"""OBJ files with their attributes: ``vt``/``vn`` per corner, ``usemtl``, ``g``/``o``/``s``, ``mtllib`` with the MTL
files and the texture images they name (see :mod:`arap.io.assets`).

Vertices keep the numbering of the ``v`` lines; polygons are kept (and fan-triangulated for the solve); negative
(relative) indices are resolved when reading and written as absolute ones. Lines the reader does not interpret
(``l``, ``p``, curves) are written back after the faces; comments are not kept.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from arap.errors import MeshFormatError, MeshTooLargeError
from arap.io.assets import MeshAsset, fan, group_normals, missing_file_warning, weld_rows, write_beside
from arap.io.screening import screen

__all__ = ["ObjData", "mtl_texture_references", "parse_obj", "read_obj_asset", "write_obj_asset"]

logger = logging.getLogger(__name__)

#: MTL statements naming a texture image (the file name is the last word; options come before it).
_MAP_KEYS = {"map_ka", "map_kd", "map_ks", "map_ns", "map_d", "map_bump", "bump", "disp", "decal", "refl", "norm",
             "map_pr", "map_pm", "map_ps", "map_ke", "map_rma", "map_orm", "map_tr"}


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


def _numbers(rows: list[list[str]], width: int, what: str, label: str, lines: list[int]) -> NDArray[np.float64]:
    """Rows of number words as a float array at least ``width`` wide, NaN-padded."""
    if not rows:
        return np.zeros((0, width))
    longest = max(width, max(len(r) for r in rows))
    try:
        if all(len(r) == longest for r in rows):
            return np.array(rows, dtype=np.float64).reshape(len(rows), longest)
        out = np.full((len(rows), longest), np.nan)
        for i, r in enumerate(rows):
            out[i, :len(r)] = [float(x) for x in r]
        return out
    except ValueError:
        for i, r in enumerate(rows):
            try:
                [float(x) for x in r]
            except ValueError:
                raise MeshFormatError(f"cannot parse {label} as OBJ: line {lines[i]}: {what} {' '.join(r)!r} is not "
                                      "a list of numbers") from None
        raise


def _resolve(word: str, count: int, what: str, label: str, line: int) -> int:
    """A face index from 0 (-1: a texture coordinate or normal before the first one, which is read as none)."""
    try:
        i = int(word)
    except ValueError:
        raise MeshFormatError(f"cannot parse {label} as OBJ: line {line}: face index {word!r} is not a whole "
                              "number") from None
    if i > 0:
        return i - 1
    if i < 0 and count + i >= 0:
        return count + i
    if i == 0:
        raise MeshFormatError(f"cannot parse {label} as OBJ: line {line}: a face names {what} 0, but OBJ counts "
                              "from 1")
    if what != "vertex":
        return -1
    raise MeshFormatError(f"cannot parse {label} as OBJ: line {line}: a face names {what} {i}, but only {count:,} "
                          f"come before it")


def parse_obj(text: bytes, label: str) -> tuple[NDArray[np.float64], ObjData, list[str], list[str]]:
    """Positions and attributes of OBJ text (UTF-8).

    Returns
    -------
    V : (n, 3) float64 array
    data : ObjData
    materials, groups : list of str
        Names in the order faces first use them.
    """
    lines = text.decode("utf-8", errors="replace").splitlines()
    v_rows: list[list[str]] = []
    v_lines: list[int] = []
    vt_rows: list[list[str]] = []
    vt_lines: list[int] = []
    vn_rows: list[list[str]] = []
    vn_lines: list[int] = []
    sizes: list[int] = []
    cv: list[int] = []
    ct: list[int] = []
    cn: list[int] = []
    tables: dict[str, dict[str, int]] = {"m": {}, "g": {}, "o": {}, "s": {}}
    state: dict[str, str | None] = {"m": None, "g": None, "o": None, "s": None}
    ids: dict[str, list[int]] = {"m": [], "g": [], "o": [], "s": []}
    mtllibs: list[str] = []
    statements: list[str] = []
    pending = ""
    for number, raw in enumerate(lines, 1):
        if raw.endswith("\\"):  # a continued line
            pending += raw[:-1] + " "
            continue
        line = (pending + raw).strip()
        pending = ""
        if not line or line[0] == "#":
            continue
        split = line.split(None, 1)
        head, rest = split[0], (split[1] if len(split) > 1 else "")
        if head in ("v", "vt", "vn", "f"):
            words = rest.split("#", 1)[0].split()
            if head == "v":
                v_rows.append(words)
                v_lines.append(number)
            elif head == "vt":
                vt_rows.append(words)
                vt_lines.append(number)
            elif head == "vn":
                vn_rows.append(words)
                vn_lines.append(number)
            else:
                if len(words) < 3:
                    raise MeshFormatError(f"cannot parse {label} as OBJ: line {number}: a face needs at least 3 "
                                          f"vertices, this one has {len(words)}")
                nv, nt, nn = len(v_rows), len(vt_rows), len(vn_rows)
                for word in words:
                    parts = word.split("/")
                    cv.append(_resolve(parts[0], nv, "vertex", label, number))
                    ct.append(_resolve(parts[1], nt, "texture coordinate", label, number)
                              if len(parts) > 1 and parts[1] else -1)
                    cn.append(_resolve(parts[2], nn, "normal", label, number)
                              if len(parts) > 2 and parts[2] else -1)
                sizes.append(len(words))
                for key in "mgos":
                    name = state[key]
                    if name is None:
                        ids[key].append(-1)
                    else:
                        ids[key].append(tables[key].setdefault(name, len(tables[key])))
            continue
        rest = rest.strip()
        if head == "usemtl":
            state["m"] = rest or None
        elif head == "g":
            state["g"] = " ".join(rest.split()) or None
        elif head == "o":
            state["o"] = rest or None
        elif head == "s":
            state["s"] = None if rest.lower() in ("", "off", "0") else rest
        elif head == "mtllib":
            words = rest.split()
            several = len(words) > 1 and all(w.lower().endswith(".mtl") for w in words)
            mtllibs.extend(words if several else [rest] if rest else [])
        else:
            statements.append(line)
    short = [i for i, r in enumerate(v_rows) if len(r) < 3]
    if short:
        i = short[0]
        raise MeshFormatError(f"cannot parse {label} as OBJ: the file ends early or a line is cut (line "
                              f"{v_lines[i]}: a vertex with {len(v_rows[i])} coordinates; truncated?)")
    V_all = _numbers(v_rows, 3, "vertex", label, v_lines)
    data = ObjData(
        vertex_extra=np.ascontiguousarray(V_all[:, 3:]),
        texcoords=_numbers(vt_rows, 3, "texture coordinate", label, vt_lines)[:, :3],
        normals=_numbers(vn_rows, 3, "normal", label, vn_lines)[:, :3],
        face_sizes=np.asarray(sizes, dtype=np.int64),
        corner_vertices=np.asarray(cv, dtype=np.int64),
        corner_texcoords=np.asarray(ct, dtype=np.int64),
        corner_normals=np.asarray(cn, dtype=np.int64),
        polygon_materials=np.asarray(ids["m"], dtype=np.int64),
        polygon_groups=np.asarray(ids["g"], dtype=np.int64),
        polygon_objects=np.asarray(ids["o"], dtype=np.int64),
        polygon_smoothing=np.asarray(ids["s"], dtype=np.int64),
        objects=list(tables["o"]),
        smoothing=list(tables["s"]),
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
    return V, data, list(tables["m"]), list(tables["g"])


def mtl_texture_references(mtl: bytes) -> list[str]:
    """The texture files an MTL file names (``map_Kd``, ``bump``, ...), in order, each once."""
    out: list[str] = []
    for raw in mtl.decode("utf-8", errors="replace").splitlines():
        line = raw.strip()
        if not line or line[0] == "#":
            continue
        words = line.split()
        if words[0].lower() in _MAP_KEYS and len(words) > 1:
            ref = words[-1]
            if ref not in out:
                out.append(ref)
    return out


def _read_beside(folder: Path | None, reference: str) -> tuple[Path | None, bytes | None]:
    from arap.io.paths import read_regular_file

    if folder is None:
        return None, None
    path = folder / reference.replace("\\", "/")
    try:
        return path, read_regular_file(path)
    except OSError:
        return path, None


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
        mtl_path, mtl = _read_beside(folder, lib)
        if mtl is None:
            missing_file_warning(f"{label}: the material file {lib!r} cannot be read; the mesh loads without it")
            continue
        obj.mtl_files[lib] = mtl
        for ref in mtl_texture_references(mtl):
            _, image = _read_beside(mtl_path.parent if mtl_path is not None else None, ref)
            if image is None:
                missing_file_warning(f"{label}: the texture {ref!r} named in {lib!r} cannot be read; its "
                                     "reference is kept")
            else:
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
