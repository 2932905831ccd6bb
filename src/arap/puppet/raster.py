"""Textured triangles drawn into a picture: the rendering of a puppet warp.

Each triangle of the deformed mesh is drawn in turn (a compiled loop): the pixel centres of its bounding box are
tested with their barycentric coordinates in the deformed triangle (a centre on an edge counts as inside, so that
neighbouring triangles leave no crack), mapped back by the same coordinates to the rest triangle in the source
picture, and sampled there bilinearly. Sampling interpolates premultiplied colours (colour times alpha), so that
transparent pixels lend no colour to their opaque neighbours; the result is divided by its alpha again. A pixel
takes the colour of the last triangle drawn over it: the drawing order is the depth order of overlapping parts.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

import arap.kernels.cache  # noqa: F401  (a writable kernel cache before the kernel is defined)

__all__ = ["draw_textured", "premultiplied"]

_EDGE = 1e-9
"""How far below 0 a pixel centre's barycentric coordinate may be for it to count as inside (on an edge)."""


def premultiplied(image: NDArray[np.uint8]) -> NDArray[np.float32]:
    """(h, w, 4) float32 premultiplied colours (r·a, g·a, b·a, a), on the scale 0 to 255, of an RGB or RGBA picture.

    Example
    -------
    >>> premultiplied(np.array([[[200, 100, 0, 51]]], dtype=np.uint8)).tolist()
    [[[40.0, 20.0, 0.0, 51.0]]]
    """
    out = np.empty((*image.shape[:2], 4), dtype=np.float32)
    if image.shape[2] == 4:
        a = image[:, :, 3].astype(np.float32)
        out[:, :, :3] = image[:, :, :3] * (a / np.float32(255.0))[:, :, None]
        out[:, :, 3] = a
    else:
        out[:, :, :3] = image
        out[:, :, 3] = 255.0
    return out


@nb.njit(cache=True, nogil=True)
def _draw(source: NDArray[np.float32], src: NDArray[np.float64], dst: NDArray[np.float64],
          triangles: NDArray[np.int64], order: NDArray[np.int64], out: NDArray[np.float32]) -> None:  # pragma: no cover
    sh, sw = source.shape[0], source.shape[1]
    oh, ow = out.shape[0], out.shape[1]
    for t in order:
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        xa, ya = dst[a, 0], dst[a, 1]
        xb, yb = dst[b, 0], dst[b, 1]
        xc, yc = dst[c, 0], dst[c, 1]
        det = (xb - xa) * (yc - ya) - (xc - xa) * (yb - ya)
        if det == 0.0 or not math.isfinite(det):
            continue
        x0 = max(0, math.ceil(min(xa, xb, xc) - 0.5))
        x1 = min(ow - 1, math.floor(max(xa, xb, xc) - 0.5))
        y0 = max(0, math.ceil(min(ya, yb, yc) - 0.5))
        y1 = min(oh - 1, math.floor(max(ya, yb, yc) - 0.5))
        for py in range(y0, y1 + 1):
            cy = py + 0.5
            for px in range(x0, x1 + 1):
                cx = px + 0.5
                l1 = ((cx - xa) * (yc - ya) - (xc - xa) * (cy - ya)) / det
                l2 = ((xb - xa) * (cy - ya) - (cx - xa) * (yb - ya)) / det
                l0 = 1.0 - l1 - l2
                if l0 < -_EDGE or l1 < -_EDGE or l2 < -_EDGE:
                    continue
                sx = l0 * src[a, 0] + l1 * src[b, 0] + l2 * src[c, 0] - 0.5
                sy = l0 * src[a, 1] + l1 * src[b, 1] + l2 * src[c, 1] - 0.5
                sx = min(max(sx, 0.0), sw - 1.0)
                sy = min(max(sy, 0.0), sh - 1.0)
                i0 = min(int(sx), sw - 2) if sw > 1 else 0
                j0 = min(int(sy), sh - 2) if sh > 1 else 0
                i1 = min(i0 + 1, sw - 1)
                j1 = min(j0 + 1, sh - 1)
                tx = sx - i0
                ty = sy - j0
                for k in range(4):
                    top = source[j0, i0, k] * (1.0 - tx) + source[j0, i1, k] * tx
                    bottom = source[j1, i0, k] * (1.0 - tx) + source[j1, i1, k] * tx
                    out[py, px, k] = top * (1.0 - ty) + bottom * ty


def draw_textured(image: NDArray[np.uint8], rest: NDArray[np.float64], deformed: NDArray[np.float64],
                  triangles: NDArray[np.int64], size: tuple[int, int], origin: tuple[int, int] = (0, 0),
                  order: NDArray[np.int64] | None = None) -> NDArray[np.uint8]:
    """Draw the picture mapped onto the deformed triangles.

    Parameters
    ----------
    image : (h, w, 3|4) uint8 array
        The source picture.
    rest : (n, 2) float array
        Where each vertex lies in the source picture (pixel coordinates, x right, y down).
    deformed : (n, 2) float array
        Where each vertex goes, in the same coordinates.
    triangles : (m, 3) int array
    size : (width, height)
        Of the result.
    origin : (x, y) ints
        The position, in the source's coordinates, of the result's top-left corner.
    order : (m,) int array or None
        The triangles to draw, in drawing order (later ones cover earlier ones); None: all, in their order.

    Returns
    -------
    (height, width, 4) uint8 array
        Straight (not premultiplied) RGBA; transparent where no triangle was drawn.

    Example
    -------
    Two triangles covering a 2×2 picture, drawn in place, give the picture back.

    >>> img = np.arange(16, dtype=np.uint8).reshape(2, 2, 4) * 10 + 100
    >>> V = np.array([[0.0, 0], [2, 0], [2, 2], [0, 2]]); F = np.array([[0, 1, 2], [0, 2, 3]])
    >>> bool((draw_textured(img, V, V, F, (2, 2)) == img).all())
    True
    """
    w, h = int(size[0]), int(size[1])
    out = np.zeros((h, w, 4), dtype=np.float32)
    F = np.ascontiguousarray(triangles, dtype=np.int64)
    seq = np.arange(len(F), dtype=np.int64) if order is None else np.ascontiguousarray(order, dtype=np.int64)
    shift = np.array([origin[0], origin[1]], dtype=np.float64)
    _draw(premultiplied(image), np.ascontiguousarray(rest, dtype=np.float64),
          np.ascontiguousarray(deformed, dtype=np.float64) - shift, F, seq, out)
    alpha = out[:, :, 3]
    result = np.zeros((h, w, 4), dtype=np.uint8)
    seen = alpha > 0
    colour = out[:, :, :3][seen] * (np.float32(255.0) / alpha[seen])[:, None]
    result[:, :, :3][seen] = np.clip(np.rint(colour), 0, 255).astype(np.uint8)
    result[:, :, 3] = np.clip(np.rint(alpha), 0, 255).astype(np.uint8)
    return result
