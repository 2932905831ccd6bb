"""The appearance of the studio's mesh: how the page draws a textured or coloured mesh file, and how the deformed
shape is exported with it (GLB, or the file's own format).

The solver works on the studio's mesh (:class:`~arap.server.meshdata.MeshData`, one vertex per position), but a
texture needs a vertex wherever a UV seam splits one: a *render mesh* of its own. A :class:`Look` holds what the page
needs beside the mesh, sent in one ``appearance`` message right after the ``mesh`` frame:

* the file's vertex colours, per mesh vertex (sRGB bytes);
* for a UV texture, the render mesh: per render vertex the mesh vertex it follows (its position is that vertex's in
  every ``vertices`` frame) and its UV, the render triangles, and the base-colour texture image as stored (PNG or
  JPEG, at most :data:`MAX_TEXTURE_BYTES`; a larger one is left out and a note says so).

Meshes without colours or texture have no look: nothing beyond the ``mesh`` frame is sent (the ``appearance`` frame
of a look is :func:`arap.server.replies.appearance_frame`). The look also keeps the
:class:`~arap.io.MeshAsset`, so that the deformed shape is exported as GLB with its UVs, materials and textures
(:func:`export_glb`).
"""

from __future__ import annotations

import logging
import os
import posixpath
import tempfile
import warnings
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np

from arap.errors import ArapError
from arap.io import formats, load_asset, load_asset_bytes, save_asset, save_mesh_bytes
from arap.io.assets import MeshAsset, may_have_attributes, result_trimesh, weld_rows
from arap.io.obj_write import obj_files, obj_text
from arap.server.mesh_model import EXPORT_MIME, MeshData, export_mesh

__all__ = ["BUNDLE_EXPANSION", "MAX_TEXTURE_BYTES", "Look", "build_look", "export_asset", "export_glb", "is_bundle",
           "load_bundle_upload", "look_from_path", "look_from_upload"]

logger = logging.getLogger(__name__)

MAX_TEXTURE_BYTES = 16 * 2**20
"""Largest texture image sent to the page; a larger one is left out (the mesh is drawn without it, and a note in
the ``appearance`` message says why)."""

BUNDLE_EXPANSION = 4
"""The files of an uploaded zip may hold this many times the upload limit once uncompressed (mesh text compresses
well; images hardly)."""

GLB_MIME = formats.get("glb").mime
ZIP_MIME = formats.get("zip").mime
_ASSET_EXTENSIONS = tuple(formats.get(name).suffix for name in formats.names("surface", asset=True))
"""Uploads read as textured models too (their colours and textures drawn)."""
_IMAGE_MIME = ((b"\x89PNG\r\n\x1a\n", "image/png"), (b"\xff\xd8\xff", "image/jpeg"))


def _mib(n: int) -> str:
    return f"{n / 2**20:.1f} MiB"


@dataclass(frozen=True, eq=False)
class Look:
    """What the page needs to draw a mesh as its file shows it (see the module notes).

    Attributes
    ----------
    asset : MeshAsset
        The file as read, for the GLB export.
    file_map : (n_file,) int64 array
        The mesh vertex of each file vertex (-1: dropped by repair).
    n_vertices : int
        Vertices of the mesh it belongs to.
    colors : (n_vertices, 3) uint8 array or None
        sRGB vertex colours per mesh vertex.
    render_map : (r,) uint32 array or None
        The mesh vertex each render vertex follows (None without a texture shown).
    render_uv : (r, 2) float32 array or None
        UV of each render vertex, ``v`` running down from the image's top row (glTF's convention).
    render_faces : (t, 3) uint32 array or None
        Render triangles.
    texture : bytes
        The base-colour image (PNG or JPEG as stored), empty without one.
    texture_mime : str
    notes : list of str
        What is not shown and why, one line each.
    """

    asset: MeshAsset
    file_map: np.ndarray
    n_vertices: int
    colors: np.ndarray | None = None
    render_map: np.ndarray | None = None
    render_uv: np.ndarray | None = None
    render_faces: np.ndarray | None = None
    texture: bytes = b""
    texture_mime: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def textured(self) -> bool:
        """A render mesh and its texture are shown."""
        return self.render_map is not None and bool(self.texture)

    @property
    def worth_sending(self) -> bool:
        """Something to draw or to say beyond the plain mesh."""
        return self.colors is not None or self.textured or bool(self.notes)

    def file_positions(self, U: np.ndarray) -> np.ndarray:
        """Positions of the mesh (``U``, mesh numbering) for every vertex of the file (a dropped one keeps its own)."""
        out = np.array(self.asset.vertices, dtype=np.float64)
        keep = self.file_map >= 0
        out[keep] = np.asarray(U, dtype=np.float64)[self.file_map[keep]]
        return out


