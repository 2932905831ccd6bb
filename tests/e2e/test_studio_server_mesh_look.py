"""A textured mesh the server was started with (``arap studio model.glb``) keeps its texture through a restore: the
page keeps the model's own file as the session's source (not a PLY of its triangles), so a reload's restore, before
and after Apply, brings the texture back with the saved shape."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from playwright.sync_api import Browser, Page, expect

from tests.e2e.conftest import _ServerThread, page_on_server, positions, wait_idle, wait_settled
from tests.e2e.test_session_safety import reload_and_restore
from tests.e2e.test_studio import drag_gizmo_x, select_anchor_and_handle
from tests.e2e.test_studio_texture import colour_counts, textured_grid_glb

pytestmark = pytest.mark.e2e

TEXTURED = "() => window.__arap.surface === 'texture' && window.__arap.textureReady"


@pytest.fixture
def started_with_glb(browser: Browser, tmp_path: Path) -> Iterator[Page]:
    """A page of a studio server started with a textured GLB as its mesh."""
    with page_on_server(browser, _ServerThread(default_mesh=textured_grid_glb(tmp_path / "checker.glb"))) as page:
        page.wait_for_function(TEXTURED)
        yield page


def _restore_after_reload(page: Page) -> None:
    reload_and_restore(page, "checker")
    page.wait_for_function(TEXTURED)
    wait_idle(page)


@pytest.mark.parametrize("apply", [False, True], ids=["deformed", "applied"])
def test_a_restore_keeps_the_texture_of_the_mesh_the_server_opened(started_with_glb: Page, apply: bool) -> None:
    page = started_with_glb
    select_anchor_and_handle(page)
    drag_gizmo_x(page, 80)
    wait_settled(page)
    if apply:
        page.get_by_test_id("apply").click()
        wait_idle(page)
    shape = positions(page)

    _restore_after_reload(page)
    expect(page.get_by_test_id("surface-texture")).to_be_visible()
    assert page.evaluate("() => window.__arap.surfaces") == ["texture", "plain"]
    red, blue = colour_counts(page)
    assert red > 500 and blue > 500, f"the checker texture is not drawn after the restore ({red} red, {blue} blue)"
    scale = float(np.ptp(shape, axis=0).max())
    assert np.allclose(positions(page), shape, atol=1e-4 * scale), "the restore did not bring the saved shape back"
