"""A point weight typed or pasted with a decimal comma is the decimal number (1,5 is 1.5, not 15); a number that
would have two separators is refused with a message."""

from __future__ import annotations

import pytest
from playwright.sync_api import Page, expect

from tests.e2e.conftest import screen_points
from tests.e2e.test_studio_points import _anchor_bottom, _place_point

pytestmark = pytest.mark.e2e

PASTE = """(text) => {
    const field = document.getElementById('point-weight');
    field.focus();
    const data = new DataTransfer();
    data.setData('text/plain', text);
    field.dispatchEvent(new ClipboardEvent('paste', { clipboardData: data, bubbles: true, cancelable: true }));
}"""


def test_a_typed_decimal_comma_gives_the_decimal_weight(page: Page) -> None:
    _anchor_bottom(page)
    page.keyboard.press("5")
    field = page.get_by_test_id("point-weight")
    field.click()
    page.keyboard.type("1,5")
    expect(field).to_have_value("1.5")
    page.keyboard.press("Enter")
    point = _place_point(page, screen_points(page))
    assert point["point"]["weight"] == 1.5, point
    assert page.evaluate("() => window.__arap.constraints().points")[0]["weight"] == 1.5


def test_a_second_separator_and_a_pasted_list_are_refused(page: Page) -> None:
    page.keyboard.press("5")
    field = page.get_by_test_id("point-weight")
    field.click()
    page.keyboard.type("2.5,")
    expect(page.get_by_test_id("status-text")).to_contain_text("one decimal separator")
    expect(field).to_have_value("2.5")
    field.fill("")
    page.evaluate(PASTE, "0,25")
    expect(field).to_have_value("0.25")
    field.fill("")
    page.evaluate(PASTE, "1,000,5")
    expect(page.get_by_test_id("status-text")).to_contain_text("was not pasted")
    expect(field).to_have_value("")
