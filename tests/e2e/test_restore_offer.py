"""The offer to restore a saved session says what would come back: the mesh, whether its shape was deformed, and,
when the page shows another mesh meanwhile, that restoring loads the saved one in its place."""

from __future__ import annotations

from pathlib import Path

import pytest
from playwright.sync_api import Page, expect

from tests.e2e.conftest import screen_points, wait_idle, wait_ready, wait_settled
from tests.e2e.test_session_safety import Dialogs, wait_autosaved
from tests.e2e.test_studio import box_select, drag_gizmo_x, select_anchor_and_handle, sphere_obj

pytestmark = pytest.mark.e2e


def test_the_offer_says_the_saved_shape_was_deformed(page: Page) -> None:
    name = page.evaluate("() => window.__arap.meshName")
    select_anchor_and_handle(page)
    drag_gizmo_x(page, 60)
    wait_settled(page)
    wait_autosaved(page)
    Dialogs(page, accept=True)
    page.reload()
    wait_ready(page)
    offer = page.get_by_test_id("restore-offer")
    expect(offer).to_be_visible()
    expect(offer).to_contain_text(f": {name} (deformed), ")
    expect(offer).not_to_contain_text("in place of")  # the mesh shown is the saved one
    page.get_by_test_id("restore-discard").click()


def test_the_offer_for_another_mesh_says_it_replaces_the_one_shown(page: Page, tmp_path: Path) -> None:
    default = page.evaluate("() => window.__arap.meshName")
    text, _ = sphere_obj(1)
    path = tmp_path / "ball.obj"
    path.write_text(text)
    page.get_by_test_id("file-input").set_input_files(str(path))
    page.wait_for_function("() => window.__arap.meshName === 'ball'")
    wait_idle(page)
    pts = screen_points(page)
    page.get_by_test_id("role-fixed").click()
    box_select(page, pts[:, 0].min() - 10, pts[:, 1].max() - 20, pts[:, 0].max() + 10, pts[:, 1].max() + 10)
    wait_idle(page)
    assert page.evaluate("() => window.__arap.counts().fixed") > 0
    wait_autosaved(page)
    Dialogs(page, accept=True)
    page.reload()
    wait_ready(page)
    offer = page.get_by_test_id("restore-offer")
    expect(offer).to_be_visible()
    expect(offer).to_contain_text(": ball (shape as loaded), ")
    expect(offer).to_contain_text(f"Restore loads ball in place of the {default} shown.")
    page.get_by_test_id("restore-accept").click()
    page.wait_for_function("() => window.__arap.meshName === 'ball' && !window.__arap.restoring")
    expect(offer).to_be_hidden()
