"""``arap.show``: a picture of a mesh or of a deformation result, without a browser. It takes what the rest of arap
takes (arrays, a mesh object, an :class:`arap.ArapResult` with its faces, a built-in name), marks the constrained
vertices in the studio's colours (anchors in red, each handle group in a colour of its own, the region of interest in
blue), and returns a :class:`~arap.render.picture.Picture` that notebooks show inline and that saves as a PNG file.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from arap.errors import ConstraintError, MeshError, OptionError
from arap.render.camera import DEFAULT_AZIMUTH, DEFAULT_ELEVATION, Camera, check_size, fit_camera
from arap.render.picture import Picture
from arap.render.raster import render_mesh

__all__ = ["BACKGROUND", "STUDIO_COLORS", "as_rgb", "role_colors", "show"]

#: The studio's role colours (web/src/viewer.js), as sRGB hex: the mesh, the vertices outside and inside a region of
#: interest, the anchors, and the handle groups in turn.
STUDIO_COLORS: dict[str, Any] = {
    "base": "#c7c9cf",
    "outside": "#8c8f94",
    "roi": "#8cbdf2",
    "fixed": "#e64c45",
    "handles": ("#ff9e1a", "#40c76b", "#a86bf5", "#fad629", "#26ccd6", "#f266ad", "#94d633", "#6685ff"),
}

#: The default background: the studio's.
BACKGROUND = "#262a31"


def as_rgb(value: Any, name: str = "colour") -> NDArray[np.float64]:
    """One colour as sRGB values in [0, 1], shape (3,).

    Parameters
    ----------
    value : str or sequence of 3 numbers
        ``"#rrggbb"`` or ``"#rgb"``; floats from 0 to 1; or integers from 0 to 255.
    name : str
        What the colour is, for messages.

    Raises
    ------
    OptionError
        Anything else.

    Example
    -------
    >>> as_rgb("#ff8000").round(3).tolist(), as_rgb((0, 0, 255)).tolist(), as_rgb([0.5, 0.5, 0.5]).tolist()
    ([1.0, 0.502, 0.0], [0.0, 0.0, 1.0], [0.5, 0.5, 0.5])
    """
    if isinstance(value, str):
        text = value.strip().removeprefix("#")
        if len(text) == 3:
            text = "".join(c + c for c in text)
        try:
            if len(text) != 6:
                raise ValueError
            return np.array([int(text[k:k + 2], 16) for k in (0, 2, 4)], dtype=np.float64) / 255.0
        except ValueError:
            raise OptionError(f"{name} must be '#rrggbb', '#rgb' or three numbers, got {value!r}") from None
    return _rgb_array(value, name, one=True)


def _rgb_array(value: Any, name: str, *, one: bool, n: int = 0) -> NDArray[np.float64]:
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):
        arr = np.asarray(None)
    shapes = "(3,)" if one else f"(3,) or ({n}, 3)"
    if arr.dtype == np.bool_ or arr.dtype.kind not in "iuf" or arr.shape[-1:] != (3,) or arr.ndim > (1 if one else 2):
        raise OptionError(f"{name} must be a colour ('#rrggbb' or 3 numbers){'' if one else ' or one per vertex'}, "
                          f"an array of shape {shapes}; got {type(value).__name__} {getattr(arr, 'shape', '')}")
    if arr.ndim == 2 and len(arr) != n:
        raise OptionError(f"{name} must have one row per vertex, shape ({n}, 3); got {arr.shape}")
    if arr.dtype.kind in "iu":
        if arr.size and (arr.min() < 0 or arr.max() > 255):
            raise OptionError(f"{name}: integer colour values must be from 0 to 255")
        return arr.astype(np.float64) / 255.0
    if not np.isfinite(arr).all() or (arr.size and (arr.min() < 0 or arr.max() > 1)):
        raise OptionError(f"{name}: colour values given as floats must be from 0 to 1")
    return arr.astype(np.float64)


# ---------------------------------------------------------------------------------------------- the mesh
def _mesh_of(obj: Any, F: Any) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The vertices and faces ``show`` pictures, checked for what rendering needs (not for what a solve needs:
    a mesh with defects can be pictured)."""
    from arap.meshes.domain import boundary_faces, element_mesh_arrays
    from arap.solve.result import ArapResult

    if isinstance(obj, str) and F is None:
        from arap.meshes.shapes import BUILTIN_MESHES, builtin_mesh

        if obj in BUILTIN_MESHES or obj == "sphere" or obj.startswith("sphere:"):
            return builtin_mesh(obj)
        if os.path.exists(obj):
            from arap.io import load_mesh

            return load_mesh(obj, repair=False)
        raise MeshError(f"{obj!r} is neither a built-in mesh ({', '.join(BUILTIN_MESHES)}, sphere, sphere:N) nor a "
                        f"mesh file")
    if isinstance(obj, os.PathLike) and F is None:
        from arap.io import load_mesh

        return load_mesh(obj, repair=False)
    if isinstance(obj, ArapResult):
        if F is None:
            raise MeshError("an ArapResult holds the deformed vertices only: give the faces too, arap.show(result, F)")
        obj = obj.vertices
    V, F = element_mesh_arrays(obj, F)
    V, F = np.asarray(V), np.asarray(F)
    if V.ndim == 2 and V.shape[1] == 2 and V.dtype.kind in "iuf":  # a planar mesh: drawn in the plane z = 0
        V = np.column_stack([V, np.zeros(len(V))])
    if F.ndim == 2 and F.shape[1] == 4 and F.dtype.kind in "iu" and len(V) and V.shape[-1] == 3:
        F = boundary_faces(F, V if np.isfinite(V).all() else None)  # a solid: drawn by its boundary
    if V.dtype == object or V.dtype.kind not in "iuf" or V.ndim != 2 or V.shape[1] != 3:
        raise MeshError(f"vertices must be an (n, 3) array of numbers, got {V.dtype} {V.shape}")
    if F.size == 0 or len(V) == 0:
        raise MeshError(f"the mesh is empty ({len(V)} vertices, {len(F) if F.ndim else 0} faces): nothing to show")
    if F.ndim != 2 or F.shape[1] != 3:
        raise MeshError(f"faces must be triangles, an (m, 3) array of vertex indices; got shape {F.shape}")
    if F.dtype.kind not in "iu":
        if F.dtype.kind != "f" or not np.isfinite(F).all() or not np.array_equal(F, np.round(F)):
            raise MeshError(f"face indices must be integers, got {F.dtype}")
    V = np.ascontiguousarray(V, dtype=np.float64)
    F = np.ascontiguousarray(F, dtype=np.int64)
    lo, hi = int(F.min()), int(F.max())
    if lo < 0 or hi >= len(V):
        bad = np.flatnonzero(np.any((F < 0) | (F >= len(V)), axis=1))
        raise MeshError(f"{len(bad)} faces have vertex indices out of range [0, {len(V)}) (first: face {bad[0]} = "
                        f"{F[bad[0]].tolist()})")
    used = np.unique(F)
    if not np.isfinite(V[used]).all():
        bad = used[~np.isfinite(V[used]).all(axis=1)]
        raise MeshError(f"{len(bad)} vertices have NaN or infinite coordinates (first: vertex {bad[0]})")
    return V, F