# ---------------------------------------------------------------------------------------------- building
def _colors_u8(values: np.ndarray) -> np.ndarray:
    """Vertex colours of a file (any type, 3 or 4 channels) as sRGB bytes, shape (n, 3)."""
    c = np.asarray(values)[:, :3]
    if np.issubdtype(c.dtype, np.floating):
        rounded: np.ndarray = np.clip(np.nan_to_num(c) * 255.0 + 0.5, 0, 255).astype(np.uint8)
        return rounded
    if c.dtype.itemsize >= 2:
        scale = 257.0 if c.max(initial=0) > 255 else 1.0
        return np.clip(c / scale + 0.5, 0, 255).astype(np.uint8)
    return c.astype(np.uint8)


def _image_mime(blob: bytes) -> str:
    return next((mime for magic, mime in _IMAGE_MIME if blob.startswith(magic)), "")


def _base_color_name(asset: MeshAsset) -> str | None:
    """For glTF, the name under which :attr:`MeshAsset.textures` holds the base-colour image of the material that
    the most triangles use (None when there is none)."""
    if asset.format not in ("glb", "gltf") or asset.data is None or not len(asset.face_materials):
        return None
    used = Counter(int(m) for m in np.asarray(asset.face_materials) if m >= 0).most_common(1)
    document = getattr(asset.data, "document", {})
    try:
        material = document["materials"][used[0][0]]
        texture = document["textures"][material["pbrMetallicRoughness"]["baseColorTexture"]["index"]]
        i = int(texture["source"])
        image = document["images"][i]
    except (IndexError, KeyError, TypeError, ValueError):
        return None
    import urllib.parse

    uri = str(image.get("uri", ""))
    return str(image.get("name") or (urllib.parse.unquote(uri) if uri and not uri.startswith("data:") else f"image{i}"))


def _pick_texture(asset: MeshAsset, max_bytes: int, notes: list[str]) -> tuple[bytes, str]:
    """The base-colour image to show and its type, or ``(b"", "")`` (with a note when one exists but cannot be)."""
    names = [n for n, blob in asset.textures.items() if _image_mime(blob)]
    if not names:
        if asset.textures:
            notes.append("the texture is not a PNG or JPEG image; the model is shown without it")
        return b"", ""
    wanted = _base_color_name(asset) if asset.format != "obj" else _diffuse_name(asset, names)
    name = wanted if wanted in names else names[0]
    blob = asset.textures[name]
    if len(blob) > max_bytes:
        notes.append(f"the texture {name!r} is {_mib(len(blob))}, more than the {_mib(max_bytes)} the studio shows; "
                     "the model is shown without it (a GLB export still keeps it)")
        return b"", ""
    if len(names) > 1:
        notes.append(f"the model has {len(names)} textures; only {name!r} is shown")
    return blob, _image_mime(blob)


