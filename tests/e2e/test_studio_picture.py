"""The puppet warp in the studio: a picture opened in the page is drawn textured on its flat mesh, bends in its
plane when a handle is dragged, and exports as the warped picture."""

from __future__ import annotations

import io
from collections.abc import Callable
from pathlib import Path

import numpy as np
from PIL import Image
from playwright.sync_api import Page

from tests.e2e.conftest import positions, wait_settled
from tests.e2e.test_studio import drag_gizmo_x, select_anchor_and_handle
from tests.e2e.test_studio_texture import colour_counts, upload


def _picture(path: Path, size: int = 160) -> Path:
    """An upright red bar on a transparent background, its top blue."""
    rgba = np.zeros((size, size, 4), dtype=np.uint8)
    rgba[10:150, 60:100] = [230, 40, 40, 255]
    rgba[10:40, 60:100] = [40, 60, 230, 255]
    Image.fromarray(rgba, "RGBA").save(path)
    return path


def test_a_picture_bends_in_its_plane_and_exports_as_a_picture(page: Page, tmp_path: Path,
                                                              shoot: Callable[[str], Path]) -> None:
    upload(page, _picture(tmp_path / "bar-picture.png"), "texture")
    shoot("picture-01-opened")
    red, blue = colour_counts(page)
    assert red > 500 and blue > 100, f"the picture is not drawn ({red} red, {blue} blue pixels)"
    rest = positions(page)
    assert np.all(rest[:, 2] == 0.0)
    select_anchor_and_handle(page)
    drag_gizmo_x(page, 80)
    wait_settled(page)
    moved = positions(page)
    assert np.abs(moved - rest).max() > 1.0, "the drag did not bend the picture"
    assert np.abs(moved[:, 2]).max() < 1e-6, "the picture left its plane"
    shoot("picture-02-bent")
    with page.expect_download() as info:
        page.get_by_test_id("export-png").click()
    download = info.value
    assert download.suggested_filename == "bar-picture-deformed.png"
    out = tmp_path / "out.png"
    download.save_as(out)
    warped = np.asarray(Image.open(io.BytesIO(out.read_bytes())))
    assert warped.shape == (160, 160, 4) and (warped[:, :, 3] > 0).sum() > 0.8 * 40 * 140
    assert not page.evaluate("() => window.__arap.errors")


def test_a_picture_offers_the_warp_modes_and_delete_removes_a_pin(page: Page, tmp_path: Path) -> None:
    from playwright.sync_api import expect

    from tests.e2e.conftest import screen_points, wait_idle

    expect(page.get_by_test_id("picture-rows")).to_be_hidden()  # a built-in model is no picture
    upload(page, _picture(tmp_path / "pinned.png"), "texture")
    expect(page.get_by_test_id("picture-rows")).to_be_visible()
    page.get_by_test_id("warp").select_option("distort")
    page.wait_for_function("() => window.__arap.params.warp === 'distort'")
    assert page.evaluate("() => window.__arap.role") == "point"  # a picture opens ready to take pins
    pts = screen_points(page)
    x, y = np.median(pts, axis=0)
    page.mouse.click(x, y)
    wait_idle(page)
    page.wait_for_function("() => window.__arap.constraints().points.length === 1")
    page.keyboard.press("Delete")
    page.wait_for_function("() => window.__arap.constraints().points.length === 0")
    page.get_by_test_id("picture-mesh").check()
    expect(page.get_by_test_id("wireframe")).to_be_checked()
    assert not page.evaluate("() => window.__arap.errors")


