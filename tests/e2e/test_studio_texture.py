"""Textured and coloured models in the studio: a GLB's checker texture and a PLY's vertex colours are drawn, the
Surface control switches them off and on, the texture follows a drag, and GLB export keeps UVs and texture."""

from __future__ import annotations

import io
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image
from playwright.sync_api import Page, expect

from arap.io import load_asset
from tests.e2e.conftest import canvas_pixels, positions, wait_idle, wait_settled
from tests.e2e.test_studio import drag_gizmo_x, select_anchor_and_handle
from tests.io.asset_models import coloured_ply as server_coloured_ply

pytestmark = pytest.mark.e2e

RED = (230, 40, 40)
BLUE = (40, 60, 220)


def checker_image(size: int = 64, cells: int = 4) -> Image.Image:
    i, j = np.indices((size, size)) * cells // size
    return Image.fromarray(np.where(((i + j) % 2 == 0)[..., None], RED, BLUE).astype(np.uint8))


def textured_grid_glb(path: Path, n: int = 14) -> Path:
    """A flat square grid facing the camera, UV-mapped onto a red and blue checker."""
    x, y = np.meshgrid(np.linspace(-1, 1, n), np.linspace(-1, 1, n))
    V = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    F = []
    for r in range(n - 1):
        for c in range(n - 1):
            a = r * n + c
            F += [[a, a + 1, a + n + 1], [a, a + n + 1, a + n]]
    mesh = trimesh.Trimesh(V, np.array(F), process=False)
    mesh.visual = trimesh.visual.TextureVisuals(uv=(V[:, :2] + 1) / 2, image=checker_image())
    path.write_bytes(mesh.export(file_type="glb"))
    return path


def coloured_ply(path: Path) -> Path:
    """A sphere, red on its +x half and blue on its -x half (both face the camera)."""
    return server_coloured_ply(path, axis=0, subdivisions=2)


def colour_counts(page: Page) -> tuple[int, int]:
    """Pixels of the 3D view that are clearly red, and clearly blue."""
    px = canvas_pixels(page)[..., :3].astype(np.int32)
    r, g, b = px[..., 0], px[..., 1], px[..., 2]
    red = (r > 110) & (r > 2 * g) & (r > 2 * b)
    blue = (b > 110) & (b > 1.8 * r) & (b > 1.5 * g)
    return int(red.sum()), int(blue.sum())


def upload(page: Page, path: Path, surface: str) -> None:
    page.get_by_test_id("file-input").set_input_files(str(path))
    page.wait_for_function(f"() => window.__arap.meshName === '{path.stem}'")
    page.wait_for_function(f"() => window.__arap.surface === '{surface}' && window.__arap.textureReady")
    wait_idle(page)


def show(page: Page, surface: str) -> None:
    page.get_by_test_id(f"surface-{surface}").click()
    page.wait_for_function(f"() => window.__arap.surface === '{surface}'")
    wait_idle(page)


def test_texture_shows_switches_off_and_follows_a_drag(page: Page, tmp_path: Path,
                                                      shoot: Callable[[str], Path]) -> None:
    expect(page.locator("#surface-row")).to_be_hidden()  # a built-in model is plain
    upload(page, textured_grid_glb(tmp_path / "checker.glb"), "texture")
    assert page.evaluate("() => window.__arap.surfaces") == ["texture", "plain"]
    expect(page.get_by_test_id("surface-texture")).to_be_visible()
    expect(page.get_by_test_id("surface-colours")).to_be_hidden()
    shoot("texture-01-checker")
    red, blue = colour_counts(page)
    assert red > 2000 and blue > 2000, f"the checker is not drawn ({red} red, {blue} blue pixels)"
    show(page, "plain")
    red, blue = colour_counts(page)
    assert red < 50 and blue < 50, f"plain view still shows colours ({red} red, {blue} blue pixels)"
    show(page, "texture")

    rest = positions(page)
    select_anchor_and_handle(page)
    drag_gizmo_x(page, 100)
    wait_settled(page)
    moved = positions(page)
    assert np.abs(moved - rest).max() > 0.05, "the drag did not deform the grid"
    assert page.evaluate("() => window.__arap.surface") == "texture"
    shoot("texture-02-dragged")
    red, blue = colour_counts(page)
    assert red > 1500 and blue > 1500, f"the texture is gone after the drag ({red} red, {blue} blue pixels)"

    # GLB export: the deformed grid with its UVs and texture
    with page.expect_download() as info:
        page.get_by_test_id("export-glb").click()
    download = info.value
    assert download.suggested_filename == "checker-deformed.glb"
    out = tmp_path / "out.glb"
    download.save_as(out)
    back = load_asset(out)
    assert back.uvs is not None and back.uvs.shape == (len(back.faces), 3, 2)
    source = load_asset(tmp_path / "checker.glb")
    np.testing.assert_allclose(back.uvs, source.uvs, atol=1e-6)
    assert len(back.textures) == 1
    image = np.asarray(Image.open(io.BytesIO(next(iter(back.textures.values())))).convert("RGB"))
    np.testing.assert_array_equal(image, np.asarray(checker_image()))
    assert np.abs(back.vertices - source.vertices).max() > 0.05, "the export is not the deformed shape"
    assert not page.evaluate("() => window.__arap.errors")


def test_vertex_colours_show_red_and_blue(page: Page, tmp_path: Path, shoot: Callable[[str], Path]) -> None:
    upload(page, coloured_ply(tmp_path / "ball.ply"), "colours")
    shoot("texture-03-colours")
    assert page.evaluate("() => window.__arap.surfaces") == ["colours", "plain"]
    red, blue = colour_counts(page)
    assert red > 2000 and blue > 2000, f"the vertex colours are not drawn ({red} red, {blue} blue pixels)"
    show(page, "plain")
    red, blue = colour_counts(page)
    assert red < 50 and blue < 50, f"plain view still shows colours ({red} red, {blue} blue pixels)"
    show(page, "colours")
    red, blue = colour_counts(page)
    assert red > 2000 and blue > 2000
    assert not page.evaluate("() => window.__arap.errors")