def build_look(asset: MeshAsset, mesh: MeshData, max_texture_bytes: int = MAX_TEXTURE_BYTES,
               notes: list[str] | None = None) -> Look | None:
    """The look of ``mesh`` read from ``asset`` (the same file), or None when it has neither colours nor a texture
    nor anything to say.

    The file's vertices are numbered as :attr:`MeshData.vertex_map` numbers them (both read the file's vertices in
    order); a file whose vertex count does not match is shown plain.

    Parameters
    ----------
    notes : list of str or None
        What loading already has to say (files named but missing); what is not shown is added.
    """
    n_file = len(asset.vertices)
    if mesh.vertex_map is not None:
        file_map = np.asarray(mesh.vertex_map, dtype=np.int64)
    else:
        file_map = np.arange(mesh.n_vertices, dtype=np.int64)
    if len(file_map) != n_file:
        logger.warning("%s: the textured reading has %d vertices, the mesh %d; shown without its texture",
                       mesh.name, n_file, len(file_map))
        return None
    notes = list(notes or [])
    colors = None
    if asset.vertex_colors is not None and asset.vertex_colors.ndim == 2 and asset.vertex_colors.shape[1] >= 3:
        colors = np.full((mesh.n_vertices, 3), 200, dtype=np.uint8)
        keep = np.flatnonzero(file_map >= 0)[::-1]  # reversed: the first copy of a welded vertex is written last
        colors[file_map[keep]] = _colors_u8(asset.vertex_colors)[keep]
    render_map = render_uv = render_faces = None
    texture, mime = b"", ""
    if asset.uvs is not None and len(asset.faces):
        texture, mime = _pick_texture(asset, max_texture_bytes, notes)
        if texture:
            corners = file_map[asset.faces]  # (m, 3) mesh vertices
            keep_faces = (corners >= 0).all(axis=1)
            corners = corners[keep_faces].reshape(-1)
            uv = np.asarray(asset.uvs, dtype=np.float64)[keep_faces].reshape(-1, 2)
            inverse, first = weld_rows(np.concatenate([corners[:, None].astype(np.float64), uv], axis=1))
            render_map = corners[first].astype(np.uint32)
            render_uv = uv[first].astype(np.float32)
            if asset.format not in ("glb", "gltf"):  # OBJ and PLY count v up from the image's bottom row
                render_uv[:, 1] = 1.0 - render_uv[:, 1]
            render_faces = inverse.reshape(-1, 3).astype(np.uint32)
    elif asset.textures:
        notes.append("the model has a texture but no texture coordinates; it is shown without it")
    if texture:
        notes.extend(n for n in _material_notes(asset) if n not in notes)
    look = Look(asset, file_map, mesh.n_vertices, colors, render_map, render_uv, render_faces, texture, mime, notes)
    return look if look.worth_sending else None


def _quietly(fn: Any, *args: Any, **kwargs: Any) -> Any:
    """``fn(...)`` with the readers' missing-file warnings silenced (they are logged)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return fn(*args, **kwargs)


def _noted(notes: list[str], label: str, fn: Any, *args: Any, **kwargs: Any) -> Any:
    """``fn(...)``, the readers' warnings (a file named but missing or refused, instances made separate parts) added
    to ``notes``, one line each, without the file's name in front (the page names the mesh)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UserWarning)
        try:
            return fn(*args, **kwargs)
        finally:
            for w in caught:
                text = str(w.message)
                for prefix in (f"{label}: ", f"cannot read {label} as glTF: "):
                    text = text.removeprefix(prefix)
                if issubclass(w.category, UserWarning) and text not in notes:
                    notes.append(text)


def _material_notes(asset: MeshAsset) -> list[str]:
    """What the page does not show of the materials: glTF material extensions and textures beside the base colour
    (normal, emissive, occlusion maps), MTL texture maps beside ``map_Kd``."""
    notes: list[str] = []
    if asset.format in ("glb", "gltf") and asset.data is not None:
        document = getattr(asset.data, "document", {})
        used = [str(e) for e in document.get("extensionsUsed", []) if str(e).startswith(("KHR_materials",
                                                                                              "KHR_texture"))]
        maps = sorted({key for m in document.get("materials", []) if isinstance(m, dict)
                       for key in ("normalTexture", "occlusionTexture", "emissiveTexture") if key in m})
        if used:
            notes.append(f"the material features {', '.join(used)} are not shown")
        if maps:
            notes.append(f"only the base colour is drawn ({', '.join(maps)} not shown)")
    elif asset.format == "obj" and asset.data is not None:
        from arap.io.obj_asset import mtl_texture_references

        other = [ref for mtl in asset.data.mtl_files.values() for ref in mtl_texture_references(mtl)
                 if ref in asset.textures and not _is_diffuse_map(mtl, ref)]
        if other:
            notes.append(f"only the diffuse texture (map_Kd) is drawn ({', '.join(dict.fromkeys(other))} not shown)")
    return notes


def _diffuse_name(asset: MeshAsset, names: list[str]) -> str | None:
    """For OBJ, the first of the texture images ``names`` that an MTL file names in a ``map_Kd`` statement."""
    mtls = list(getattr(asset.data, "mtl_files", {}).values())
    return next((n for n in names if any(_is_diffuse_map(mtl, n) for mtl in mtls)), None)


