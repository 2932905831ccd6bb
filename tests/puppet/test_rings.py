"""A pin's hidden ring is made in one place: the puppet warp and the studio keep the same ring points of a pin on the
same mesh, turn them the same way, and refuse a pin too near the shape's edge with the same reason."""

from __future__ import annotations

import numpy as np
import pytest

import arap
from arap.errors import ConstraintError
from arap.method.points import PointConstraints
from arap.puppet.rings import RING_POINTS, pin_rings, ring_offsets
from tests.puppet.pictures import bar


def test_the_warp_holds_the_rings_the_studio_makes_on_its_mesh() -> None:
    from arap.server.pictures import pin_rings as studio_rings

    puppet = arap.PuppetWarp(bar(), [[30, 100], [100, 100]], spacing=6, angles=[None, 30.0])
    V, F = puppet.mesh.vertices, puppet.mesh.triangles
    pins = PointConstraints(puppet.faces, puppet.barycentric, np.full(2, np.inf))
    V3 = np.column_stack([V, np.zeros(len(V))])
    studio = studio_rings(V3, F, pins, [None, 0.5])
    ring = puppet._rings.points
    assert len(ring) == RING_POINTS
    np.testing.assert_array_equal(ring.faces, studio.points.faces)
    np.testing.assert_allclose(ring.barycentric, studio.points.barycentric, atol=1e-9)
    # Held at rest, the ring points stay where they are; the warp's ring turns by the angle about the pin.
    U = puppet.deform()
    at = np.einsum("pc,pcx->px", ring.barycentric, U[F[ring.faces]])
    pin_at = np.einsum("c,cx->x", puppet.barycentric[1], U[F[puppet.faces[1]]])
    a = np.radians(30.0)  # counter-clockwise as seen with y down: x towards -y
    R = np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    np.testing.assert_allclose(at - pin_at, puppet._rings.offset @ R.T, atol=1e-6 * float(np.ptp(V)))


def test_a_ring_is_two_mean_edge_lengths_about_its_pin() -> None:
    V = np.array([[0.0, 0.0], [3.0, 0.0], [0.0, 4.0]])
    offsets = ring_offsets(V, np.array([[0, 1, 2]]))
    np.testing.assert_allclose(np.linalg.norm(offsets, axis=1), 2.0 * (3 + 4 + 5) / 3)


def test_a_pin_too_near_the_edge_is_refused_alike_by_the_warp_and_the_studio() -> None:
    from arap.server.pictures import pin_rings as studio_rings
    from arap.server.session_errors import BadValues

    V = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    F = np.array([[0, 1, 2]])
    with pytest.raises(ConstraintError, match="pin 1 is too near the edge of the shape to hold an angle"):
        pin_rings(V, F, [[0.2, 0.2], [0.3, 0.3]], [None, 0.1])
    pins = PointConstraints(np.array([0]), np.array([[0.4, 0.3, 0.3]]), np.array([np.inf]))
    with pytest.raises(BadValues, match="pin 0 is too near the edge of the shape to hold an angle"):
        studio_rings(np.column_stack([V, np.zeros(3)]), F, pins, [0.0])
    img = np.zeros((30, 30, 4), dtype=np.uint8)
    img[10:16, 10:16] = 255  # a square of about two mesh spacings: a ring about its middle misses it
    with pytest.raises(ConstraintError, match="pin 0 is too near the edge of the shape to hold an angle"):
        arap.PuppetWarp(img, [[13, 13]], spacing=3, angles=[10.0])
    with pytest.raises(ConstraintError, match="2 angles for 1 pins"):
        pin_rings(V, F, [[0.2, 0.2]], [None, 0.1])
