"""A point handle the server refuses (every corner of its triangle anchored) is taken away again; the handle
groups the page drags then still match the server's, before and after an undo."""

from __future__ import annotations

import numpy as np
import pytest
from playwright.sync_api import Page, expect

from tests.e2e.conftest import positions, wait_idle, wait_settled
from tests.e2e.test_studio import drag_gizmo_x, paint_stroke
from tests.e2e.test_studio_points import _anchor_bottom, _faces

pytestmark = pytest.mark.e2e


def _held_triangle_on_screen(page: Page) -> tuple[float, float]:
    fixed = set(page.evaluate("() => window.__arap.constraints().fixed"))
    F = _faces(page)
    V = positions(page)
    held = np.asarray([all(int(i) in fixed for i in f) for f in F])
    centres = V[F[held]].mean(axis=1)
    on_screen = np.asarray([page.evaluate("(p) => window.__arap.project(p)", c.tolist()) for c in centres])
    x, y = on_screen[np.argmin(np.linalg.norm(on_screen - np.median(on_screen, axis=0), axis=1))]
    return float(x), float(y)


def _drag_is_answered(page: Page) -> None:
    before = page.evaluate("() => window.__arap.lastSeq")
    drag_gizmo_x(page, 60.0)
    wait_settled(page)
    assert page.evaluate("() => window.__arap.lastSeq") > before, "no drag was answered"


def test_drags_go_on_after_a_refused_point_handle_and_after_undo(page: Page) -> None:
    pts = _anchor_bottom(page)
    ymin, ymax = pts[:, 1].min(), pts[:, 1].max()
    tx, ty = pts[pts[:, 1] <= ymin + 0.03 * (ymax - ymin)].mean(axis=0)
    page.get_by_test_id("role-handle").click()
    paint_stroke(page, tx - 6, ty + 8)
    wait_idle(page)
    assert page.evaluate("() => window.__arap.counts().groups[0]") > 0
    _drag_is_answered(page)
    assert page.evaluate("() => window.__arap.errors") == []

    x, y = _held_triangle_on_screen(page)
    page.keyboard.press("5")
    page.mouse.click(x, y)
    page.wait_for_function("() => window.__arap.errors.length > 0")
    wait_idle(page)
    expect(page.get_by_test_id("status-text")).to_contain_text("Removed point")
    assert page.evaluate("() => window.__arap.constraints().points") == []

    _drag_is_answered(page)
    errors = page.evaluate("() => window.__arap.errors")
    assert [e["request"] for e in errors] == ["set_constraints"], errors

    page.keyboard.press("Control+z")
    page.wait_for_function("() => window.__arap.canRedo")
    wait_settled(page)
    _drag_is_answered(page)
    errors = page.evaluate("() => window.__arap.errors")
    assert [e["request"] for e in errors] == ["set_constraints"], errors
