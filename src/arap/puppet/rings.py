"""A pin's hidden ring: how a pin of a flat mesh holds its surroundings turned by an angle.

A pin (a point handle of a flat triangle mesh) may hold an angle (Photoshop's fixed pin rotation): its surroundings
then turn by that angle about it instead of turning freely with the bend. The solver holds this with a hidden ring of
:data:`RING_POINTS` hard point handles at :data:`RING_SPACINGS` mean edge lengths about the pin, those of them that lie
on the mesh, which move with the pin turned by its angle. :class:`arap.PuppetWarp` (``arap warp``), the studio and
``arap deform`` / ``arap batch`` on a constraints document whose pins hold angles (:func:`held_points`) all make
their rings here.

Angles here are radians, counter-clockwise from x towards y (seen from +z when y points up, as in the studio; a
picture's pixels, y down, turn the other way as seen).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from arap.errors import ConstraintError
from arap.method.points import PointConstraints

if TYPE_CHECKING:
    from arap.constraints.document import Constraints

__all__ = ["RING_POINTS", "RING_SPACINGS", "PinRings", "held_points", "locate_points", "mean_edge_length",
           "pin_rings", "ring_offsets", "turned"]

RING_POINTS = 6
"""Hidden points around a pin that holds an angle (those on the mesh are kept)."""
RING_SPACINGS = 2.0
"""Radius of that ring, in mean edge lengths of the mesh."""


def mean_edge_length(V: ArrayLike, F: ArrayLike) -> float:
    """The mean length of the triangles' edges (an edge of two triangles counted twice), in the plane of the first
    two coordinates of ``V``."""
    P = np.asarray(V, dtype=np.float64)[:, :2]
    T = np.asarray(F, dtype=np.int64)
    edges = np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]])
    return float(np.linalg.norm(P[edges[:, 0]] - P[edges[:, 1]], axis=1).mean())


def ring_offsets(V: ArrayLike, F: ArrayLike) -> NDArray[np.float64]:
    """The rest offsets ``(RING_POINTS, 2)`` of a ring about a pin of the flat mesh ``V``, ``F``: evenly spaced on a
    circle of :data:`RING_SPACINGS` mean edge lengths, the first along +x.

    Example
    -------
    >>> V = np.array([[0.0, 0], [1, 0], [0, 1]]); F = np.array([[0, 1, 2]])
    >>> ring_offsets(V, F)[:2].round(3).tolist()
    [[2.276, 0.0], [1.138, 1.971]]
    """
    turn = 2.0 * np.pi * np.arange(RING_POINTS) / RING_POINTS
    return RING_SPACINGS * mean_edge_length(V, F) * np.column_stack([np.cos(turn), np.sin(turn)])


def turned(offsets: ArrayLike, angles: ArrayLike) -> NDArray[np.float64]:
    """Offsets ``(r, 2|3)`` turned in the plane of their first two coordinates by ``angles`` (radians, one each or
    one for all); a third coordinate is kept.

    Example
    -------
    >>> turned([[1.0, 0.0, 5.0]], np.pi / 2).round(6).tolist()
    [[0.0, 1.0, 5.0]]
    """
    o = np.array(offsets, dtype=np.float64)
    a = np.broadcast_to(np.asarray(angles, dtype=np.float64), o.shape[:1])
    c, s = np.cos(a), np.sin(a)
    x, y = o[:, 0].copy(), o[:, 1].copy()
    o[:, 0], o[:, 1] = c * x - s * y, s * x + c * y
    return o


def locate_points(V: ArrayLike, F: ArrayLike, points: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """The triangle of a flat mesh (``V``: its first two coordinates read) under each of ``points`` ((k, 2|3), x and
    y read) and the points' barycentric coordinates in it; a point outside the mesh takes the nearest triangle (the
    one where its most negative coordinate is least negative), its coordinates clipped to it.

    Example
    -------
    >>> V = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]); F = np.array([[0, 1, 2], [0, 2, 3]])
    >>> faces, bary = locate_points(V, F, np.array([[0.25, 0.75]]))
    >>> faces.tolist(), bary.round(2).tolist()
    ([1], [[0.25, 0.25, 0.5]])
    """
    P = np.asarray(points, dtype=np.float64)[:, :2]
    W = np.asarray(V, dtype=np.float64)
    T = np.asarray(F, dtype=np.int64)
    a, b, c = (W[T[:, k], :2] for k in range(3))
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    det = np.where(det == 0.0, np.finfo(np.float64).tiny, det)
    faces = np.empty(len(P), dtype=np.int64)
    bary = np.empty((len(P), 3))
    for k, (x, y) in enumerate(P):
        l1 = ((x - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (y - a[:, 1])) / det
        l2 = ((b[:, 0] - a[:, 0]) * (y - a[:, 1]) - (x - a[:, 0]) * (b[:, 1] - a[:, 1])) / det
        lam = np.column_stack([1.0 - l1 - l2, l1, l2])
        best = int(np.argmax(lam.min(axis=1)))
        inside = np.clip(lam[best], 0.0, None)
        faces[k], bary[k] = best, inside / inside.sum()
    return faces, bary


@dataclass(frozen=True, eq=False)
class PinRings:
    """The angles pins hold and the hidden rings that hold them (:func:`pin_rings`): around each pin that holds an
    angle, hard point handles that move with the pin turned by its angle.

    Attributes
    ----------
    angles : tuple of float or None
        Per pin, the angle (radians, see :mod:`arap.puppet.rings`) by which it holds its surroundings turned, or None
        for a pin whose surroundings turn freely with the bend.
    points : PointConstraints
        The ring points on the rest mesh (hard), the rings of the pins in order.
    pin : (r,) int64 array
        The pin each ring point turns with.
    offset : (r, 2) float64 array
        Each ring point's rest place relative to its pin's rest place.
    """

    angles: tuple[float | None, ...]
    points: PointConstraints
    pin: NDArray[np.int64]
    offset: NDArray[np.float64]

    def targets(self, pin_targets: ArrayLike, angles: Sequence[float | None] | None = None) -> NDArray[np.float64]:
        """Where the ring points go when the pins go to ``pin_targets`` ((k, 2|3); a third coordinate is the ring
        points' too): each at its pin's target plus its offset turned by its pin's angle (``angles``: per pin, the
        angle to hold instead, None entries or None: :attr:`angles`).

        Example
        -------
        A pin at the middle of a 10×10 grid, turned by half a turn: its ring's first point, 2.28 to its right at
        rest, goes as far to the left of the pin's target.

        >>> x, y = np.meshgrid(np.arange(11.0), np.arange(11.0)); V = np.column_stack([x.ravel(), y.ravel()])
        >>> q = (np.arange(10)[:, None] * 11 + np.arange(10)).ravel()
        >>> F = np.concatenate([np.column_stack([q, q + 1, q + 12]), np.column_stack([q, q + 12, q + 11])])
        >>> rings = pin_rings(V, F, [[5.0, 5.0]], [0.0])
        >>> rings.targets([[7.0, 5.0]], [np.pi])[0].round(3).tolist()
        [4.724, 5.0]
        """
        T = np.asarray(pin_targets, dtype=np.float64)
        given = [None] * len(self.angles) if angles is None else list(angles)
        if len(given) != len(self.angles):
            raise ConstraintError(f"{len(given)} angles for {len(self.angles)} pins")
        per_pin = np.array([g if g is not None else (a if a is not None else 0.0)
                            for g, a in zip(given, self.angles, strict=True)], dtype=np.float64)
        if not len(self.pin):
            return np.zeros((0, T.shape[1]))
        offset = np.zeros((len(self.pin), T.shape[1]))
        offset[:, :2] = self.offset
        return T[self.pin] + turned(offset, per_pin[self.pin])


def pin_rings(V: ArrayLike, F: ArrayLike, pins: ArrayLike,
              angles: Sequence[float | None]) -> PinRings:
    """The hidden rings of ``pins`` ((k, 2|3) rest places, x and y read) on the flat mesh ``V``, ``F`` that hold an
    angle (``angles``: per pin, radians or None): the points of a ring (:func:`ring_offsets`) about each such pin that
    lie on the mesh.

    Raises
    ------
    ConstraintError
        Not one angle per pin, or a pin holds an angle with no ring point on the mesh (too near its
        edge for the mesh's spacing).

    Example
    -------
    On a 10×10 grid, a pin in the middle keeps its whole ring, one near a corner two of its six points:

    >>> x, y = np.meshgrid(np.arange(11.0), np.arange(11.0)); V = np.column_stack([x.ravel(), y.ravel()])
    >>> q = (np.arange(10)[:, None] * 11 + np.arange(10)).ravel()
    >>> F = np.concatenate([np.column_stack([q, q + 1, q + 12]), np.column_stack([q, q + 12, q + 11])])
    >>> rings = pin_rings(V, F, [[5.0, 5.0], [0.0, 0.0], [9.0, 9.0]], [0.5, None, 0.0])
    >>> rings.pin.tolist(), rings.angles
    ([0, 0, 0, 0, 0, 0, 2, 2], (0.5, None, 0.0))
    """
    W = np.asarray(V, dtype=np.float64)
    T = np.asarray(F, dtype=np.int64)
    P = np.asarray(pins, dtype=np.float64)
    centres = P[:, :2] if P.ndim == 2 else np.zeros((0, 2))
    if len(centres) != len(angles):
        raise ConstraintError(f"{len(angles)} angles for {len(centres)} pins; give one angle (or None) per pin")
    offsets = ring_offsets(W, T)
    faces, bary, pin, offset = [np.zeros(0, dtype=np.int64)], [np.zeros((0, 3))], [np.zeros(0, dtype=np.int64)], \
        [np.zeros((0, 2))]
    for k, a in enumerate(angles):
        if a is None:
            continue
        ring = centres[k] + offsets
        f, b = locate_points(W, T, ring)
        at = np.einsum("kc,kcd->kd", b, W[T[f]][:, :, :2])
        on = np.linalg.norm(at - ring, axis=1) <= 1e-6 * (1.0 + np.abs(ring).max())
        if not on.any():
            raise ConstraintError(f"pin {k} is too near the edge of the shape to hold an angle (none of its ring, "
                                  f"{RING_SPACINGS:g} mesh spacings about it, is on the shape)")
        faces.append(f[on])
        bary.append(b[on])
        pin.append(np.full(int(on.sum()), k, dtype=np.int64))
        offset.append(offsets[on])
    points = PointConstraints(np.concatenate(faces), np.concatenate(bary), np.full(sum(map(len, pin)), np.inf))
    return PinRings(tuple(None if a is None else float(a) for a in angles), points, np.concatenate(pin),
                    np.concatenate(offset))


def held_points(constraints: Constraints, V: ArrayLike, F: ArrayLike,
                command: str) -> tuple[PointConstraints | None, NDArray[np.float64] | None]:
    """The point handles a solve of ``constraints`` on the mesh ``V``, ``F`` holds, and their targets: the document's
    point handles, then the hidden rings (:func:`pin_rings`) of those that hold an angle (``"angle"``, a picture's pin
    turned in the studio), each ring point at its pin's target plus its rest offset turned by the angle. Without
    angles, the document's own.

    Angles turn about the z axis, counter-clockwise as seen from +z, as the studio saves them for a picture's mesh
    in ``z = 0``: they are held on a mesh of triangles in a plane of constant z (``command``, e.g. ``"arap deform"``,
    names the command that refuses the others).

    Raises
    ------
    ConstraintError
        A pin holds an angle on a mesh that is not flat in a plane of constant z (a surface in space, a solid), or is
        too near the shape's edge to hold it.
    """
    from arap.meshes.domain import PLANAR_TOLERANCE

    points, targets = constraints.points, constraints.point_targets
    angles = constraints.pin_angles or []
    held = [(k, a) for k, a in enumerate(angles) if a is not None]
    if not held or points is None or targets is None:
        return points, targets
    W = np.asarray(V, dtype=np.float64)
    T = np.asarray(F, dtype=np.int64)
    spread = np.ptp(W, axis=0) if len(W) else np.zeros(3)
    flat = W.shape[1] == 2 or float(spread[2]) <= PLANAR_TOLERANCE * max(float(np.linalg.norm(spread)), 1e-300)
    if T.shape[1] != 3 or not flat:
        k, a = held[0]
        what = "a solid" if T.shape[1] != 3 else "a surface that is not flat in a plane of constant z"
        raise ConstraintError(
            f"{command} holds a pin's angle only on a flat mesh in a plane of constant z (a picture's, as the studio "
            f"saves it), and this is {what}: points[{k}] holds an angle of {a:g} degrees "
            f"(\"angle\"{f', and {len(held) - 1} more' if len(held) > 1 else ''}); remove \"angle\" to let the "
            "pins turn freely with the bend")
    rings = pin_rings(W, T, points.positions(W, T), [None if a is None else np.radians(a) for a in angles])
    ring = rings.points
    return (PointConstraints(np.concatenate([points.faces, ring.faces]),
                             np.concatenate([points.barycentric, ring.barycentric]),
                             np.concatenate([points.weights, ring.weights])),
            np.concatenate([targets, rings.targets(targets)]))