# ---------------------------------------------------------------------------------------------- marks
def _handle_groups(handles: Any, n: int) -> list[NDArray[np.int64]]:
    """``handles=``: one list of vertex indices (one group) or a list of such lists (one group each)."""
    from arap.solve.indexing import check_index_array

    if handles is None:
        return []
    items = list(handles) if not isinstance(handles, np.ndarray) else [handles] if handles.ndim == 1 else []
    nested = bool(items) and all(isinstance(g, Sequence | np.ndarray) and not isinstance(g, str) for g in items)
    groups = items if nested else [handles]
    return [check_index_array(g, n, f"handle group {k}" if nested else "handles") for k, g in enumerate(groups)]


def _constraint_marks(constraints: Any, n: int, m: int
                      ) -> tuple[NDArray[np.int64], list[NDArray[np.int64]], NDArray[np.int64] | None]:
    """Fixed vertices, handle groups and region of interest of a constraint set, a document or a file."""
    from arap.constraints import Constraints, load_constraints
    from arap.solve.indexing import check_index_array

    if isinstance(constraints, Constraints):
        fixed = check_index_array(constraints.fixed, n, "fixed")
        handles = check_index_array(constraints.handles, n, "handles")
        roi = None if constraints.roi is None else check_index_array(constraints.roi, n, "roi")
        groups = constraints.handle_groups
    elif isinstance(constraints, Mapping | str | os.PathLike):
        c = load_constraints(constraints, n, m)
        fixed, handles, roi, groups = c.fixed, c.handles, c.roi, c.handle_groups
    else:
        raise ConstraintError(f"constraints must be an arap.Constraints, a constraints document (a dict) or the path "
                              f"of a constraints file, got {type(constraints).__name__}")
    if groups:
        grouped = [check_index_array(g, n, f"handle_groups[{k}]") for k, g in enumerate(groups)]
    else:
        grouped = [handles] if len(handles) else []
    return fixed, grouped, roi


