"""A picture the server was started with (``arap studio picture.png``, or ``arap.studio(picture)`` from a notebook)
keeps its picture through a restore: the page keeps the picture itself as the session's source (not a PLY of its
triangles), so a reload's restore brings back the picture mode, textured, with the saved shape and pins."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import Browser, Page, expect

from tests.e2e.conftest import _ServerThread, page_on_server, positions, screen_points, wait_idle, wait_settled
from tests.e2e.test_session_safety import reload_and_restore
from tests.e2e.test_studio import drag_gizmo_x, select_anchor_and_handle
from tests.e2e.test_studio_picture import _picture
from tests.e2e.test_studio_texture import colour_counts

pytestmark = pytest.mark.e2e

TEXTURED = "() => window.__arap.surface === 'texture' && window.__arap.textureReady"


def _server(how: str, path: Path) -> _ServerThread:
    """A studio server started on the picture at ``path`` as ``arap studio PICTURE`` starts one (``cli``: the path as
    its default mesh), or as :func:`arap.studio` does from a notebook (``notebook``: the picture's mesh and look)."""
    if how == "cli":
        return _ServerThread(default_mesh=path)
    from arap.studio_handle import picture_input

    opened = picture_input(path, None, "mesh")
    assert opened is not None
    mesh, look = opened
    server = _ServerThread(default_mesh=mesh)
    server.server.config.app.state.studio.default_look = look
    return server


@pytest.fixture(params=["cli", "notebook"])
def started_with_picture(request: pytest.FixtureRequest, browser: Browser, tmp_path: Path) -> Iterator[Page]:
    """A page of a studio server started with a picture (an upright red bar, its top blue) as its mesh."""
    with page_on_server(browser, _server(request.param, _picture(tmp_path / "upright.png"))) as page:
        page.wait_for_function(TEXTURED)
        wait_idle(page)
        yield page


def test_a_restore_keeps_the_picture_the_server_opened(started_with_picture: Page) -> None:
    page = started_with_picture
    expect(page.get_by_test_id("picture-rows")).to_be_visible()
    x, y = np.median(screen_points(page), axis=0)
    page.mouse.click(x, y)  # a picture opens ready to take pins
    wait_idle(page)
    page.wait_for_function("() => window.__arap.constraints().points.length === 1")
    select_anchor_and_handle(page)
    drag_gizmo_x(page, 60)
    wait_settled(page)
    wait_idle(page)
    shape = positions(page)
    pins = page.evaluate("() => window.__arap.constraints().points")
    assert np.ptp(shape[:, 0]) > 0.0

    reload_and_restore(page, "upright")
    page.wait_for_function("() => window.__arap.constraints().points.length === 1", timeout=30_000)

    page.wait_for_function(TEXTURED)
    expect(page.get_by_test_id("picture-rows")).to_be_visible()  # the picture mode, not a mesh of its triangles
    red, blue = colour_counts(page)
    assert red > 500 and blue > 100, f"the picture is not drawn after the restore ({red} red, {blue} blue pixels)"
    scale = float(np.ptp(shape, axis=0).max())
    assert np.allclose(positions(page), shape, atol=1e-4 * scale), "the restore did not bring the saved shape back"
    restored = page.evaluate("() => window.__arap.constraints().points")
    assert [p["face"] for p in restored] == [p["face"] for p in pins]
    assert np.allclose([p["barycentric"] for p in restored], [p["barycentric"] for p in pins], atol=1e-6)
    assert not page.evaluate("() => window.__arap.errors")


@pytest.mark.parametrize("started_with_picture", ["notebook"], indirect=True)
def test_a_restore_meshes_the_picture_again_at_its_density_and_keeps_it_after_an_apply(
        started_with_picture: Page) -> None:
    page = started_with_picture
    opened = page.evaluate("() => window.__arap.nVertices")
    page.get_by_test_id("density").select_option("coarse")
    page.wait_for_function(f"() => window.__arap.nVertices !== {opened}", timeout=30_000)
    wait_idle(page)
    coarse = page.evaluate("() => window.__arap.nVertices")
    x, y = np.median(screen_points(page), axis=0)
    page.mouse.click(x, y)
    wait_idle(page)
    page.wait_for_function("() => window.__arap.constraints().points.length === 1")
    select_anchor_and_handle(page)
    drag_gizmo_x(page, 60)
    wait_settled(page)
    page.get_by_test_id("apply").click()
    wait_idle(page)
    shape = positions(page)
    pins = page.evaluate("() => window.__arap.constraints().points")

    reload_and_restore(page, "upright")
    page.wait_for_function("() => window.__arap.constraints().points.length === 1", timeout=30_000)

    assert page.evaluate("() => window.__arap.nVertices") == coarse
    page.wait_for_function(TEXTURED)
    expect(page.get_by_test_id("picture-rows")).to_be_visible()
    expect(page.get_by_test_id("density")).to_have_value("coarse")
    scale = float(np.ptp(shape, axis=0).max())
    assert np.allclose(positions(page), shape, atol=1e-4 * scale), "the restore did not bring the saved shape back"
    assert [p["face"] for p in page.evaluate("() => window.__arap.constraints().points")] == [p["face"] for p in pins]
    assert not page.evaluate("() => window.__arap.errors")
