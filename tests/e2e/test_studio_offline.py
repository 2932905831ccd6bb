"""While the server is away: the gizmo refuses to move handles the server cannot hear about, and the controls
that depend on the paint mode come back in the state that mode gives them."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest
from playwright.sync_api import Browser, Page, expect

from tests.e2e.conftest import VIEWPORT, positions, wait_ready
from tests.e2e.test_studio import select_anchor_and_handle
from tests.waiting import scaled_ms

pytestmark = pytest.mark.e2e


@pytest.fixture
def own_page(browser: Browser, own_server: list) -> Iterator[Page]:
    """A studio page on a server of its own (which the test may stop or restart); fails on uncaught page errors."""
    context = browser.new_context(viewport=VIEWPORT)
    page = context.new_page()
    page_errors: list[str] = []
    page.on("pageerror", lambda exc: page_errors.append(str(exc)))
    page.goto(own_server[-1].url)
    wait_ready(page)
    yield page
    context.close()
    assert not page_errors, f"errors in the page: {page_errors}"


def _disabled(page: Page) -> dict:
    return page.evaluate("""() => ({
        invert: document.getElementById('btn-invert').disabled,
        slider: document.getElementById('stiffness').disabled,
    })""")


def test_the_gizmo_does_not_move_handles_while_disconnected(own_page: Page, own_server: list) -> None:
    page = own_page
    select_anchor_and_handle(page)
    before = positions(page)
    gizmo = page.evaluate("() => window.__arap.gizmo()")
    own_server[-1].stop()
    expect(page.get_by_test_id("conn-text")).to_have_text("reconnecting…", timeout=scaled_ms(10))
    cx, cy = gizmo["screen"]
    ax, ay = gizmo["axes"]["x"]
    d = np.array([ax - cx, ay - cy]) / np.hypot(ax - cx, ay - cy)
    page.mouse.move(ax, ay)
    page.mouse.down()
    for k in range(1, 13):
        page.mouse.move(ax + d[0] * 10 * k, ay + d[1] * 10 * k)
    page.mouse.up()
    page.evaluate("() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r)))")
    expect(page.get_by_test_id("status-text")).to_contain_text("Not connected")
    # nothing moved: neither the surface, nor the gizmo, nor the transform the next drag would send
    assert np.array_equal(positions(page), before)
    after = page.evaluate("() => window.__arap.gizmo()")
    assert np.allclose(after["screen"], gizmo["screen"], atol=0.5)
    assert np.allclose(page.evaluate("() => window.__arap.transforms()[0]"), np.eye(4).ravel())


def test_mode_controls_keep_their_state_after_a_reconnection(own_page: Page, own_server: list) -> None:
    page = own_page
    page.keyboard.press("6")
    page.get_by_test_id("stiffness-rigid").check()
    assert _disabled(page) == {"invert": True, "slider": True}
    own_server[-1].stop()
    expect(page.get_by_test_id("conn-text")).to_have_text("reconnecting…", timeout=scaled_ms(10))
    own_server.append(own_server[-1].restarted())
    expect(page.get_by_test_id("conn-text")).to_have_text("connected", timeout=scaled_ms(20))
    wait_ready(page)
    # stiffness cannot be inverted, and a rigid brush has no strength to set
    assert _disabled(page) == {"invert": True, "slider": True}
    page.get_by_test_id("stiffness-rigid").uncheck()
    assert _disabled(page) == {"invert": True, "slider": False}
    page.keyboard.press("2")
    assert _disabled(page)["invert"] is False
