"""Meshing a picture's shape: no triangle outside it or in its holes, none folded over, the whole shape covered."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest
import scipy.ndimage as ndi

import arap
from arap.puppet.imagemesh import _lattice
from arap.puppet.outline import loop_area, outline_loops
from arap.puppet.raster import draw_textured
from tests.puppet.pictures import centres, ring


def _signed_areas(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    e1, e2 = V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]
    return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def test_a_ring_is_meshed_without_its_hole_and_without_folds() -> None:
    img = ring(200, 30, 80)
    mask = img[:, :, 3] > 0
    mesh = arap.image_mesh(img, spacing=6)
    V, F = mesh.vertices, mesh.triangles
    centroid = V[F].mean(axis=1)
    d = np.hypot(centroid[:, 0] - 100, centroid[:, 1] - 100)
    assert (d > 29).all() and (d < 81).all()  # none in the hole, none outside (to within a pixel)
    assert mask[centroid[:, 1].astype(int), centroid[:, 0].astype(int)].all()
    area = _signed_areas(V, F)
    assert (area > 0).all() or (area < 0).all()
    assert abs(np.abs(area).sum() - mask.sum()) <= 0.06 * mask.sum()
    assert np.allclose(mesh.uv, V / 200)


@pytest.mark.parametrize("spacing", [4.0, 9.0])
def test_every_shape_pixel_is_within_one_spacing_of_the_mesh(spacing: float) -> None:
    img = ring(160, 20, 70)
    img[10:30, 10:150, 3] = 255  # a second part, with a corner
    mask = img[:, :, 3] > 0
    mesh = arap.image_mesh(img, spacing=spacing)
    opaque = np.full_like(img, 255)
    covered = draw_textured(opaque, mesh.vertices, mesh.vertices, mesh.triangles, mesh.size)[:, :, 3] > 0
    distance = ndi.distance_transform_edt(~covered)
    assert distance[mask].max() <= spacing


def test_the_default_spacing_gives_about_the_density_asked() -> None:
    img = np.zeros((300, 300, 3), dtype=np.uint8)  # no alpha: the whole frame
    n = len(arap.image_mesh(img, density=2000).vertices)
    assert 1600 <= n <= 2400


def test_a_background_colour_is_left_out() -> None:
    img = np.full((100, 120, 3), 255, dtype=np.uint8)
    x, y = centres(100, 120)
    img[np.hypot(x - 60, y - 50) < 30] = (10, 120, 200)
    mesh = arap.image_mesh(img, spacing=5, background=(255, 255, 255), tolerance=10)
    c = mesh.vertices[mesh.triangles].mean(axis=1)
    assert (np.hypot(c[:, 0] - 60, c[:, 1] - 50) < 30).all()
    assert abs(np.abs(_signed_areas(mesh.vertices, mesh.triangles)).sum() - np.pi * 900) < 0.06 * np.pi * 900


def test_outline_loops_run_around_regions_and_holes() -> None:
    mask = np.zeros((9, 9), dtype=bool)
    mask[1:8, 1:8] = True
    mask[3:6, 3:6] = False
    loops = outline_loops(mask)
    areas = sorted(loop_area(lp) for lp in loops)
    assert len(loops) == 2 and areas[0] < 0 < areas[1]  # the hole runs the other way
    assert areas[1] == pytest.approx(7 * 7 - 0.5) and areas[0] == pytest.approx(-(3 * 3 - 0.5))


def test_an_empty_shape_is_refused() -> None:
    with pytest.raises(arap.ArapError, match="shape is empty"):
        arap.image_mesh(np.zeros((50, 50, 4), dtype=np.uint8))


def test_pictures_of_the_wrong_kind_are_refused() -> None:
    with pytest.raises(arap.ArapError, match="uint8"):
        arap.image_mesh(np.zeros((50, 50, 4)))
    with pytest.raises(arap.ArapError, match=r"shape \(h, w, 3\)"):
        arap.image_mesh(np.zeros((50, 50, 2), dtype=np.uint8))


def test_a_missing_optional_package_is_named_with_its_install_line(monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "pythoncdt", None)
    with pytest.raises(arap.ArapError, match=r"needs PythonCDT: pip install 'arap\[image\]'"):
        arap.image_mesh(ring(60, 5, 25), spacing=5)
    monkeypatch.setitem(sys.modules, "PIL", None)
    with pytest.raises(arap.ArapError, match=r"needs Pillow: pip install 'arap\[image\]'"):
        arap.image_mesh(__file__)


def test_the_lattice_keeps_the_points_the_distance_transform_keeps() -> None:
    # The lattice measures its points' distance to the shape's edge pixels only; the whole picture's distance
    # transform gives the same points.
    rng = np.random.default_rng(5)
    y, x = np.mgrid[0:120, 0:160]
    masks = [np.hypot(x - 80, y - 60) < 50, (np.abs(x - 30) < 25) | (np.abs(y - 100) < 15),
             ndi.binary_opening(rng.random((120, 160)) < 0.7, iterations=2), np.ones((120, 160), dtype=bool)]
    for mask in masks:
        for spacing in (4.0, 7.5, 12.0):
            distance = ndi.distance_transform_edt(np.pad(mask, 1))[1:-1, 1:-1]
            h, w = mask.shape
            dy = spacing * math.sqrt(3.0) / 2.0
            ys = np.arange(dy / 2, h, dy)
            xs = np.arange(spacing / 2, w + spacing, spacing)
            X = xs[None, :] + (np.arange(len(ys)) % 2)[:, None] * (spacing / 2)
            P = np.column_stack([X.ravel(), np.broadcast_to(ys[:, None], X.shape).ravel()])
            P = P[(P[:, 0] < w) & (P[:, 1] < h)]
            want = P[distance[P[:, 1].astype(np.int64), P[:, 0].astype(np.int64)] > 0.55 * spacing + 0.5]
            assert np.array_equal(_lattice(mask, spacing), want)
