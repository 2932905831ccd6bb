"""Z-buffered triangle rasterisation in NumPy, with two-sided Lambert shading from a headlight.

Each triangle is tested against the pixel centres of its bounding box on screen, all triangles at once (in chunks
that bound the memory): a pixel centre inside or on the edge of a triangle is covered by it. The nearest covering
triangle of each pixel wins (a z-buffer kept with ``np.minimum.at``), and only the winners are coloured, by the
barycentric interpolation of their corners' colours (Gouraud shading). The light comes from the viewer; a face is
lit by the absolute cosine between its normal and the view direction, so back faces (the inside of an open mesh) are
shaded like front faces. Colours are lit in linear light and written in sRGB. Anti-aliasing renders the picture
``supersample`` times larger each way and averages the blocks of pixels.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from arap.meshes._geometry import vertex_normals
from arap.render.camera import Camera

__all__ = [
    "AMBIENT",
    "DIFFUSE",
    "linear_to_srgb",
    "lit_colors",
    "rasterize",
    "render_mesh",
    "srgb_to_linear",
]

#: Shares of the light that every face gets (ambient) and that faces turned to the viewer add (diffuse).
AMBIENT, DIFFUSE = 0.16, 0.84

#: Pixel tests per chunk of triangles (larger triangles are cut into bands of rows): bounds the memory a
#: rasterisation takes besides its picture to about 300 MB.
CHUNK = 1 << 21


def srgb_to_linear(c: NDArray[np.floating]) -> NDArray[np.float64]:
    """Linear light of sRGB values in [0, 1].

    Example
    -------
    >>> srgb_to_linear(np.array([0.0, 0.5, 1.0])).round(4).tolist()
    [0.0, 0.214, 1.0]
    """
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c: NDArray[np.floating]) -> NDArray[np.float64]:
    """sRGB values of linear light in [0, 1] (clipped to it first).

    Example
    -------
    >>> linear_to_srgb(srgb_to_linear(np.array([0.2, 0.8]))).round(12).tolist()
    [0.2, 0.8]
    """
    c = np.clip(np.asarray(c, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * c ** (1 / 2.4) - 0.055)


def lit_colors(normals: NDArray[np.float64], toward_viewer: NDArray[np.float64],
               colors: NDArray[np.float64]) -> NDArray[np.float64]:
    """Linear-light colours of vertices lit by a headlight, two-sided.

    Parameters
    ----------
    normals : (n, 3) float array
        Unit normals (zero: ambient light only).
    toward_viewer : (3,) float array
        Unit vector from the mesh towards the viewer.
    colors : (n, 3) or (3,) float array
        sRGB colours in [0, 1].

    Returns
    -------
    (n, 3) float64 array

    Example
    -------
    >>> n = np.array([[0.0, 0, 1], [1, 0, 0]])
    >>> lit_colors(n, np.array([0.0, 0, 1]), np.ones(3)).tolist()   # facing the light, then grazing
    [[1.0, 1.0, 1.0], [0.16, 0.16, 0.16]]
    """
    light = AMBIENT + DIFFUSE * np.abs(normals @ np.asarray(toward_viewer, dtype=np.float64))
    return light[:, None] * srgb_to_linear(np.broadcast_to(colors, normals.shape))


def _boxes(S: NDArray[np.float64], F: NDArray[np.int64], width: int, height: int
           ) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """The triangles that cover some pixel centre, and the first column, width, first row and height of the block
    of pixels whose centres their bounding boxes hold (pixel j's centre is j + 0.5)."""
    xs, ys = S[F, 0], S[F, 1]
    with np.errstate(invalid="ignore"):
        x0 = np.maximum(np.ceil(xs.min(axis=1) - 0.5), 0)
        x1 = np.minimum(np.floor(xs.max(axis=1) - 0.5), width - 1)
        y0 = np.maximum(np.ceil(ys.min(axis=1) - 0.5), 0)
        y1 = np.minimum(np.floor(ys.max(axis=1) - 0.5), height - 1)
        keep = np.flatnonzero((x1 >= x0) & (y1 >= y0))  # false for NaN too
    x0, y0 = x0[keep].astype(np.int64), y0[keep].astype(np.int64)
    return keep, x0, x1[keep].astype(np.int64) - x0 + 1, y0, y1[keep].astype(np.int64) - y0 + 1


def _pieces(bw: NDArray[np.int64], bh: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64],
                                                                     NDArray[np.int64]]:
    """Bands of the boxes' rows of at most :data:`CHUNK` pixels each: the box, the first row (from the box's top) and
    the rows of each band. Only triangles larger than the chunk are cut."""
    per = np.maximum(CHUNK // bw, 1)
    n = -(-bh // per)
    box = np.repeat(np.arange(len(bw)), n)
    k = np.arange(len(box)) - np.repeat(np.cumsum(n) - n, n)
    first = k * per[box]
    return box, first, np.minimum(per[box], bh[box] - first)


def _coverage(S: NDArray[np.float64], F: NDArray[np.int64], x0: NDArray[np.int64], bw: NDArray[np.int64],
              y0: NDArray[np.int64], bh: NDArray[np.int64], width: int, zbuf: NDArray[np.float64]
              ) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    """The pixel samples the triangles ``F`` (indices into the screen points ``S``) cover within their blocks of
    pixels (first column, width, first row, height): pixel index, depth, triangle (index into ``F``) and the
    barycentric weights (k, 3) of each; ``zbuf`` (h * w,) is lowered to the nearest depths."""
    A, B, C = S[F[:, 0]], S[F[:, 1]], S[F[:, 2]]
    area = (B[:, 0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (B[:, 1] - A[:, 1]) * (C[:, 0] - A[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(area != 0, 1.0 / area, np.nan)  # a triangle seen edge-on covers nothing (NaN fails the tests)
    # Barycentric weights and depth as affine functions of the sample's offset (dx, dy) from the block's first
    # centre: value = at + per_x * dx + per_y * dy.
    cx, cy = x0 + 0.5, y0 + 0.5
    wa_x, wa_y = (B[:, 1] - C[:, 1]) * inv, (C[:, 0] - B[:, 0]) * inv
    wb_x, wb_y = (C[:, 1] - A[:, 1]) * inv, (A[:, 0] - C[:, 0]) * inv
    wa = ((B[:, 0] - cx) * (C[:, 1] - cy) - (B[:, 1] - cy) * (C[:, 0] - cx)) * inv
    wb = ((C[:, 0] - cx) * (A[:, 1] - cy) - (C[:, 1] - cy) * (A[:, 0] - cx)) * inv
    za, zb, zc = A[:, 2], B[:, 2], C[:, 2]
    z0 = zc + wa * (za - zc) + wb * (zb - zc)
    z_x = wa_x * (za - zc) + wb_x * (zb - zc)
    z_y = wa_y * (za - zc) + wb_y * (zb - zc)

    counts = bw * bh
    t = np.repeat(np.arange(len(F)), counts)
    local = np.arange(len(t)) - np.repeat(np.cumsum(counts) - counts, counts)
    w_t = bw[t]
    dy = local // w_t
    dx = local - dy * w_t
    fx, fy = dx.astype(np.float64), dy.astype(np.float64)
    la = wa[t] + wa_x[t] * fx + wa_y[t] * fy
    lb = wb[t] + wb_x[t] * fx + wb_y[t] * fy
    lc = 1.0 - la - lb
    inside = np.flatnonzero((la >= 0) & (lb >= 0) & (lc >= 0))
    t, dx, dy = t[inside], dx[inside], dy[inside]
    la, lb, lc = la[inside], lb[inside], lc[inside]
    z = z0[t] + z_x[t] * dx + z_y[t] * dy
    pixel = (y0[t] + dy) * width + x0[t] + dx
    np.minimum.at(zbuf, pixel, z)
    near = np.flatnonzero(z <= zbuf[pixel])  # the nearest so far: the rest can never win
    return pixel[near], z[near], t[near], np.stack([la[near], lb[near], lc[near]], axis=1)


def rasterize(S: NDArray[np.float64], F: NDArray[np.int64], colors: NDArray[np.float64], width: int, height: int,
              background: NDArray[np.float64]) -> NDArray[np.float32]:
    """Paint triangles given in screen coordinates, the nearest one at each pixel.

    Parameters
    ----------
    S : (n, 3) float array
        Pixel x (right), pixel y (down) and depth (larger is farther) of the vertices; pixel ``(i, j)`` has its
        centre at ``x = j + 0.5, y = i + 0.5``.
    F : (m, 3) int array
        Triangles, indices into ``S`` (either orientation).
    colors : (n, 3) float array
        Colour of each vertex (any linear space), interpolated across the triangles.
    width, height : int
    background : (3,) float array
        Colour of the pixels no triangle covers.

    Returns
    -------
    (height, width, 3) float32 array

    Example
    -------
    >>> S = np.array([[0.0, 0, 0], [4, 0, 0], [0, 4, 0]])
    >>> img = rasterize(S, np.array([[0, 1, 2]]), np.ones((3, 3)), 4, 4, np.zeros(3))
    >>> img[:, :, 0].astype(int)
    array([[1, 1, 1, 1],
           [1, 1, 1, 0],
           [1, 1, 0, 0],
           [1, 0, 0, 0]])
    """
    zbuf = np.full(width * height, np.inf)
    image = np.empty((width * height, 3), dtype=np.float32)
    image[:] = background
    if not len(F):
        return image.reshape(height, width, 3)
    keep, x0, bw, y0, bh = _boxes(S, F, width, height)
    box, first, rows = _pieces(bw, bh)
    ends = np.cumsum(bw[box] * rows)
    start = 0
    while start < len(box):  # chunks of whole pieces, each of at most CHUNK pixel tests unless one piece is larger
        stop = max(int(np.searchsorted(ends, (ends[start - 1] if start else 0) + CHUNK, side="right")), start + 1)
        b = box[start:stop]
        pixel, _, t, w = _coverage(S, F[keep[b]], x0[b], bw[b], y0[b] + first[start:stop], rows[start:stop], width,
                                   zbuf)
        # The nearest samples so far: a later chunk's sample that covers the same pixel is painted over them only if
        # it is as near or nearer (the z-buffer only decreases), so the last paint of each pixel is its nearest.
        corners = F[keep[b[t]]]
        image[pixel] = (w[:, 0, None] * colors[corners[:, 0]] + w[:, 1, None] * colors[corners[:, 1]]
                        + w[:, 2, None] * colors[corners[:, 2]])
        start = stop
    return image.reshape(height, width, 3)


def render_mesh(V: NDArray[np.float64], F: NDArray[np.int64], camera: Camera, colors: NDArray[np.float64],
                background: NDArray[np.float64], *, supersample: int = 2) -> NDArray[np.uint8]:
    """A shaded picture of a mesh.

    Parameters
    ----------
    V : (n, 3) float64 array
    F : (m, 3) int64 array
        Indices in range (checked by the caller).
    camera : Camera
    colors : (n, 3) or (3,) float array
        sRGB colours in [0, 1] of the vertices, or one for all.
    background : (3,) float array
        sRGB colour in [0, 1].
    supersample : int
        Samples per pixel each way (1: no anti-aliasing).

    Returns
    -------
    (camera.height, camera.width, 3) uint8 array

    Example
    -------
    >>> from arap.render.camera import fit_camera
    >>> V, F = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]])
    >>> img = render_mesh(V, F, fit_camera(V, 8, 8, azimuth=0, elevation=0), np.ones(3), np.zeros(3))
    >>> img.shape, img.dtype, int(img[6, 1, 0]), int(img[1, 6, 0])    # lit white inside, black outside
    ((8, 8, 3), dtype('uint8'), 255, 0)
    """
    cam = camera.scaled(supersample) if supersample > 1 else camera
    lit = lit_colors(vertex_normals(V, F), camera.toward_viewer, colors)
    back = srgb_to_linear(np.asarray(background, dtype=np.float64))
    img = rasterize(cam.project(V), F, lit, cam.width, cam.height, back)
    if supersample > 1:
        s = supersample
        img = img.reshape(camera.height, s, camera.width, s, 3).mean(axis=(1, 3))
    return np.round(255.0 * linear_to_srgb(img)).astype(np.uint8)