def role_colors(n: int, base: NDArray[np.float64], fixed: NDArray[np.int64] | None = None,
                groups: Sequence[NDArray[np.int64]] = (), roi: NDArray[np.int64] | None = None
                ) -> NDArray[np.float64]:
    """Vertex colours marking the constraints as the studio does: the region of interest (when given) in blue and the
    rest in a darker grey, then the anchors, then each handle group in its colour (:data:`STUDIO_COLORS`).

    Parameters
    ----------
    n : int
        Vertex count.
    base : (3,) or (n, 3) float array
        sRGB colours of the unmarked vertices.
    fixed : (f,) int array or None
    groups : sequence of (k,) int arrays
    roi : (r,) int array or None

    Returns
    -------
    (n, 3) float64 array

    Example
    -------
    >>> c = role_colors(3, as_rgb("#000000"), fixed=np.array([0]), groups=[np.array([2])])
    >>> [("#%02x%02x%02x" % tuple(round(255 * x) for x in row)) for row in c]
    ['#e64c45', '#000000', '#ff9e1a']
    """
    colors = np.array(np.broadcast_to(base, (n, 3)), dtype=np.float64)
    if roi is not None:
        colors[:] = as_rgb(STUDIO_COLORS["outside"])
        colors[roi] = as_rgb(STUDIO_COLORS["roi"])
    if fixed is not None and len(fixed):
        colors[fixed] = as_rgb(STUDIO_COLORS["fixed"])
    palette = STUDIO_COLORS["handles"]
    for k, group in enumerate(groups):
        colors[group] = as_rgb(palette[k % len(palette)])
    return colors


