"""Pictures in the studio: the puppet warp (:mod:`arap.puppet`) of a PNG, JPEG or WebP opened in the page.

An opened picture becomes a flat textured mesh: its opaque part outlined and meshed (:func:`arap.image_mesh`), at
``(x, h − y, 0)`` in pixels (y up, as the studio draws), textured with the picture itself. It is loaded through the
same path as a textured GLB (:func:`arap.server.appearance.look_from_upload`), so the page draws it, picks on it and
exports it as any textured model. The session then deforms it in its plane with the element energy (one 2×2
rotation per triangle), whatever the energy chosen for surfaces; handles dragged off the plane are put back on it.
**Export PNG** gives the warped picture, drawn at the picture's resolution (:func:`arap.puppet.raster.draw_textured`).
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

import arap.io.formats as formats
from arap.errors import ArapError, ConstraintError
from arap.method.points import PointConstraints
from arap.puppet.rings import PinRings
from arap.server.appearance import Look, look_from_upload
from arap.server.constraints import ConstraintSet
from arap.server.errors import RequestError
from arap.server.mesh_model import MeshData
from arap.server.meshdata import load_upload

__all__ = [
    "DENSITIES",
    "PICTURE_EXTENSIONS",
    "draw_layers",
    "draw_order",
    "is_picture",
    "load_picture",
    "page_draw_order",
    "page_drawing",
    "picture_mesh",
    "pin_parts",
    "pin_rings",
    "pin_turn",
    "warped_picture_png",
]

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


DENSITIES: dict[str, int] = {"coarse": 1500, "normal": 5000, "fine": 15000}
"""The studio's mesh densities of a picture: vertices when the shape fills the picture (:func:`arap.image_mesh`'s
``density``; ``normal`` is its default)."""


def picture_mesh(picture: np.ndarray, stem: str, max_vertices: int, spacing: float | None = None,
                 density: str = "normal") -> tuple[MeshData, Look | None]:
    """The mesh and look of a picture's pixels ((h, w, 3|4) uint8), named ``stem``; ``spacing``: the mesh's edge
    length in pixels (None: that of ``density``, one of :data:`DENSITIES`).

    Raises
    ------
    RequestError
        As :func:`load_picture`.
    """
    from arap.puppet.imagemesh import image_mesh
    from arap.puppet.warp import PuppetWarp

    try:
        mesh = image_mesh(picture, spacing, density=DENSITIES[density])
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


def pin_parts(mesh: MeshData, points: PointConstraints | None) -> np.ndarray:
    """The pin each triangle of a picture's ``mesh`` belongs to (:meth:`arap.puppet.PuppetWarp.pin_parts`: the
    nearest pin to its rest centroid within its island, -1 for an island without a pin), for the point handles
    ``points`` (all -1 without any)."""
    from types import SimpleNamespace

    from arap.puppet.warp import PuppetWarp

    F = np.asarray(mesh.F, dtype=np.int64)
    if points is None or len(points.faces) == 0:
        return np.full(len(F), -1, dtype=np.int64)
    pins = np.einsum("kc,kcd->kd", points.barycentric, mesh.V[F[points.faces]])[:, :2]
    warp: Any = SimpleNamespace(mesh=SimpleNamespace(vertices=mesh.V[:, :2], triangles=F), faces=points.faces,
                                pins=pins)
    return PuppetWarp.pin_parts(warp)  # the same parts whatever the y axis' direction


def pin_rings(V: np.ndarray, F: np.ndarray, points: PointConstraints,
              angles: list[float | None] | tuple[float | None, ...]) -> PinRings:
    """The hidden rings (:func:`arap.puppet.rings.pin_rings`) of the pins ``points`` of a picture's mesh (rest pose
    ``V``, triangles ``F``) that hold an angle (``angles``: per pin, radians or None).

    Raises
    ------
    BadValues
        A pin that holds an angle with no ring point on the shape (too near its edge).
    """
    from arap.puppet.rings import pin_rings as rings_of
    from arap.server.session_errors import BadValues

    try:
        return rings_of(V, F, points.positions(V, np.asarray(F, dtype=np.int64)), angles)
    except ConstraintError as exc:
        raise BadValues(str(exc)) from exc


def pin_turn(V: np.ndarray, U: np.ndarray, F: np.ndarray, points: PointConstraints, k: int) -> float:
    """The angle (radians, counter-clockwise seen from +z) by which the shape ``U`` of a picture's mesh (rest pose
    ``V``) has turned the surroundings of pin ``k`` of ``points``: the best-fitting rotation of its ring's points."""
    F = np.asarray(F, dtype=np.int64)
    single = PointConstraints(points.faces[k:k + 1], points.barycentric[k:k + 1], points.weights[k:k + 1])
    rings = pin_rings(V, F, single, [0.0])
    at_rest = rings.points.positions(V, F)[:, :2] - single.positions(V, F)[0, :2]
    now = rings.points.positions(U, F)[:, :2] - single.positions(U, F)[0, :2]
    cross = float(np.sum(at_rest[:, 0] * now[:, 1] - at_rest[:, 1] * now[:, 0]))
    return float(np.arctan2(cross, float(np.sum(at_rest * now))))