def test_a_pin_goes_forward_and_the_picture_is_meshed_again_with_its_pin(page: Page, tmp_path: Path) -> None:
    from tests.e2e.conftest import screen_points, wait_idle

    upload(page, _picture(tmp_path / "dense.png"), "texture")
    before = len(positions(page))
    x, y = np.median(screen_points(page), axis=0)
    page.mouse.click(x, y)
    wait_idle(page)
    page.wait_for_function("() => window.__arap.constraints().points.length === 1")
    page.get_by_test_id("pin-forward").click()
    page.get_by_test_id("density").select_option("coarse")
    page.wait_for_function(f"() => window.__arap.nVertices !== {before}", timeout=30_000)
    wait_idle(page)
    page.wait_for_function("() => window.__arap.constraints().points.length === 1")  # the pin is kept
    assert len(positions(page)) < before
    assert not page.evaluate("() => window.__arap.errors")


def test_alt_drag_turns_the_picture_about_its_pin_and_a_restored_session_keeps_its_angle(page: Page,
                                                                                        tmp_path: Path) -> None:
    import math

    from tests.e2e.conftest import screen_points, wait_idle
    from tests.e2e.test_session_safety import wait_autosaved

    upload(page, _picture(tmp_path / "turned.png"), "texture")
    x, y = np.median(screen_points(page), axis=0)
    page.mouse.click(x, y)
    wait_idle(page)
    page.wait_for_function("() => window.__arap.constraints().points.length === 1")
    rest = positions(page)
    px, py = page.evaluate("() => window.__arap.pointHandles()[0].screen")
    page.keyboard.down("Alt")  # a quarter turn counter-clockwise about the pin, from its right to above it
    page.mouse.move(px + 60, py)
    page.mouse.down()
    for k in range(1, 13):
        a = k / 12 * math.pi / 2
        page.mouse.move(px + 60 * math.cos(a), py - 60 * math.sin(a))
    page.mouse.up()
    page.keyboard.up("Alt")
    page.wait_for_function("() => Math.abs(window.__arap.picturePins().angles[0] ?? 0) > 45")
    wait_settled(page)
    wait_idle(page)
    angle = page.evaluate("() => window.__arap.picturePins().angles[0]")
    assert abs(angle - 90.0) < 20.0
    moved = positions(page)
    assert np.ptp(rest[:, 1]) > 2 * np.ptp(rest[:, 0]) and np.ptp(moved[:, 0]) > 2 * np.ptp(moved[:, 1]), \
        "the upright bar did not turn about its pin"
    assert page.evaluate("() => window.__arap.constraints().points.length") == 1  # the ring is the server's
    page.get_by_test_id("pin-forward").click()
    wait_autosaved(page)
    page.reload()
    page.get_by_test_id("restore-accept").click()
    page.wait_for_function("() => window.__arap.picturePins().angles[0] !== null && "
                           "window.__arap.picturePins().angles[0] !== undefined", timeout=30_000)
    pins = page.evaluate("() => window.__arap.picturePins()")
    assert abs(pins["angles"][0] - angle) < 1e-6 and pins["depth"] == [0]
    assert not page.evaluate("() => window.__arap.errors")


def _blue_dragged_over_red(page: Page, tmp_path: Path) -> np.ndarray:
    """Open a red square and a blue one, apart, put a pin on each (the blue one's is then the active pin) and drag
    the blue square over the red one's right part; the red square's vertices (a mask of the vertices)."""
    from tests.e2e.conftest import screen_points, wait_idle

    rgba = np.zeros((60, 120, 4), dtype=np.uint8)
    rgba[10:50, 10:50] = [230, 40, 40, 255]
    rgba[10:50, 70:110] = [40, 60, 230, 255]
    Image.fromarray(rgba, "RGBA").save(tmp_path / "squares.png")
    upload(page, tmp_path / "squares.png", "texture")
    pts = screen_points(page)
    left, right = pts[:, 0].min(), pts[:, 0].max()
    y = float(np.median(pts[:, 1]))
    red_x, blue_x = left + (right - left) * 20 / 100, left + (right - left) * 80 / 100  # the squares' centres
    for x in (red_x, blue_x):
        page.mouse.click(x, y)
        wait_idle(page)
    page.wait_for_function("() => window.__arap.constraints().points.length === 2")
    drag_gizmo_x(page, -0.6 * (blue_x - red_x))
    wait_settled(page)
    return np.asarray(pts[:, 0] < (left + right) / 2)


