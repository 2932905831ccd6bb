"""The first-use guide ticks off its three steps (anchors, a handle, a drag) and closes by itself after the last,
for good, so that it no longer covers the hints under the view."""

from __future__ import annotations

import pytest
from playwright.sync_api import Page, expect

from tests.e2e.conftest import wait_ready, wait_settled
from tests.e2e.test_session_safety import Dialogs
from tests.e2e.test_studio import drag_gizmo_x, select_anchor_and_handle
from tests.waiting import scaled_ms

pytestmark = pytest.mark.e2e


def test_the_guide_closes_after_its_last_step(page: Page) -> None:
    guide = page.get_by_test_id("guide")
    expect(guide).to_be_visible()
    done = guide.locator("li.done")
    expect(done).to_have_count(0)
    select_anchor_and_handle(page)
    expect(done).to_have_count(2)
    expect(guide).to_be_visible()  # the drag is still to come
    drag_gizmo_x(page, 60)
    expect(done).to_have_count(3)
    expect(guide).to_be_hidden(timeout=scaled_ms(5))
    wait_settled(page)
    Dialogs(page, accept=True)  # the warning before leaving an edited session
    page.reload()
    wait_ready(page)
    assert page.evaluate("() => window.__arap.counts().fixed") == 0, "the page was not reloaded"
    # whether the guide shows is decided as the page starts, before it is ready
    expect(page.get_by_test_id("guide")).to_be_hidden()  # done once: not shown again
