"""The puppet warp: pins land on their targets, a rigid pin set moves the picture rigidly, a bend keeps the
picture's colours where the pins take them."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.ndimage as ndi

import arap
from arap.puppet.raster import premultiplied
from arap.puppet.warp import pin_targets
from tests.puppet.pictures import bar, centres, dot, find, ring, textured


def _pin_points(puppet: arap.PuppetWarp, U: np.ndarray) -> np.ndarray:
    return np.einsum("pc,pcx->px", puppet.barycentric, U[puppet.mesh.triangles[puppet.faces]])


@pytest.mark.parametrize("mode", ["rigid", "normal", "distort"])
def test_pins_land_exactly_on_their_targets(mode: str) -> None:
    pins = np.array([[30.0, 100.0], [100.0, 60.0], [170.0, 100.0], [100.5, 139.25]])
    targets = [[40.0, 110.0], None, [150.0, 130.0]]  # the second and the last pin hold
    puppet = arap.PuppetWarp(ring(200, 30, 80), pins, spacing=8, mode=mode)
    U = puppet.deform(targets)
    assert np.abs(_pin_points(puppet, puppet.mesh.vertices) - pins).max() <= 1e-9  # the handles are the pins
    want = pins.copy()
    want[0], want[2] = targets[0], targets[2]
    assert np.abs(_pin_points(puppet, U) - want).max() <= 1e-6
    assert np.abs(puppet.mesh.vertices - U).max() > 10  # it did move


def _bilinear(img: np.ndarray, sx: np.ndarray, sy: np.ndarray) -> np.ndarray:
    """Premultiplied bilinear samples of ``img`` at pixel coordinates (sx, sy)."""
    P = premultiplied(img).astype(np.float64)
    fx, fy = sx - 0.5, sy - 0.5
    i0, j0 = np.floor(fx).astype(int), np.floor(fy).astype(int)
    tx, ty = (fx - i0)[..., None], (fy - j0)[..., None]
    h, w = img.shape[:2]

    def at(j: np.ndarray, i: np.ndarray) -> np.ndarray:
        return P[np.clip(j, 0, h - 1), np.clip(i, 0, w - 1)]

    return ((at(j0, i0) * (1 - tx) + at(j0, i0 + 1) * tx) * (1 - ty)
            + (at(j0 + 1, i0) * (1 - tx) + at(j0 + 1, i0 + 1) * tx) * ty)


@pytest.mark.parametrize("mode", ["rigid", "normal", "distort"])
def test_a_rigid_pin_set_moves_the_picture_rigidly(mode: str) -> None:
    img = textured(200, 200)
    x, y = centres(200, 200)
    img[:, :, 3] = np.where(np.hypot(x - 100, y - 100) < 60, 255, 0)
    pins = np.array([[70.0, 90.0], [130.0, 95.0], [100.0, 140.0]])
    angle, shift = np.radians(25.0), np.array([12.0, -7.0])
    R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    centre = np.array([100.0, 100.0])
    targets = (pins - centre) @ R.T + centre + shift
    out = arap.warp(img, pins, targets, spacing=7, mode=mode)
    # Where every output pixel centre comes from under the inverse motion.
    q = np.stack([x, y], axis=-1) - centre - shift
    src = q @ R + centre
    expected = _bilinear(img, src[..., 0], src[..., 1])
    inside = ndi.distance_transform_edt(img[:, :, 3] > 0)
    hs, ws = np.clip(src[..., 1].astype(int), 0, 199), np.clip(src[..., 0].astype(int), 0, 199)
    interior = (inside[hs, ws] > 3) & (src >= 0).all(axis=-1) & (src < 200).all(axis=-1)
    assert interior.sum() > 8000
    assert (out[interior, 3] == 255).all()
    difference = np.abs(out[interior, :3].astype(float) - expected[interior, :3])
    assert difference.mean() < 0.5 and difference.max() <= 2.0


def test_a_bend_takes_the_pins_colours_to_their_targets() -> None:
    img = bar()
    pins = np.array([[30.0, 100.0], [100.0, 100.0], [170.0, 100.0]])
    colours = [(255, 0, 0), (0, 255, 0), (0, 0, 255)]
    for (px, py), colour in zip(pins, colours, strict=True):
        dot(img, px, py, colour)
    targets = np.array([[40.0, 60.0], [100.0, 100.0], [160.0, 60.0]])  # both ends up: a smile
    out = arap.warp(img, pins, targets, spacing=5)
    for target, colour in zip(targets, colours, strict=True):
        assert np.hypot(*(find(out, colour) - target)) <= 3.0
    opaque = (img[:, :, 3] > 0).sum()
    assert abs((out[:, :, 3] > 0).sum() - opaque) <= 0.06 * opaque


def test_fit_enlarges_the_canvas_to_hold_the_warped_shape() -> None:
    img = bar()
    pins = [[30.0, 100.0], [170.0, 100.0]]
    targets = [[30.0, 100.0], [230.0, 100.0]]  # past the right edge
    cut = arap.warp(img, pins, targets, spacing=6)
    fitted = arap.warp(img, pins, targets, spacing=6, fit=True)
    assert cut.shape == (200, 200, 4)
    assert fitted.shape[0] == 200 and fitted.shape[1] >= 232
    assert (fitted[:, :, 3] > 0).sum() > (cut[:, :, 3] > 0).sum() + 500


def test_depth_puts_one_part_over_the_other() -> None:
    img = np.zeros((100, 200, 4), dtype=np.uint8)
    img[40:60, 10:90] = (255, 0, 0, 255)    # a red arm on the left
    img[40:60, 90:190] = (0, 0, 255, 255)   # a blue arm on the right
    puppet = arap.PuppetWarp(img, [[50.0, 50.0]], spacing=5)
    U = puppet.mesh.vertices.copy()
    U[U[:, 0] < 89, 0] += 100  # the red arm laid over the blue one
    left = np.zeros((100, 200))
    left[:, :90] = 1
    for depth, colour in ((left, 0), (1 - left, 2)):  # the red arm in front, then the blue one
        out = puppet.render(U, depth=depth)
        assert out[50, 140, colour] == 255 and out[50, 140, 2 - colour] == 0
    per_vertex = (puppet.mesh.vertices[:, 0] >= 89).astype(float)  # depth per vertex: the blue arm in front
    assert puppet.render(U, depth=per_vertex)[50, 140, 2] == 255


def test_a_rigid_region_keeps_its_shape() -> None:
    img = bar()
    rigid = np.zeros((200, 200), dtype=bool)
    rigid[:, 20:100] = True  # the left half
    pins = [[30.0, 100.0], [170.0, 100.0]]
    puppet = arap.PuppetWarp(img, pins, spacing=6, rigid=rigid)
    U = puppet.deform([None, [150.0, 150.0]])
    V = puppet.mesh.vertices
    left = V[:, 0] < 95
    d_rest = np.linalg.norm(V[left][:, None] - V[left][None], axis=2)
    d_now = np.linalg.norm(U[left][:, None] - U[left][None], axis=2)
    assert np.abs(d_rest - d_now).max() < 1e-3


def test_a_pin_outside_the_shape_is_named() -> None:
    with pytest.raises(arap.ArapError, match=r"pin 1 at \(100, 100\) is outside the picture's shape"):
        arap.warp(ring(200, 30, 80), [[30, 100], [100, 100]], None, spacing=8)


def test_bad_pins_are_refused() -> None:
    img = ring(200, 30, 80)
    with pytest.raises(arap.ArapError, match="at least one pin"):
        arap.warp(img, [], None)
    with pytest.raises(arap.ArapError, match="pins 0 and 1 are at the same place"):
        arap.warp(img, [[30, 100], [30, 100]], None)
    with pytest.raises(arap.ArapError, match="3 targets for 2 pins"):
        arap.warp(img, [[30, 100], [170, 100]], [None, None, None])
    with pytest.raises(arap.ArapError, match="unknown warp mode"):
        arap.warp(img, [[30, 100]], None, mode="bendy")  # type: ignore[arg-type]


@pytest.mark.parametrize("mode", ["rigid", "normal", "distort"])
def test_one_pin_drags_the_picture_along(mode: str) -> None:
    puppet = arap.PuppetWarp(bar(), [[40.0, 95.0]], spacing=8, mode=mode)
    U = puppet.deform([[55.0, 105.0]])
    assert np.abs(U - puppet.mesh.vertices - [15.0, 10.0]).max() < 1e-5


def test_a_part_without_a_pin_stays_where_it_is() -> None:
    img = bar()
    img[20:50, 60:140] = (0, 200, 0, 255)  # an island above the bar
    for mode in ("rigid", "distort"):
        puppet = arap.PuppetWarp(img, [[30.0, 100.0], [170.0, 100.0]], spacing=6, mode=mode)  # type: ignore[arg-type]
        U = puppet.deform([None, [150.0, 160.0]])
        island = puppet.mesh.vertices[:, 1] < 60
        assert island.any() and np.abs(U[island] - puppet.mesh.vertices[island]).max() < 1e-9
        assert np.abs(U[~island] - puppet.mesh.vertices[~island]).max() > 20


def test_a_malformed_target_is_named() -> None:
    with pytest.raises(arap.ArapError, match=r"the target of pin 1 must be an \(x, y\) pair or None"):
        pin_targets([[1, 2], [3, 4]], [None, [5]])


def test_transparent_pixels_lend_no_colour_to_their_neighbours() -> None:
    img = np.zeros((60, 60, 4), dtype=np.uint8)
    img[:, :, 1] = 255                        # transparent green
    img[10:50, 10:30] = (255, 0, 0, 255)     # an opaque red square, its right edge at x = 30
    out = arap.warp(img, [[20.0, 30.0]], [[20.7, 30.0]], spacing=4)  # moved 0.7 px to the right
    edge = out[20:40, 30]                     # centres at x = 30.5: 0.7 red and 0.3 transparent in the source
    assert (edge[:, 0] == 255).all() and (edge[:, 1] == 0).all()
    assert np.abs(edge[:, 3].astype(int) - round(0.7 * 255)).max() <= 1


def test_pin_depth_brings_a_pins_part_forward() -> None:
    img = np.zeros((100, 200, 4), dtype=np.uint8)
    img[40:60, 10:90] = (255, 0, 0, 255)    # a red arm on the left
    img[40:60, 90:190] = (0, 0, 255, 255)   # a blue arm on the right
    island = np.zeros((100, 200, 4), dtype=np.uint8)
    island[80:95, 10:20] = (0, 255, 0, 255)  # an island without a pin
    img = np.where(island[:, :, 3:] > 0, island, img)
    puppet = arap.PuppetWarp(img, [[30.0, 50.0], [170.0, 50.0]], spacing=5)
    parts = puppet.pin_parts()
    centroid = puppet.mesh.vertices[puppet.mesh.triangles].mean(axis=1)
    assert np.all(parts[centroid[:, 1] > 75] == -1)
    arm = centroid[:, 1] < 75
    assert np.all(parts[arm & (centroid[:, 0] < 80)] == 0) and np.all(parts[arm & (centroid[:, 0] > 100)] == 1)
    U = puppet.mesh.vertices.copy()
    U[(U[:, 0] < 89) & (U[:, 1] < 75), 0] += 100  # the red arm laid over the blue one
    for front, colour in ((0, 0), (1, 2)):
        depth = np.where(np.arange(2) == front, 1.0, 0.0)
        out = puppet.render(U, depth=np.append(depth, 0.0)[parts])  # the island (-1) at the back
        assert out[50, 140, colour] == 255 and out[50, 140, 2 - colour] == 0