def draw_order(parts: np.ndarray, depth: list[int] | np.ndarray | None) -> np.ndarray | None:
    """The triangles' drawing order for a depth per pin (later drawn over earlier; None: the mesh's order): a
    triangle takes its pin's depth (:func:`pin_parts`), 0 for a pin beyond ``depth`` or no pin, ties in the mesh's
    order.

    Example
    -------
    >>> draw_order(np.array([0, 1, -1, 0]), [2, 1]).tolist()
    [2, 1, 0, 3]
    """
    per_triangle = _triangle_depths(parts, depth)
    return None if per_triangle is None else np.argsort(per_triangle, kind="stable").astype(np.int64)


def draw_layers(parts: np.ndarray, depth: list[int] | np.ndarray | None) -> np.ndarray | None:
    """How many triangles :func:`draw_order` puts at each depth, back to front (runs of its order that share a
    depth; None where it is None).

    Example
    -------
    >>> draw_layers(np.array([0, 1, -1, 0]), [2, 1]).tolist()
    [1, 1, 2]
    """
    per_triangle = _triangle_depths(parts, depth)
    return None if per_triangle is None else np.unique(per_triangle, return_counts=True)[1].astype(np.int64)


def _triangle_depths(parts: np.ndarray, depth: list[int] | np.ndarray | None) -> np.ndarray | None:
    """Each triangle's depth (:func:`draw_order`), or None without depths."""
    if depth is None or len(depth) == 0:
        return None
    d = np.zeros(len(parts) and int(parts.max()) + 2, dtype=np.float64)
    given = np.asarray(depth, dtype=np.float64)[: len(d) - 1]
    d[: len(given)] = given
    return d[parts]  # -1 (no pin) reads the last entry, 0


class _DrawnSession(Protocol):
    """What :func:`page_draw_order` reads of a studio session (:class:`arap.server.session.Session`)."""

    @property
    def mesh(self) -> MeshData | None: ...

    @property
    def look(self) -> Look | None: ...

    @property
    def pin_depth(self) -> list[int]: ...

    @property
    def constraints(self) -> ConstraintSet: ...


def page_draw_order(session: _DrawnSession) -> list[int] | None:
    """The order in which the page draws the triangles of a picture's textured mesh (its look's render triangles,
    :class:`arap.server.render_mesh.Look`) for the session's pin depths (:func:`draw_order`; later over earlier), or
    None: not a picture, no depths, or all equal (the mesh's order)."""
    drawing = page_drawing(session)
    return None if drawing is None else drawing[0]


def page_drawing(session: _DrawnSession) -> tuple[list[int], list[int]] | None:
    """:func:`page_draw_order` and the number of its triangles at each depth, back to front (:func:`draw_layers`:
    the page draws each layer's wireframe over that layer alone), or None where the order is None."""
    mesh, look = session.mesh, session.look
    depth = session.pin_depth
    if mesh is None or mesh.picture is None or not any(depth):
        return None
    parts = pin_parts(mesh, session.constraints.points)
    order, layers = draw_order(parts, depth), draw_layers(parts, depth)
    if order is None or layers is None:
        return None
    drawing = (order.tolist(), layers.tolist())
    if look is None or look.render_faces is None or look.render_map is None:
        return drawing
    drawn = look.render_map[look.render_faces].astype(np.int64)
    F = np.asarray(mesh.F, dtype=np.int64)
    if drawn.shape != F.shape or not np.array_equal(np.sort(drawn, axis=1), np.sort(F, axis=1)):
        return None  # (a picture's render triangles are its mesh's, in its order)
    return drawing


def warped_picture_png(mesh: MeshData, U: np.ndarray, points: PointConstraints | None = None,
                       depth: list[int] | None = None) -> bytes:
    """The picture of ``mesh`` drawn on its deformed positions ``U`` (the studio's ``(x, h − y, 0)``), at the picture's
    size, as PNG bytes; ``depth``: a depth per pin of ``points`` (the point handles), whose parts are drawn in that
    order where they overlap (:func:`draw_order`)."""
    import io

    from PIL import Image

    from arap.puppet.raster import draw_textured

    assert mesh.picture is not None
    h, w = mesh.picture.shape[:2]
    rest = np.column_stack([mesh.V[:, 0], h - mesh.V[:, 1]])
    now = np.column_stack([U[:, 0], h - U[:, 1]])
    order = draw_order(pin_parts(mesh, points), depth) if depth else None
    pixels = draw_textured(mesh.picture, rest, now, np.asarray(mesh.F, dtype=np.int64), (w, h), (0, 0), order)
    out = io.BytesIO()
    Image.fromarray(pixels, "RGBA").save(out, format="PNG")
    return out.getvalue()