def _is_diffuse_map(mtl: bytes, ref: str) -> bool:
    """Whether an MTL file names ``ref`` in a ``map_Kd`` statement."""
    from arap.io.obj_asset import map_file_name

    for raw in mtl.decode("utf-8", errors="replace").splitlines():
        words = raw.strip().split(None, 1)
        if len(words) == 2 and words[0].lower() == "map_kd" and map_file_name(words[1]) == ref:
            return True
    return False


def look_from_path(spec: str | os.PathLike[str] | MeshData | None, mesh: MeshData,
                   max_texture_bytes: int = MAX_TEXTURE_BYTES) -> Look | None:
    """The look of the default mesh when it is an OBJ, PLY, glTF or GLB file with colours or a texture."""
    if spec is None or isinstance(spec, MeshData):
        return None
    path = Path(spec)
    if path.suffix.lower() not in _ASSET_EXTENSIONS or not path.is_file():
        return None
    notes: list[str] = []
    try:
        asset = _noted(notes, str(path), load_asset, path)
    except (ArapError, OSError, ValueError) as exc:
        logger.warning("%s: shown without its texture or colours: %s", path, exc)
        return None
    return build_look(asset, mesh, max_texture_bytes, notes)


def look_from_upload(data: bytes | memoryview, filename: str, mesh: MeshData, max_vertices: int | None = None,
                     max_texture_bytes: int = MAX_TEXTURE_BYTES, folder: Path | None = None) -> Look | None:
    """The look of an uploaded file already loaded as ``mesh`` (None for a plain one with nothing to say).

    Parameters
    ----------
    folder : Path or None
        The folder of its unpacked bundle (:func:`load_bundle_upload`), where the files it names are read; None for
        a file uploaded alone: a note then says what it names and how to bring it.
    """
    ext = ("." + filename.rsplit(".", 1)[-1].lower()) if "." in filename else ""
    if ext not in _ASSET_EXTENSIONS:
        return None
    blob = bytes(data)
    if folder is None and not may_have_attributes(blob, ext):  # nothing worth a second, attribute-keeping read
        return None
    notes: list[str] = []
    label = f"{mesh.name}{ext}"
    try:
        asset = _noted(notes, label, load_asset_bytes, blob, ext[1:], name=label, folder=folder,
                       max_vertices=max_vertices)
    except (ArapError, OSError, ValueError) as exc:
        logger.info("%s: shown without its texture or colours: %s", label, exc)
        return None
    if notes and folder is None:
        notes.append("open the mesh file together with the files it names (select them all, drop them together, or "
                     "open a zip of them)")
    return build_look(asset, mesh, max_texture_bytes, notes)


def is_bundle(filename: str) -> bool:
    """Whether an uploaded file name is a zip of a mesh file and the files it names."""
    return formats.find(filename, "bundle") is not None


def load_bundle_upload(data: bytes | memoryview, filename: str, max_vertices: int, max_bytes: int,
                       max_texture_bytes: int = MAX_TEXTURE_BYTES) -> tuple[MeshData, Look | None]:
    """The mesh and look of an uploaded zip holding a mesh file and the files it names (MTL files, textures, glTF
    buffers and images): what the mesh file names is read among the files of the zip only, by the rules of
    :func:`arap.io.paths.read_reference` (a name outside it is missing: a note names it).

    Parameters
    ----------
    max_bytes : int
        Largest total size of the zip's files once uncompressed (:func:`arap.io.assets.read_bundle`).

    Raises
    ------
    RequestError
        ``bad_mesh`` for a zip that is refused (:func:`arap.io.assets.read_bundle`), that holds no mesh file or
        several, or whose mesh file cannot be read; ``too_large`` for too many vertices.
    """
    from arap.io.assets import bundle_mesh_name, read_bundle, unpacked_bundle
    from arap.server.errors import RequestError
    from arap.server.meshdata import load_upload

    try:
        files = read_bundle(bytes(data), max_bytes=max_bytes, label=filename)
        main = bundle_mesh_name(files, filename)
        with unpacked_bundle(files) as folder:
            base = posixpath.basename(main)
            mesh = load_upload(files[main], base, max_vertices, folder=folder / posixpath.dirname(main))
            look = look_from_upload(files[main], base, mesh, max_vertices, max_texture_bytes,
                                    folder=folder / posixpath.dirname(main))
    except ArapError as exc:
        raise RequestError("bad_mesh", str(exc)) from exc
    if look is not None:
        look.asset.source = None
    return mesh, look


