"""The shape of a picture and its outline: which pixels belong to it, and the closed polygons around them.

- :func:`shape_mask`: the opaque pixels of a picture with alpha (``alpha > alpha_threshold``), or, without alpha,
  the whole frame or the pixels that differ from a background colour.
- :func:`outline_loops`: marching squares on the mask sampled at the pixel centres, at pixel resolution: closed
  loops through the midpoints between an inside and an outside pixel centre, holes included. Every loop has the
  shape on its right when walked on screen (x right, y down); where two shape pixels touch only at a corner, they
  are kept apart (the saddle cases are read as two separate corners).
- :func:`simplify_loop`: a loop reduced to the mesh's spacing: Douglas-Peucker within a fraction of a pixel, then
  edges longer than the spacing cut into equal pieces.

Positions are in pixel coordinates: x to the right, y down, the pixel ``(row, col)`` covering
``[col, col + 1) × [row, row + 1)``, its centre at ``(col + 0.5, row + 0.5)``.
"""

from __future__ import annotations

import itertools
import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

import arap.kernels.cache  # noqa: F401  (a writable kernel cache before the kernels are defined)
from arap.errors import ArapError

__all__ = ["loop_area", "outline_loops", "shape_mask", "simplify_loop"]


def shape_mask(image: NDArray[np.uint8], alpha_threshold: int = 0, background: tuple[int, int, int] | None = None,
               tolerance: float = 0.0) -> NDArray[np.bool_]:
    """The pixels that belong to the picture's shape.

    Parameters
    ----------
    image : (h, w, 3) or (h, w, 4) uint8 array
    alpha_threshold : int
        A pixel of a picture with alpha belongs to the shape when its alpha is above this (0 to 254).
    background : (r, g, b) or None
        Leave out the pixels of this colour (within ``tolerance``), with or without alpha.
    tolerance : float
        Largest difference per channel (0 to 255) for a pixel to count as the background colour.

    Returns
    -------
    (h, w) bool array

    Example
    -------
    >>> img = np.zeros((2, 3, 4), dtype=np.uint8); img[0, 1, 3] = 200
    >>> shape_mask(img).astype(int).tolist()
    [[0, 1, 0], [0, 0, 0]]
    """
    if not 0 <= alpha_threshold <= 254:
        raise ArapError(f"alpha_threshold must be from 0 to 254, got {alpha_threshold}")
    if image.shape[2] == 4:
        mask = image[:, :, 3] > alpha_threshold
    else:
        mask = np.ones(image.shape[:2], dtype=bool)
    if background is not None:
        colour = np.asarray(background, dtype=np.int16).reshape(-1)
        if colour.shape != (3,) or (colour < 0).any() or (colour > 255).any():
            raise ArapError(f"background must be an (r, g, b) colour with values from 0 to 255, got {background}")
        if not 0 <= tolerance <= 255:
            raise ArapError(f"tolerance must be from 0 to 255, got {tolerance}")
        difference = np.abs(image[:, :, :3].astype(np.int16) - colour).max(axis=2)
        mask &= difference > tolerance
    return mask


# Cell corners in screen-clockwise order (top left, top right, bottom right, bottom left) as (row, col) offsets, and
# the cell's edges between them (top, right, bottom, left).
_CORNERS = ((0, 0), (0, 1), (1, 1), (1, 0))


def outline_loops(mask: NDArray[np.bool_]) -> list[NDArray[np.float64]]:
    """Closed loops around the mask's regions and holes (marching squares at the pixel centres).

    Parameters
    ----------
    mask : (h, w) bool array

    Returns
    -------
    list of (p, 2) float64 arrays
        Each loop's points (x, y) in pixel coordinates, not repeating the first at the end; the shape is on the right
        of the walk on screen, so outer loops run clockwise on screen and holes anticlockwise.

    Example
    -------
    A single pixel: a diamond through the midpoints of its sides.

    >>> outline_loops(np.array([[True]]))[0].tolist()
    [[0.0, 0.5], [0.5, 0.0], [1.0, 0.5], [0.5, 1.0]]
    """
    m = np.zeros((mask.shape[0] + 2, mask.shape[1] + 2), dtype=bool)
    m[1:-1, 1:-1] = mask
    H2, W2 = m.shape
    corner = [m[dr:H2 - 1 + dr, dc:W2 - 1 + dc] for dr, dc in _CORNERS]
    code = corner[0] * 1 + corner[1] * 2 + corner[2] * 4 + corner[3] * 8
    rows, cols = np.nonzero((code != 0) & (code != 15))
    if len(rows) == 0:
        return []
    inside = [c[rows, cols] for c in corner]
    # Edge k runs from corner k to corner k+1 (clockwise); its crossing point has an id (horizontal edges first).
    horizontal = H2 * W2
    edge_id = [rows * W2 + cols, horizontal + rows * W2 + cols + 1, (rows + 1) * W2 + cols,
               horizontal + rows * W2 + cols]
    leaving = [inside[k] & ~inside[(k + 1) % 4] for k in range(4)]   # in → out, clockwise
    entering = [~inside[k] & inside[(k + 1) % 4] for k in range(4)]  # out → in
    starts, ends = [], []
    for k in range(4):
        todo = leaving[k].copy()
        for back in (1, 2, 3):  # the nearest entering edge anticlockwise
            j = (k - back) % 4
            hit = todo & entering[j]
            starts.append(edge_id[k][hit])
            ends.append(edge_id[j][hit])
            todo &= ~hit
    start = np.concatenate(starts)
    end = np.concatenate(ends)
    order = np.argsort(start)
    start, end = start[order], end[order]
    follow = np.searchsorted(start, end)  # every crossing point starts one segment and ends one
    order, bounds = _chains(follow)
    ids = start[order]
    vertical = ids >= horizontal
    local = np.where(vertical, ids - horizontal, ids)
    r, c = local // W2, local % W2
    x = np.where(vertical, c, c + 0.5) - 0.5  # padded sample (r, c) is pixel (r - 1, c - 1), centre c - 0.5
    y = np.where(vertical, r + 0.5, r) - 0.5
    points = np.column_stack([x, y]).astype(np.float64)
    return [points[a:b] for a, b in itertools.pairwise(bounds)]


