"""Pictures in the studio: the puppet warp (:mod:`arap.puppet`) of a PNG, JPEG or WebP opened in the page.

An opened picture becomes a flat textured mesh: its opaque part outlined and meshed (:func:`arap.image_mesh`), at
``(x, h − y, 0)`` in pixels (y up, as the studio draws), textured with the picture itself. It is loaded through the
same path as a textured GLB (:func:`arap.server.render_mesh.look_from_upload`), so the page draws it, picks on it and
exports it as any textured model. The session then deforms it in its plane with the element energy (one 2×2
rotation per triangle), whatever the energy chosen for surfaces; handles dragged off the plane are put back on it.
**Export PNG** gives the warped picture, drawn at the picture's resolution (:func:`arap.puppet.raster.draw_textured`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

import arap.io.formats as formats
from arap.errors import ArapError
from arap.server.errors import RequestError
from arap.server.mesh_model import MeshData
from arap.server.meshdata import load_upload
from arap.server.render_mesh import Look, look_from_upload

__all__ = ["PICTURE_EXTENSIONS", "is_picture", "load_picture", "picture_mesh", "warped_picture_png"]

PICTURE_EXTENSIONS: tuple[str, ...] = formats.suffixes("picture")
"""Pictures the studio opens for the puppet warp."""


def is_picture(filename: str) -> bool:
    """Whether an uploaded file name is a picture (by its extension)."""
    return filename.lower().endswith(PICTURE_EXTENSIONS)


def load_picture(data: bytes | memoryview, filename: str, max_vertices: int) -> tuple[MeshData, Look | None]:
    """The mesh and look of an uploaded picture.

    Raises
    ------
    RequestError
        ``bad_mesh`` for a picture that cannot be read or has no opaque part; ``too_large`` beyond the picture limit
        (:data:`arap.puppet.picture.MAX_PIXELS`) or ``max_vertices``.
    """
    from arap.puppet.picture import decode_picture

    stem = filename.rsplit(".", 1)[0] or "picture"
    try:
        picture = decode_picture(bytes(data), filename)
    except ArapError as exc:
        raise RequestError("bad_mesh", str(exc)) from exc
    return picture_mesh(picture, stem, max_vertices)


def picture_mesh(picture: np.ndarray, stem: str, max_vertices: int,
                 spacing: float | None = None) -> tuple[MeshData, Look | None]:
    """The mesh and look of a picture's pixels ((h, w, 3|4) uint8), named ``stem``; ``spacing``: the mesh's edge
    length in pixels (None: :func:`arap.image_mesh`'s default density).

    Raises
    ------
    RequestError
        As :func:`load_picture`.
    """
    from arap.puppet.imagemesh import image_mesh
    from arap.puppet.warp import PuppetWarp

    try:
        mesh = image_mesh(picture, spacing)
        if len(mesh.vertices) > max_vertices:
            raise RequestError("too_large", f"the picture's mesh has {len(mesh.vertices):,} vertices, more than this "
                                            f"studio's {max_vertices:,}")
        warp = PuppetWarp.__new__(PuppetWarp)  # only its textured-mesh export, for the picture's mesh
        warp.picture, warp.mesh = picture, mesh
        glb = warp.textured_mesh(mesh.vertices).export(file_type="glb")
    except RequestError:
        raise
    except ArapError as exc:
        raise RequestError("bad_mesh", str(exc)) from exc
    name = f"{stem}.glb"
    loaded = load_upload(glb, name, max_vertices)
    look = look_from_upload(glb, name, loaded, max_vertices)
    data_mesh = MeshData(loaded.name, loaded.V, loaded.F, [*loaded.report, _note(picture, mesh)], loaded.vertex_map,
                         picture=_frozen(picture))
    return data_mesh, look


def _note(picture: np.ndarray, mesh: Any) -> str:
    h, w = picture.shape[:2]
    return (f"a {w}×{h} picture, meshed with {len(mesh.vertices):,} vertices: it bends in its plane (one rotation per "
            "triangle); place point handles on it and drag them")


def _frozen(a: np.ndarray) -> np.ndarray:
    out = np.array(a)
    out.setflags(write=False)
    return out


def warped_picture_png(mesh: MeshData, U: np.ndarray) -> bytes:
    """The picture of ``mesh`` drawn on its deformed positions ``U`` (the studio's ``(x, h − y, 0)``), at the picture's
    size, as PNG bytes."""
    import io

    from PIL import Image

    from arap.puppet.raster import draw_textured

    assert mesh.picture is not None
    h, w = mesh.picture.shape[:2]
    rest = np.column_stack([mesh.V[:, 0], h - mesh.V[:, 1]])
    now = np.column_stack([U[:, 0], h - U[:, 1]])
    pixels = draw_textured(mesh.picture, rest, now, np.asarray(mesh.F, dtype=np.int64), (w, h), (0, 0), None)
    out = io.BytesIO()
    Image.fromarray(pixels, "RGBA").save(out, format="PNG")
    return out.getvalue()