# ---------------------------------------------------------------------------------------------- show
def show(obj: Any, F: Any = None, *, constraints: Any = None, handles: Any = None, fixed: Any = None,
         colors: Any = None, width: int = 640, height: int = 480, azimuth: float | None = None,
         elevation: float | None = None, background: Any = BACKGROUND, camera: Camera | None = None,
         antialias: bool = True) -> Picture:
    """A picture of a mesh, with its constrained vertices marked.

    Parameters
    ----------
    obj : (n, 3) float array, ArapResult, mesh object, str or path-like
        Vertex positions (then ``F`` is needed); a result of :meth:`arap.ArapSolver.solve` (its deformed vertices:
        ``F`` is needed, a result does not hold the faces); a mesh object (a ``trimesh.Trimesh``, anything with
        ``vertices`` and ``faces``: see :func:`arap.mesh_arrays`); a built-in name (``"cactus"``, ``"bar"``,
        ``"cylinder"``, ``"sphere"``, ``"sphere:N"``) or a mesh file (read as stored, without repair, so that
        constraint indices mean the file's vertices).
    F : (m, 3) int array or None
        Triangles, with arrays or a result.
    constraints : arap.Constraints, dict or path-like, optional
        A constraint set, a constraints document (the JSON of ``arap constraints``, ``arap deform -c`` and the
        studio) or its file: anchors in red, each handle group in its own colour (``handle_groups``, else one group
        of all the handles), the region of interest (``roi``) in blue and the rest in a darker grey.
    handles : list of int, or list of lists of int, optional
        Handle vertices (one group), or handle groups; not together with ``constraints``.
    fixed : list of int, optional
        Anchored vertices; not together with ``constraints``.
    colors : str, (3,) or (n, 3) array, optional
        The mesh's colour, or one per vertex (interpolated across the faces): ``"#rrggbb"``, floats from 0 to 1 or
        integers from 0 to 255. Default: the studio's grey. Marks are painted over it.
    width, height : int
        Picture size in pixels (1 to 4096).
    azimuth, elevation : float or None
        Viewing direction in degrees: 0, 0 looks along -z with +y up (the studio's axes); None: a three-quarter view
        from the front right and above (30, 20), or 0, 0 for a mesh flat in z (a planar mesh given with two
        coordinates is drawn in z = 0, a tetrahedral one by its boundary).
    background : str or sequence of 3 numbers
        Colour around the mesh (the studio's by default).
    camera : arap.render.camera.Camera, optional
        The camera of an earlier picture (``picture.camera``), to show another shape of the mesh at the same place
        and scale; replaces ``width``, ``height``, ``azimuth`` and ``elevation``.
    antialias : bool
        Smooth edges (2x2 samples per pixel); False renders one sample per pixel.

    Returns
    -------
    Picture
        ``.pixels`` (h, w, 3) uint8, ``.png()``, ``.save(path)``; shown inline by Jupyter.

    Raises
    ------
    MeshError
        No faces given where needed, an empty mesh, face indices out of range, non-finite coordinates.
    ConstraintError
        Constraints that do not fit the mesh (the checks of :func:`arap.load_constraints`), or ``constraints``
        given together with ``fixed`` or ``handles``.
    OptionError
        A size, angle or colour out of range.

    Example
    -------
    >>> import arap
    >>> V, F = arap.builtin_mesh("sphere:100")
    >>> pic = arap.show(V, F, fixed=[0, 1, 2], width=64, height=48)
    >>> pic.pixels.shape, pic.png()[:4]
    ((48, 64, 3), b'\\x89PNG')
    """
    if camera is None:
        width, height = check_size(width, height)
    elif not isinstance(camera, Camera):
        raise OptionError(f"camera must be the camera of an earlier picture, got {type(camera).__name__}")
    V, F = _mesh_of(obj, F)
    n = len(V)
    base = as_rgb(STUDIO_COLORS["base"]) if colors is None else (
        as_rgb(colors, "colors") if isinstance(colors, str) else _rgb_array(colors, "colors", one=False, n=n))
    back = as_rgb(background, "background")
    if constraints is not None and (fixed is not None or handles is not None):
        raise ConstraintError("give the constraints either as constraints= or as fixed= and handles=, not both")
    anchors: NDArray[np.int64] | None
    if constraints is not None:
        anchors, groups, roi = _constraint_marks(constraints, n, len(F))
    else:
        from arap.solve.indexing import check_index_array

        anchors = None if fixed is None else check_index_array(fixed, n, "fixed")
        groups, roi = _handle_groups(handles, n), None
    marked = anchors is not None or groups or roi is not None
    vertex_colors = role_colors(n, base, anchors, groups, roi) if marked else base
    if camera is None:
        used = V[np.unique(F)]
        flat = bool(np.ptp(used[:, 2]) == 0)  # a planar mesh: seen from +z, x to the right and y up, by default
        camera = fit_camera(used, width, height,
                            azimuth=(0.0 if flat else DEFAULT_AZIMUTH) if azimuth is None else azimuth,
                            elevation=(0.0 if flat else DEFAULT_ELEVATION) if elevation is None else elevation)
    pixels = render_mesh(V, F, camera, vertex_colors, back, supersample=2 if antialias else 1)
    return Picture(pixels, camera)