def test_pin_depth_chooses_which_part_the_page_draws_over_the_other(page: Page, tmp_path: Path) -> None:
    _blue_dragged_over_red(page, tmp_path)

    def counts_after(button: str, first: int | None) -> tuple[int, int, int]:
        page.get_by_test_id(button).click()  # the state that answers it gives another drawing order
        page.wait_for_function(f"() => ![null, {first if first is not None else 'null'}].includes("
                               "window.__arap.picturePins().drawFirst)")
        page.evaluate("() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done)))")
        return (*colour_counts(page), page.evaluate("() => window.__arap.picturePins().drawFirst"))

    red_back, blue_front, first = counts_after("pin-forward", None)
    red_front, blue_back, _ = counts_after("pin-backward", first)
    assert red_front > red_back + 50 and blue_front > blue_back + 50, (red_back, blue_front, red_front, blue_back)
    assert not page.evaluate("() => window.__arap.errors")


def test_the_mesh_drawn_over_a_picture_hides_the_edges_of_a_part_under_another(page: Page, tmp_path: Path) -> None:
    """With the blue square brought forward over the red one, the blue square covers the red one where they overlap,
    and the mesh drawn over the picture shows there the blue square's edges and none of the red one's: its edges
    darken the overlap as much as they darken the blue square alone."""
    from tests.e2e.conftest import canvas_origin, canvas_pixels, screen_points

    red = _blue_dragged_over_red(page, tmp_path)
    page.get_by_test_id("pin-forward").click()  # the blue square drawn over the red one
    page.wait_for_function("() => window.__arap.picturePins().drawFirst !== null")
    page.evaluate("() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done)))")
    bare = canvas_pixels(page)[..., :3].astype(np.float64)
    page.get_by_test_id("picture-mesh").check()
    page.evaluate("() => new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done)))")
    meshed = canvas_pixels(page)[..., :3].astype(np.float64)
    pts = screen_points(page) - np.asarray(canvas_origin(page))
    red_box = pts[red].min(axis=0), pts[red].max(axis=0)
    blue_box = pts[~red].min(axis=0), pts[~red].max(axis=0)
    assert blue_box[0][0] < red_box[1][0] - 20 < blue_box[1][0] - 40  # they overlap, and the blue one reaches out
    rows = slice(int(max(red_box[0][1], blue_box[0][1])) + 4, int(min(red_box[1][1], blue_box[1][1])) - 4)

    def region(px: np.ndarray, x0: float, x1: float) -> np.ndarray:
        return px[rows, int(x0) + 4:int(x1) - 4]

    def blue_share(x0: float, x1: float) -> float:
        px = region(bare, x0, x1)
        return float(((px[..., 2] > 1.5 * px[..., 0]) & (px[..., 2] > 60)).mean())

    def edge_ink(x0: float, x1: float) -> float:
        """How much the mesh darkens the picture between columns x0 and x1 (the gizmo, the same in both, aside)."""
        ratio = region(meshed, x0, x1).sum(axis=2) / np.maximum(region(bare, x0, x1).sum(axis=2), 1.0)
        return float(np.clip(1.0 - ratio, 0.0, None).mean())

    overlap, alone = (blue_box[0][0], red_box[1][0]), (red_box[1][0], blue_box[1][0])
    assert blue_share(*overlap) > 0.9 and blue_share(*alone) > 0.9, (blue_share(*overlap), blue_share(*alone))
    over_red, blue_alone = edge_ink(*overlap), edge_ink(*alone)
    assert 0.5 * blue_alone < over_red < 1.25 * blue_alone, (over_red, blue_alone)
    assert page.evaluate("() => window.__arap.wireLayers") == 2
    assert not page.evaluate("() => window.__arap.errors")
