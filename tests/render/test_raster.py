"""The rasteriser: which pixels a triangle covers, which triangle is in front, and how faces are lit."""

from __future__ import annotations

import numpy as np
import pytest

from arap.render.camera import check_size, fit_camera, view_basis
from arap.render.raster import rasterize, render_mesh
from arap.render.show import show

WHITE, BLACK = np.ones(3), np.zeros(3)


def _mask(S: np.ndarray, F: np.ndarray, w: int, h: int) -> np.ndarray:
    return rasterize(np.asarray(S, float), np.asarray(F), np.ones((len(S), 3)), w, h, BLACK)[:, :, 0] > 0.5


@pytest.mark.parametrize("order", [[0, 1, 2], [0, 2, 1]])
def test_a_triangle_covers_exactly_the_pixel_centres_inside_it(order: list[int]) -> None:
    """Pixel (i, j) has its centre at (j + 0.5, i + 0.5): inside x + y <= 9.8 when i + j <= 8, whatever the winding."""
    S = [[0.0, 0, 0], [9.8, 0, 0], [0, 9.8, 0]]
    got = _mask(S, np.array([order]), 12, 10)
    i, j = np.mgrid[:10, :12]
    np.testing.assert_array_equal(got, i + j <= 8)


def test_a_triangle_off_the_picture_covers_only_what_is_inside() -> None:
    S = [[-50.0, -50, 0], [60, -50, 0], [-50, 60, 0]]  # x + y <= 10, mostly outside a 6x4 picture
    i, j = np.mgrid[:4, :6]
    np.testing.assert_array_equal(_mask(S, np.array([[0, 1, 2]]), 6, 4), (i + 0.5) + (j + 0.5) <= 10)
    assert not _mask([[-9.0, -9, 0], [-1, -9, 0], [-9, -1, 0]], np.array([[0, 1, 2]]), 6, 4).any()


def test_degenerate_and_empty_inputs_paint_only_the_background() -> None:
    img = rasterize(np.array([[0.0, 0, 0], [5, 5, 0], [9, 9, 0]]), np.array([[0, 1, 2]]), np.ones((3, 3)), 10, 10,
                    np.full(3, 0.25))
    assert (img == 0.25).all()
    assert (rasterize(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64), np.zeros((0, 3)), 3, 2, BLACK) == 0).all()


@pytest.mark.parametrize("near_first", [True, False])
def test_the_nearer_triangle_hides_the_farther_whatever_the_face_order(near_first: bool) -> None:
    near = [[1.0, 1, 1.0], [15, 1, 1.0], [1, 15, 1.0]]    # depth 1: in front
    far = [[3.0, 3, 5.0], [19, 3, 5.0], [3, 19, 5.0]]    # depth 5, overlapping it
    S = np.array(near + far if near_first else far + near)
    F = np.array([[0, 1, 2], [3, 4, 5]])
    red, green = [1.0, 0, 0], [0.0, 1, 0]
    colors = np.array([red] * 3 + [green] * 3 if near_first else [green] * 3 + [red] * 3)
    img = rasterize(S, F, colors, 20, 20, BLACK)
    assert img[5, 5].tolist() == red          # both cover it: the near one shows
    assert img[2, 2].tolist() == red          # only the near one
    assert img[17, 4].tolist() == green       # only the far one
    assert img[19, 19].tolist() == [0, 0, 0]  # neither


def test_depth_is_interpolated_across_a_triangle() -> None:
    """Two triangles crossing each other: each is in front on its own side of the crossing line."""
    S = np.array([[0.0, 0, 0], [20, 0, 10], [0, 20, 0],      # depth grows to the right
                  [0.0, 0, 10], [20, 0, 0], [0, 20, 10]])    # depth shrinks to the right
    colors = np.array([[1.0, 0, 0]] * 3 + [[0.0, 0, 1]] * 3)
    img = rasterize(S, np.array([[0, 1, 2], [3, 4, 5]]), colors, 20, 20, BLACK)
    assert img[2, 2].tolist() == [1, 0, 0] and img[2, 14].tolist() == [0, 0, 1]


def test_colours_are_interpolated_between_the_corners() -> None:
    S = np.array([[0.0, 0, 0], [100, 0, 0], [0, 100, 0]])
    colors = np.array([[0.0, 0, 0], [1.0, 0, 0], [0.0, 0, 0]])
    img = rasterize(S, np.array([[0, 1, 2]]), colors, 100, 100, BLACK)
    assert img[0, 10, 0] == pytest.approx(0.105, abs=1e-6) and img[0, 80, 0] == pytest.approx(0.805, abs=1e-6)


