"""Rotate rings where they cross on screen: the gizmo picks the ring whose line is nearest to the pointer, not the
one in front."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from playwright.sync_api import Page

from tests.e2e.test_studio_transform import gizmo, ready_to_rotate

pytestmark = pytest.mark.e2e


def _distance(p: np.ndarray, ring: np.ndarray) -> float:
    """Distance from p to the closed polyline `ring`."""
    a = ring
    b = np.roll(ring, -1, axis=0)
    d = b - a
    t = np.clip(((p - a) * d).sum(axis=1) / np.maximum((d * d).sum(axis=1), 1e-12), 0, 1)
    return float(np.min(np.linalg.norm(p - a - t[:, None] * d, axis=1)))


def test_the_ring_nearest_to_the_pointer_is_picked_where_rings_cross(page: Page) -> None:
    ready_to_rotate(page)
    g = gizmo(page)
    rings = {name: np.asarray(g["rings"][name]) for name in ("x", "y", "z", "e")}
    checked = 0
    wrong: list[str] = []
    for a, b in itertools.combinations(rings, 2):
        A, B = rings[a], rings[b]
        # where the two rings cross on screen: the closest pair of their points
        gaps = np.linalg.norm(A[:, None, :] - B[None, :, :], axis=2)
        if gaps.min() > 3:
            continue
        for crossing in zip(*np.nonzero(gaps < 3), strict=True):
            ia, ib = crossing
            # a point on each ring a few pixels from the crossing, nearer to its own ring than to the other
            for name, other, ring, k in ((a, b, A, ia), (b, a, B, ib)):
                for step in (1, -1):
                    p = ring[(k + step) % len(ring)]
                    own, far = _distance(p, ring), _distance(p, rings[other])
                    if not (far - own > 2.5 and far < 9):
                        continue
                    page.mouse.move(float(p[0]), float(p[1]))
                    hover = page.evaluate("() => window.__arap.gizmo().hover")
                    checked += 1
                    if hover != name.upper():
                        wrong.append(f"{hover} instead of {name.upper()} at {p.round(1).tolist()} "
                                     f"({own:.1f} px from its ring, {far:.1f} px from {other.upper()})")
                    break
            break
    assert checked >= 4, "the rings should cross on screen"
    print(f"{checked} points beside crossings checked")
    assert not wrong, "; ".join(wrong)
