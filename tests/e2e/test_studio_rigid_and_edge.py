"""A drag that nothing holds says that the model moves rigidly, and a brush stroke that starts just off the model's
silhouette paints instead of turning the camera."""

from __future__ import annotations

import numpy as np
import pytest
from playwright.sync_api import Page, expect

from tests.e2e.conftest import screen_points, wait_idle, wait_settled
from tests.e2e.test_studio import drag_gizmo_x, paint_stroke
from tests.e2e.test_studio_points import _anchor_bottom

pytestmark = pytest.mark.e2e

HINT = "No anchors: the model moves rigidly"


def _paint_top_handle(page: Page) -> None:
    pts = screen_points(page)
    ymin, ymax = pts[:, 1].min(), pts[:, 1].max()
    tx, ty = pts[pts[:, 1] <= ymin + 0.03 * (ymax - ymin)].mean(axis=0)
    page.get_by_test_id("role-handle").click()
    paint_stroke(page, tx - 6, ty + 8)
    wait_idle(page)
    assert page.evaluate("() => window.__arap.counts().groups[0]") > 0


def test_a_drag_without_anchors_says_the_model_moves_rigidly(page: Page) -> None:
    _paint_top_handle(page)
    drag_gizmo_x(page, 60.0)
    wait_settled(page)
    expect(page.get_by_test_id("status-text")).to_contain_text(HINT)
    assert page.evaluate("() => window.__arap.lastSeq") > 0


def test_a_drag_with_anchors_says_nothing_of_rigid_motion(page: Page) -> None:
    _anchor_bottom(page)
    _paint_top_handle(page)
    drag_gizmo_x(page, 60.0)
    wait_settled(page)
    bar = page.get_by_test_id("statusbar")
    assert bar.is_hidden() or HINT not in page.get_by_test_id("status-text").inner_text()


def test_a_stroke_starting_just_off_the_silhouette_paints_and_keeps_the_camera(page: Page) -> None:
    wait_idle(page)
    page.get_by_test_id("role-fixed").click()
    pts = screen_points(page)
    k = int(np.argmin(pts[:, 0]))
    x, y = pts[k, 0] - 8.0, pts[k, 1]
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + 40, y, steps=8)
    page.mouse.up()
    wait_idle(page)
    assert page.evaluate("() => window.__arap.counts().fixed") > 0, "the stroke painted nothing"
    np.testing.assert_allclose(screen_points(page), pts, atol=1e-6, err_msg="the camera turned")
