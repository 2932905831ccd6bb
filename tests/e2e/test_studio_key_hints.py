"""Keys that do nothing say why in a short hint, and a key pressed while the server is away leaves the message
about the lost connection in place."""

from __future__ import annotations

import pytest
from playwright.sync_api import Page, expect

from tests.e2e.conftest import wait_idle
from tests.e2e.test_studio_offline import own_page  # noqa: F401  (fixture)
from tests.waiting import scaled_ms

pytestmark = pytest.mark.e2e


def test_a_key_that_is_no_shortcut_and_an_undo_with_nothing_to_undo_say_so(page: Page) -> None:
    wait_idle(page)
    status = page.get_by_test_id("status-text")
    page.keyboard.press("q")
    expect(status).to_contain_text("“q” is not a shortcut")
    expect(status).to_contain_text("press ?")
    page.keyboard.press("Control+z")
    expect(status).to_have_text("Nothing to undo.")
    page.keyboard.press("Control+Shift+z")
    expect(status).to_have_text("Nothing to redo.")
    assert page.evaluate("() => window.__arap.errors") == []


def test_growing_an_empty_role_says_there_is_nothing_to_grow(page: Page) -> None:
    wait_idle(page)
    page.keyboard.press("2")
    page.keyboard.press("+")
    expect(page.get_by_test_id("status-text")).to_contain_text("Nothing of the current role to grow")


def test_undo_while_the_server_is_away_keeps_the_reconnecting_message(own_page: Page,  # noqa: F811
                                                                      own_server: list) -> None:
    page = own_page
    own_server[-1].stop()
    expect(page.get_by_test_id("conn-text")).to_have_text("reconnecting…", timeout=scaled_ms(10))
    status = page.get_by_test_id("status-text")
    expect(status).to_contain_text("Lost the connection to the studio server")
    for key in ("Control+z", "Control+y", "q", "+"):
        page.keyboard.press(key)
        expect(status).to_contain_text("Lost the connection to the studio server")
    expect(page.get_by_test_id("statusbar")).to_be_visible()