def loop_area(loop: NDArray[np.float64]) -> float:
    """Signed area of a closed loop (shoelace formula): positive when it runs clockwise on screen (y down).

    Example
    -------
    >>> loop_area(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]))
    1.0
    """
    x, y = loop[:, 0], loop[:, 1]
    return float(0.5 * (np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)))


@nb.njit(cache=True, nogil=True)
def _douglas_peucker(points: NDArray[np.float64], tolerance: float) -> NDArray[np.bool_]:  # pragma: no cover
    """Which points an open polyline keeps (ends included) within ``tolerance``."""
    n = len(points)
    keep = np.zeros(n, dtype=np.bool_)
    keep[0] = True
    keep[n - 1] = True
    stack = np.empty((n + 1, 2), dtype=np.int64)
    stack[0, 0], stack[0, 1] = 0, n - 1
    top = 1
    while top > 0:
        top -= 1
        a, b = stack[top, 0], stack[top, 1]
        if b - a < 2:
            continue
        px, py = points[a, 0], points[a, 1]
        dx, dy = points[b, 0] - px, points[b, 1] - py
        length = math.hypot(dx, dy)
        best, far = -1.0, a + 1
        for i in range(a + 1, b):
            ix, iy = points[i, 0] - px, points[i, 1] - py
            d = abs(ix * dy - iy * dx) / length if length > 0 else math.hypot(ix, iy)
            if d > best:
                best, far = d, i
        if best > tolerance:
            keep[far] = True
            stack[top, 0], stack[top, 1] = a, far
            stack[top + 1, 0], stack[top + 1, 1] = far, b
            top += 2
    return keep


@nb.njit(cache=True, nogil=True)
def _chains(follow: NDArray[np.int64]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:  # pragma: no cover
    """The segments in the order the loops walk them, and where each loop starts in that order (and the end)."""
    n = len(follow)
    seen = np.zeros(n, dtype=np.bool_)
    order = np.empty(n, dtype=np.int64)
    starts = np.empty(n + 1, dtype=np.int64)
    count, loops = 0, 0
    for first in range(n):
        if seen[first]:
            continue
        starts[loops] = count
        loops += 1
        i = first
        while not seen[i]:
            seen[i] = True
            order[count] = i
            count += 1
            i = follow[i]
    starts[loops] = count
    return order, starts[:loops + 1]


def simplify_loop(loop: NDArray[np.float64], spacing: float, tolerance: float) -> NDArray[np.float64]:
    """A closed loop within ``tolerance`` of the original, its edges at most ``spacing`` long.

    Parameters
    ----------
    loop : (p, 2) float array
        Closed loop (first point not repeated).
    spacing : float
        Longest edge of the result.
    tolerance : float
        Largest distance of a left-out point from the result (Douglas-Peucker).

    Returns
    -------
    (q, 2) float64 array
        Fewer than 3 points when the loop is too small to keep.

    Example
    -------
    >>> square = np.array([[0.0, 0], [1, 0], [2, 0], [2, 2], [0, 2]])
    >>> simplify_loop(square, spacing=1.0, tolerance=0.1).shape
    (8, 2)
    """
    if len(loop) < 3:
        return loop
    far = int(np.argmax(np.hypot(*(loop - loop[0]).T)))
    if far == 0:
        return loop[:1]
    closed = np.concatenate([loop, loop[:1]])
    first = np.flatnonzero(_douglas_peucker(closed[:far + 1], float(tolerance)))
    second = far + np.flatnonzero(_douglas_peucker(closed[far:], float(tolerance)))
    kept = closed[np.concatenate([first, second[1:-1]])]
    if len(kept) < 3:
        return kept
    nxt = np.roll(kept, -1, axis=0)
    pieces = np.maximum(np.ceil(np.hypot(*(nxt - kept).T) / spacing).astype(np.int64), 1)
    t = np.concatenate([np.arange(n) / n for n in pieces])
    edge = np.repeat(np.arange(len(kept)), pieces)
    return kept[edge] + t[:, None] * (nxt[edge] - kept[edge])