def _two_faces(tilt_degrees: float) -> tuple[np.ndarray, np.ndarray]:
    """A triangle facing +z on the left and one turned about y by ``tilt_degrees`` on the right."""
    left = np.array([[-2.0, -1, 0], [-0.2, -1, 0], [-2, 1, 0]])
    c, s = np.cos(np.radians(tilt_degrees)), np.sin(np.radians(tilt_degrees))
    right = np.array([[0.2, -1, 0], [0.2 + 1.8 * c, -1, -1.8 * s], [0.2, 1, 0]])
    return np.vstack([left, right]), np.array([[0, 1, 2], [3, 4, 5]])


@pytest.mark.parametrize("flip", [False, True])
def test_faces_turned_to_the_viewer_are_brighter_than_grazing_ones_on_both_sides(flip: bool) -> None:
    V, F = _two_faces(80.0)
    if flip:  # back faces are lit alike
        F = F[:, ::-1]
    cam = fit_camera(V, 200, 100, azimuth=0, elevation=0)
    img = render_mesh(V, F, cam, np.ones(3), BLACK).astype(int)
    S = cam.project(V)
    facing = img[int(S[:3, 1].mean()), int(S[:3, 0].mean())]
    grazing = img[int(S[3:, 1].mean()), int(S[3:, 0].mean())]
    assert facing.tolist() == [255, 255, 255]
    assert 20 < grazing[0] < 0.6 * facing[0]


def test_the_camera_frames_the_mesh_from_the_given_direction() -> None:
    V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 2, 0], [0, 0, 3]])
    cam = fit_camera(V, 100, 80, azimuth=0, elevation=0)
    S = cam.project(V)
    assert S[:, 0].min() == pytest.approx(100 / 2 - 0.9 * 80 / 2 / 2) and S[:, 1].min() == pytest.approx(4.0)
    assert S[3, 2] < S[0, 2]  # +z is towards the viewer: nearer
    side = fit_camera(V, 100, 80, azimuth=90, elevation=0).project(V)
    assert side[3, 0] < side[0, 0] and side[1, 2] < side[0, 2]  # seen from +x: z to the left, x nearer
    top = view_basis(0.0, 90.0)
    np.testing.assert_allclose(top[2], [0, 1, 0], atol=1e-12)  # looking straight down is defined too
    np.testing.assert_allclose(top[0], [1, 0, 0], atol=1e-12)


def test_antialiasing_softens_edges_only() -> None:
    V, F = _two_faces(0.0)
    sharp = show(V, F, width=60, height=40, antialias=False, azimuth=0, elevation=0).pixels
    smooth = show(V, F, width=60, height=40, antialias=True, azimuth=0, elevation=0).pixels
    assert len(np.unique(sharp.reshape(-1, 3), axis=0)) == 2  # the flat lit mesh, or the background
    assert len(np.unique(smooth.reshape(-1, 3), axis=0)) > 3
    assert np.mean(sharp != smooth) < 0.2


def test_sizes_are_checked() -> None:
    from arap.errors import OptionError

    assert check_size(1, 4096) == (1, 4096)
    for bad in [(0, 10), (10, -1), (10.0, 10), (True, 10), (5000, 10)]:
        with pytest.raises(OptionError):
            check_size(*bad)


def test_large_triangles_cut_into_bands_paint_the_same(monkeypatch: pytest.MonkeyPatch) -> None:
    """A chunk of pixel tests smaller than a triangle cuts it into bands of rows (one row at the least), and the
    picture is the same."""
    import arap.render.raster as raster

    rng = np.random.default_rng(3)
    S = np.column_stack([rng.uniform(-10, 70, 60), rng.uniform(-10, 50, 60), rng.uniform(0, 1, 60)])
    F = rng.integers(0, 60, (40, 3))
    colors = rng.uniform(0, 1, (60, 3))
    whole = rasterize(S, F, colors, 64, 48, BLACK)
    for chunk in (7, 100, 1000):
        monkeypatch.setattr(raster, "CHUNK", chunk)
        np.testing.assert_allclose(rasterize(S, F, colors, 64, 48, BLACK), whole, atol=1e-6)
    assert (whole.sum(axis=2) > 0).mean() > 0.5