# ---------------------------------------------------------------------------------------------- export
def _name_material(mesh: Any, asset: MeshAsset) -> None:
    """Give a textured ``trimesh`` mesh of ``asset`` the name of the material most of its triangles use (a PBR
    material: its name is written in GLB)."""
    import trimesh

    used = np.asarray(asset.face_materials)
    used = used[(used >= 0) & (used < len(asset.materials))] if len(used) == len(asset.faces) else used[:0]
    if not len(used) or not isinstance(mesh.visual, trimesh.visual.TextureVisuals):
        return
    image = getattr(mesh.visual.material, "image", None)
    # (trimesh's material constructors are untyped, and it types a texture's material as the SimpleMaterial its
    # constructor makes, though any Material is one)
    pbr_material = cast(Any, trimesh.visual.material.PBRMaterial)
    mesh.visual.material = pbr_material(name=asset.materials[int(np.bincount(used).argmax())], baseColorTexture=image)


def export_glb(name: str, U: np.ndarray, F: np.ndarray, look: Look | None) -> tuple[str, str, bytes]:
    """The deformed mesh as GLB: a glTF or GLB source written back with everything it holds
    (:func:`arap.io.save_asset`), an OBJ or PLY source with its first texture and UVs (and the name of the material
    most triangles use) or its vertex colours (:func:`arap.io.assets.result_trimesh`), a plain mesh as
    geometry.

    Returns
    -------
    filename, mime, data
    """
    filename = f"{name}-deformed.glb"
    if look is None:
        return filename, GLB_MIME, save_mesh_bytes(U, F, "glb")
    positions = look.file_positions(U)
    if look.asset.format in ("glb", "gltf"):
        with tempfile.TemporaryDirectory(prefix="arap-export-") as folder:
            path = Path(folder) / "export.glb"
            _quietly(save_asset, path, look.asset, positions)
            return filename, GLB_MIME, path.read_bytes()
    mesh = result_trimesh(positions, look.asset)
    _name_material(mesh, look.asset)
    data = mesh.export(file_type="glb")
    assert isinstance(data, bytes)
    return filename, GLB_MIME, data


def _zip(files: dict[str, bytes]) -> bytes:
    """A zip archive of ``files`` (by name, in order)."""
    import io
    import zipfile

    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name, content in files.items():
            archive.writestr(name, content)
    return out.getvalue()


def export_asset(name: str, U: np.ndarray, F: np.ndarray, look: Look | None, fmt: str) -> tuple[str, str, bytes]:
    """The deformed mesh as a file of format ``fmt``: GLB as :func:`export_glb`; a PLY source as PLY keeps its
    colours and UVs; an OBJ source read from disk as OBJ its texture coordinates, normals (recomputed), groups,
    materials and its ``mtllib`` references as they were (the MTL file and textures beside the original file serve
    the download too); an uploaded OBJ source, or a glTF, GLB or PLY source, as OBJ with its MTL file and texture
    images (:func:`arap.io.obj_write.obj_files`), all in a zip (``NAME-deformed.zip``) when there is more than the
    OBJ; anything else is the geometry (:func:`arap.server.meshdata.export_mesh`).

    Returns
    -------
    filename, mime, data
    """
    if fmt == "glb":
        return export_glb(name, U, F, look)
    if look is None or (look.asset.format != fmt and fmt != "obj"):
        return export_mesh(name, U, F, fmt)
    positions = look.file_positions(U)
    if fmt == "obj" and (look.asset.format != "obj" or look.asset.source is None):
        files = obj_files(look.asset, positions, f"{name}-deformed")
        if len(files) == 1:
            return f"{name}-deformed.obj", EXPORT_MIME["obj"], next(iter(files.values()))
        return f"{name}-deformed.zip", ZIP_MIME, _zip(files)
    if fmt == "obj":
        data = obj_text(look.asset, positions, list(look.asset.data.mtllibs)).encode("utf-8")
    else:
        with tempfile.TemporaryDirectory(prefix="arap-export-") as folder:
            path = Path(folder) / f"export.{fmt}"
            _quietly(save_asset, path, look.asset, positions)
            data = path.read_bytes()
    return f"{name}-deformed.{fmt}", EXPORT_MIME[fmt], data

