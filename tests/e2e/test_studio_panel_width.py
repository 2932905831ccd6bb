"""The side panel leaves the 3D view most of a small window: a quarter of 1024 pixels, its controls fitting without
a horizontal scroll, and it folds away to a strip (and back) with the button in its head."""

from __future__ import annotations

import pytest
from playwright.sync_api import Browser, expect

from tests.e2e.conftest import wait_ready

pytestmark = pytest.mark.e2e

SIZES = """() => {
  const p = document.getElementById('panel');
  return { panel: p.getBoundingClientRect().width, scroll: p.scrollWidth, client: p.clientWidth,
           view: document.getElementById('view').getBoundingClientRect().width };
}"""


def test_the_panel_is_narrower_in_a_small_window_and_folds_away(browser: Browser, server_url: str) -> None:
    context = browser.new_context(viewport={"width": 1024, "height": 700})
    page = context.new_page()
    page.goto(server_url)
    wait_ready(page)
    s = page.evaluate(SIZES)
    assert s["panel"] <= 0.26 * 1024, f"the panel takes {s['panel'] / 1024:.0%} of the width"
    assert s["scroll"] <= s["client"] + 1, "the panel's controls should fit its width"
    toggle = page.get_by_test_id("panel-toggle")
    toggle.click()
    page.wait_for_function("() => document.getElementById('view').getBoundingClientRect().width > 900")
    folded = page.evaluate(SIZES)
    assert folded["panel"] <= 48
    expect(page.get_by_test_id("builtin-select")).to_be_hidden()
    expect(toggle).to_be_visible()
    toggle.click()
    page.wait_for_function(f"() => document.getElementById('panel').getBoundingClientRect().width === {s['panel']}")
    expect(page.get_by_test_id("builtin-select")).to_be_visible()
    assert page.evaluate(SIZES)["view"] == s["view"]

    page.set_viewport_size({"width": 1280, "height": 800})
    page.wait_for_function("() => document.getElementById('panel').getBoundingClientRect().width === 320")
    assert not page.evaluate("() => window.__arap.errors")
    context.close()
